"""User effects: a Python file named on the command line, or an installed entry point.

The interface is the built-ins' own: build an :class:`~mav_motor_health.model.effects.Effect` from a pure
function ``(terms, parameters, data) -> terms`` and declare its parameters and needed variables. A file
passed with ``--effects-file my_effect.py`` exposes them as a module-level list ``EFFECTS`` (or as
module-level ``Effect`` objects)::

    from mav_motor_health.model.effects import Effect, EffectParameter

    def hall_sensor_drift(terms, p, data):
        \"\"\"The current sensor's zero drifts with the ESC temperature.\"\"\"
        return terms.replace(current_offset_a=terms.current_offset_a + p["gain_a_per_k"] * (data["esc_temp_c"] - 25))

    EFFECTS = [Effect("hall_drift", hall_sensor_drift,
                      (EffectParameter("gain_a_per_k", "A/K", -0.5, 0.5, 0.0, 0.0),),
                      needs=("esc_temp_c",))]

An installed package can instead declare an entry point in the group ``mav_motor_health.effects`` that
loads to an ``Effect`` or a list of them. Both are ranked and fitted exactly like the built-ins.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Iterable, Mapping, Sequence
from importlib import metadata
from pathlib import Path

from ...errors import ConfigError
from .base import Effect
from .library import BUILTIN_EFFECTS

__all__ = ["ENTRY_POINT_GROUP", "available_effects", "entry_point_effects", "load_effects_file"]

ENTRY_POINT_GROUP = "mav_motor_health.effects"


def _effects_in(obj: object, origin: str) -> list[Effect]:
    if isinstance(obj, Effect):
        return [obj]
    if isinstance(obj, Iterable) and not isinstance(obj, (str, bytes)):
        items = list(obj)
        if all(isinstance(x, Effect) for x in items):
            return items
    raise ConfigError(f"{origin} is a {type(obj).__name__}", expected="an Effect or a list of Effect")


def load_effects_file(path: str | Path) -> list[Effect]:
    """The effects a user's Python file declares (its ``EFFECTS`` list, else its module-level Effects)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("file not found", path=path, expected="a Python file declaring EFFECTS")
    spec = importlib.util.spec_from_file_location(f"mav_motor_health_user_effects_{path.stem}", path)
    if spec is None or spec.loader is None:
        raise ConfigError("cannot be imported", path=path, expected="a Python file (.py)")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except ConfigError as exc:
        raise ConfigError(exc.reason, path=path, key=exc.key, expected=exc.expected) from exc
    except Exception as exc:
        raise ConfigError(f"failed to import: {type(exc).__name__}: {exc}", path=path) from exc
    if hasattr(module, "EFFECTS"):
        return _effects_in(module.EFFECTS, f"{path}: EFFECTS")
    found = [v for v in vars(module).values() if isinstance(v, Effect)]
    if not found:
        raise ConfigError("declares no effect", path=path, expected="a list EFFECTS of Effect objects")
    return found


def entry_point_effects() -> list[Effect]:
    """Effects installed by other packages under the entry-point group ``mav_motor_health.effects``."""
    found: list[Effect] = []
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            obj = ep.load()
        except Exception as exc:
            raise ConfigError(f"entry point '{ep.name}' failed to load: {exc}") from exc
        found += _effects_in(obj, f"entry point '{ep.name}'")
    return found


def available_effects(
    files: Sequence[str | Path] = (), extra: Iterable[Effect] = (), *, entry_points: bool = True
) -> dict[str, Effect]:
    """Built-in effects, then installed ones, then those of ``files`` and ``extra`` (later names win)."""
    effects: dict[str, Effect] = dict(BUILTIN_EFFECTS)
    more: list[Effect] = entry_point_effects() if entry_points else []
    for f in files:
        more += load_effects_file(f)
    more += list(extra)
    for e in more:
        effects[e.name] = e
    return effects


def resolve(names: Iterable[str], registry: Mapping[str, Effect]) -> list[Effect]:
    out = []
    for name in names:
        if name not in registry:
            raise ConfigError(
                f"unknown effect '{name}'",
                key=f"motor.effects.{name}",
                expected=f"one of {', '.join(registry)} (user effects: --effects-file or an entry point "
                f"in '{ENTRY_POINT_GROUP}')",
            )
        out.append(registry[name])
    return out
