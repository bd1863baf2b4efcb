"""Loading configuration: motor parameters and threshold profiles from TOML, validated on load.

Files live in ``params/`` (``params/motors/*.toml``, ``params/profiles/*.toml``); a name without a path
(``--profile flight``, ``--params paper_x2212``) is looked up there. Every problem is reported as one
:class:`~mav_motor_health.errors.ConfigError` naming the file, the key and what was expected.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any

from .diagnosis.detection import SequentialRule
from .diagnosis.noise import NOISE_KEYS, SIGNED_NOISE_KEYS, band_noise_of
from .diagnosis.plausibility import PlausibilityRule
from .diagnosis.profile import PersistenceRule, ThresholdProfile
from .diagnosis.rules.base import CompareRule, check_settings, compare_rule
from .diagnosis.vehicle_check import VehicleCheckRule
from .errors import ConfigError
from .model.identify import CurrentReading, EscMap
from .model.params import MotorParams
from .model.vehicle import CURRENT_SIDES, VehicleParams

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = [
    "DEFAULT_MOTOR",
    "DEFAULT_PROFILE",
    "PARAMS_DIR",
    "dump_motor_params",
    "dump_profile",
    "dump_vehicle_params",
    "load_motor_params",
    "load_profile",
    "load_vehicle_params",
    "read_toml",
    "resolve_params_file",
]

#: The bundled ``params/`` folder (a link to the repository's ``params/``).
PARAMS_DIR = Path(__file__).resolve().parent / "params"
DEFAULT_MOTOR = "paper_x2212"
DEFAULT_PROFILE = "testbed"


def resolve_params_file(name_or_path: str | Path, kind: str) -> Path:
    """A path as given, or a bundled file by name: ``params/<kind>/<name>.toml``."""
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.exists() or len(candidate.parts) > 1:
        return candidate
    bundled = PARAMS_DIR / kind / f"{name_or_path}.toml"
    if bundled.exists():
        return bundled
    known = sorted(p.stem for p in (PARAMS_DIR / kind).glob("*.toml"))
    raise ConfigError(
        f"no {kind[:-1]} named '{name_or_path}'", expected=f"a TOML file path or one of {known}"
    )


def read_toml(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    try:
        with path.open("rb") as handle:
            return tomllib.load(handle)
    except FileNotFoundError:
        raise ConfigError("file not found", path=path) from None
    except IsADirectoryError:
        raise ConfigError("is a folder", path=path, expected="a TOML file") from None
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", path=path) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a text file (byte {exc.start} is not UTF-8)", path=path) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=path) from exc


class _Section:
    """Reads one TOML table with type checks; ``done()`` rejects keys nobody asked for."""

    def __init__(self, data: Any, path: Path, prefix: str) -> None:
        if not isinstance(data, Mapping):
            raise ConfigError(f"is a {type(data).__name__}", path=path, key=prefix, expected="a table")
        self.data, self.path, self.prefix = data, path, prefix
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.prefix}.{name}" if self.prefix else name

    def number(
        self,
        name: str,
        default: float | None = None,
        *,
        minimum: float | None = None,
        maximum: float | None = None,
        unit: str = "",
    ) -> float:
        self.used.add(name)
        if name not in self.data:
            if default is None:
                raise ConfigError(
                    "missing", path=self.path, key=self.key(name), expected=f"a number {unit}".strip()
                )
            return default
        value = self.data[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(
                f"{value!r} is not a finite number",
                path=self.path,
                key=self.key(name),
                expected=f"a number {unit}".strip(),
            )
        if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
            rng = (
                f"between {minimum} and {maximum}"
                if minimum is not None and maximum is not None
                else (f">= {minimum}" if minimum is not None else f"<= {maximum}")
            )
            raise ConfigError(
                f"{value!r} is out of range",
                path=self.path,
                key=self.key(name),
                expected=f"{rng} {unit}".strip(),
            )
        return float(value)

    def text(self, name: str, default: str) -> str:
        self.used.add(name)
        value = self.data.get(name, default)
        if not isinstance(value, str):
            raise ConfigError(
                f"{value!r} is not text", path=self.path, key=self.key(name), expected="a string"
            )
        return value

    def table(self, name: str) -> _Section:
        self.used.add(name)
        return _Section(self.data.get(name, {}), self.path, self.key(name))

    def raw(self, name: str) -> Any:
        self.used.add(name)
        return self.data.get(name)

    def done(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise ConfigError(
                f"unknown key(s) {', '.join(unknown)}",
                path=self.path,
                key=self.prefix or None,
                expected=f"only {', '.join(sorted(self.used))}",
            )


def load_motor_params(name_or_path: str | Path = DEFAULT_MOTOR) -> MotorParams:
    """Motor parameters from a TOML file with a ``[motor]`` table (and optional ``[source]`` notes)."""
    path = resolve_params_file(name_or_path, "motors")
    data = read_toml(path)
    top = _Section(data, path, "")
    motor = top.table("motor")
    top.raw("source")  # free-form provenance, kept in the file only
    for section in VEHICLE_SECTIONS:  # a vehicle file is a motor file too: load_vehicle_params reads these
        top.raw(section)
    top.done()
    values = {
        "R_ohm": motor.number("R_ohm", minimum=1e-6, unit="ohm"),
        "k_e": motor.number("k_e", minimum=1e-7, unit="V*s/rad"),
        "C_p": motor.number("C_p", minimum=0.0, unit="N*m/(rad/s)^k"),
        "B": motor.number("B", 0.0, unit="N*m/(rad/s)"),
        "T_f": motor.number("T_f", 0.0, unit="N*m"),
        "k": motor.number("k", 3.0, minimum=0.5, maximum=6.0),
    }
    inertia = motor.number("J_kg_m2", 0.0, minimum=0.0, unit="kg*m^2")
    name = motor.text("name", path.stem)
    effects_section = motor.table("effects")
    effects = []
    for effect_name in effects_section.data:
        sub = effects_section.table(effect_name)
        params = tuple((key, sub.number(key)) for key in list(sub.data))
        sub.done()
        effects.append((effect_name, params))
    effects_section.done()
    motor.done()
    try:
        return MotorParams(**values, name=name, effects=tuple(effects), J_kg_m2=inertia or None)
    except ConfigError as exc:
        raise ConfigError(
            exc.reason, path=path, key=f"motor.{exc.key}" if exc.key else None, expected=exc.expected
        ) from None


def dump_motor_params(params: MotorParams, source: Mapping[str, str] | None = None) -> str:
    """TOML text for a motor that :func:`load_motor_params` reads back exactly."""
    lines = ["[motor]", f"name = {_toml_string(params.name)}"]
    for key in ("R_ohm", "k_e", "C_p", "B", "T_f", "k", "J_kg_m2"):
        if getattr(params, key) is not None:
            lines.append(f"{key} = {float(getattr(params, key))!r}")
    for effect_name, values in params.effects:
        lines += ["", f"[motor.effects.{effect_name}]"]
        lines += [f"{k} = {float(v)!r}" for k, v in values]
    if source:
        lines += ["", "[source]"] + [f"{k} = {_toml_string(str(v))}" for k, v in source.items()]
    return "\n".join(lines) + "\n"


def _toml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _number_rows(
    raw: object, path: Path, key: str, width: int | tuple[int, ...], expected: str
) -> tuple[tuple[float, ...], ...] | None:
    """A TOML list of rows of ``width`` numbers (``current_band_a``, ``activity_band``), or of one of the
    widths given, the same for every row; None if absent."""
    if raw is None:
        return None
    widths = (width,) if isinstance(width, int) else width
    ok = isinstance(raw, list) and all(
        isinstance(row, list)
        and len(row) in widths
        and len(row) == len(raw[0])
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in row)
        for row in raw
    )
    if not ok:
        raise ConfigError(f"{raw!r}", path=path, key=key, expected=expected)
    return tuple(tuple(float(x) for x in row) for row in raw)  # type: ignore[attr-defined]


def _label_numbers(section: _Section, unit: str) -> tuple[tuple[str, float], ...]:
    """A table of state label = number ≥ 0 (``[persistence.announce_s]`` and its per-activity twin)."""
    values = tuple((label, section.number(label, minimum=0.0, unit=unit)) for label in list(section.data))
    section.done()
    return values


#: the range the loader checks each ``[steady]`` setting against (minimum, maximum, unit); the rule checks
#: the rest and holds the defaults (:mod:`.diagnosis.rules`)
_STEADY_RANGES: dict[str, tuple[float | None, float | None, str]] = {
    "step_v": (0.0, None, "V"),
    "settle_s": (0.0, None, "s"),
    "lag_fraction": (0.0, None, ""),
    "residual_tau_s": (0.0, 5.0, "s"),
    "activity_tau_s": (0.0, 60.0, "s"),
    "activity_ref_v": (0.0, None, "V"),
    "residual_tau_max_s": (0.0, 10.0, "s"),
    "slow_factor": (0.0, 100.0, ""),
    "bus_ref_v": (0.0, None, "V"),
    "excursion_weight": (0.0, 1.0, ""),
    "excursion_pairing_weight": (0.0, 1.0, ""),
    "step_sigmas": (0.0, 1000.0, ""),
    "step_over_changes": (0.0, 1.0, ""),
}


#: a number without a range the loader checks (the dataclass checks it)
_ANY: tuple[float | None, float | None, str] = (None, None, "")

_PROFILE_RANGES: dict[str, tuple[float | None, float | None, str]] = {
    "speed_band_rad_s": (0.0, None, "rad/s"),
    "stop_speed_rad_s": (0.0, None, "rad/s"),
    "stall_split_a": (0.0, None, "A"),
    "stall_split_per_v": (None, None, "A/V"),
    "stall_split_ref_v": (0.0, None, "V"),
    "speed_only_band_frac": (0.0, 1.0, ""),
    "free_speed_headroom_fraction": _ANY,  # 0 means the default; the range is checked by the profile
    "stop_speed_fraction": (0.0, 0.99, ""),
    "stop_speed_lowest_fraction": (0.0, 0.99, ""),
    "joint_band_sum": (0.0, 2.0, ""),
    "slow_band_fraction": (0.0, 1.0, ""),
    "min_command": (0.0, 1.0, ""),
    "noise_bands": (0.0, 50.0, ""),
    "stall_split_typical": (0.0, 100.0, ""),
    "range_margin": (0.0, 10.0, ""),
    "range_growth": (0.0, 4.0, ""),
    "conditions_reach": (1.0, 100.0, ""),
    "conditions_growth": (0.0, 4.0, ""),
    "conditions_siblings": (0.0, 100.0, ""),
    "conditions_siblings_s": (0.001, 600.0, "s"),
    "torque_siblings_spread": (0.0, 100.0, ""),
    "slow_siblings": (0.0, 100.0, ""),
    "torque_slow_siblings": (0.0, 100.0, ""),
    "voltage_slow_siblings": (0.0, 100.0, ""),
    "equation_bands": (0.0, 50.0, ""),
    "speed_against_siblings": (0.0, 10.0, ""),
}
_VEHICLE_CHECK_RANGES: dict[str, tuple[float | None, float | None, str]] = {
    "speed_departure": (0.0, 1.0, ""),
    "min_samples": (1.0, None, ""),
    "min_span_s": (0.0, None, "s"),
    "min_motors": (2.0, None, ""),
}
_DETECTION_RANGES: dict[str, tuple[float | None, float | None, str]] = {
    "false_alarms_per_100h": (0.0, None, ""),
    "reference_sigmas": (None, None, "sigma"),
    "min_observations": (0.0, None, ""),
    "hold_sigmas": (0.0, None, "sigma"),
}
_PERSISTENCE_RANGES: dict[str, tuple[float | None, float | None, str]] = {
    "default_announce_s": (0.0, None, "s"),
    "clear_s": (0.0, None, "s"),
    "max_gap_s": (0.0, None, "s"),
    "max_depth": (1.0, None, ""),
}


def _given(
    section: _Section, ranges: Mapping[str, tuple[float | None, float | None, str]]
) -> dict[str, float]:
    """The numbers of ``ranges`` that the table gives, each checked against its (minimum, maximum, unit);
    the keys it does not give keep their dataclass's defaults."""
    values = {}
    for name, (minimum, maximum, unit) in ranges.items():
        if name in section.data:
            values[name] = section.number(name, minimum=minimum, maximum=maximum, unit=unit)
        else:
            section.used.add(name)
    return values


def _compare_rule(section: _Section) -> CompareRule:
    """The ``[steady]`` table's comparison rule: its ``kind`` (default ``step``) with the settings given."""
    kind = section.text("kind", "step")
    names = [name for name in section.data if name != "kind"]
    try:
        check_settings(kind, names)
    except ConfigError as exc:
        raise ConfigError(exc.reason, path=section.path, key=exc.key, expected=exc.expected) from None
    settings = _given(section, {name: _STEADY_RANGES.get(name, _ANY) for name in names})
    return compare_rule(kind, **settings)


def load_profile(name_or_path: str | Path = DEFAULT_PROFILE) -> ThresholdProfile:
    """A threshold profile from a TOML file with ``[profile]``, ``[steady]`` and ``[persistence]``."""
    path = resolve_params_file(name_or_path, "profiles")
    top = _Section(read_toml(path), path, "")
    p = top.table("profile")
    steady = top.table("steady")
    pers = top.table("persistence")
    plaus = top.table("plausibility")
    vehicle = top.table("vehicle_check")
    detection = top.table("detection")
    top.raw("source")
    top.done()
    band = _number_rows(
        p.raw("current_band_a"),
        path,
        "profile.current_band_a",
        2,
        "a list of [voltage_v, halfwidth_a] pairs of numbers",
    )
    activity_band = _number_rows(
        p.raw("activity_band"),
        path,
        "profile.activity_band",
        (3, 4),
        "a list of [activity_v, speed_widening_rad_s, current_widening_a] rows of numbers, or of "
        "[activity_v, speed_widening_rad_s, current_above_a, current_below_a], all of one length",
    )
    announce = _label_numbers(pers.table("announce_s"), "s")
    per_activity = _label_numbers(pers.table("announce_per_activity_s"), "s per V")
    # Only the keys given: the defaults live on the dataclasses
    top_level: dict[str, object] = dict(_given(p, _PROFILE_RANGES))
    if top_level.get("free_speed_headroom_fraction") == 0:  # 0 means the default
        del top_level["free_speed_headroom_fraction"]
    if band is not None:  # absent: the paper's band (an empty list is kept, and refused by the profile)
        top_level["current_band_a"] = band
    if activity_band is not None:
        top_level["activity_band"] = activity_band
    checks: dict[str, float | int] = dict(_given(vehicle, _VEHICLE_CHECK_RANGES))
    for name in ("min_samples", "min_motors"):
        if name in checks:
            checks[name] = int(checks[name])
    try:
        profile = ThresholdProfile(
            name=p.text("name", path.stem),
            description=p.text("description", ""),
            steady=_compare_rule(steady),
            plausibility=PlausibilityRule(**_given(plaus, dict.fromkeys(PlausibilityRule().__dict__, _ANY))),
            vehicle_check=VehicleCheckRule(**checks),  # type: ignore[arg-type]
            detection=SequentialRule(**_given(detection, _DETECTION_RANGES)),
            persistence=PersistenceRule(
                **_given(pers, _PERSISTENCE_RANGES),
                announce_s=announce,
                announce_per_activity_s=per_activity,
            ),
            **top_level,  # type: ignore[arg-type]
        )
    except ConfigError as exc:
        if exc.path is not None:
            raise
        key = exc.key
        if key and key.split(".")[0] not in (
            "steady",
            "persistence",
            "plausibility",
            "vehicle_check",
            "detection",
        ):
            key = f"profile.{key}"
        raise ConfigError(exc.reason, path=path, key=key, expected=exc.expected) from None
    p.done()
    steady.done()
    pers.done()
    plaus.done()
    vehicle.done()
    detection.done()
    return profile


def dump_profile(profile: ThresholdProfile, source: Mapping[str, str] | None = None) -> str:
    """TOML text for a profile that :func:`load_profile` reads back exactly."""
    band = ", ".join(f"[{v!r}, {w!r}]" for v, w in profile.current_band_a)
    lines = [
        "[profile]",
        f"name = {_toml_string(profile.name)}",
        f"description = {_toml_string(profile.description)}",
        f"speed_band_rad_s = {profile.speed_band_rad_s!r}",
        f"current_band_a = [{band}]",
        f"stop_speed_rad_s = {profile.stop_speed_rad_s!r}",
        f"stall_split_a = {profile.stall_split_a!r}",
        f"stall_split_per_v = {profile.stall_split_per_v!r}",
        f"stall_split_ref_v = {profile.stall_split_ref_v!r}",
        f"speed_only_band_frac = {profile.speed_only_band_frac!r}",
        f"free_speed_headroom_fraction = {profile.free_speed_headroom_fraction!r}",
        f"joint_band_sum = {profile.joint_band_sum!r}",
        f"slow_band_fraction = {profile.slow_band_fraction!r}",
        f"stop_speed_fraction = {profile.stop_speed_fraction!r}",
        f"min_command = {profile.min_command!r}",
    ]
    if profile.stop_speed_lowest_fraction:
        lines.append(f"stop_speed_lowest_fraction = {profile.stop_speed_lowest_fraction!r}")
    if profile.activity_band:
        rows = ", ".join("[" + ", ".join(repr(x) for x in row) + "]" for row in profile.activity_band)
        lines.append(f"activity_band = [{rows}]")
    if profile.noise_bands:
        lines.append(f"noise_bands = {profile.noise_bands!r}")
    if profile.stall_split_typical:
        lines.append(f"stall_split_typical = {profile.stall_split_typical!r}")
    if profile.range_margin:
        lines.append(f"range_margin = {profile.range_margin!r}")
    if profile.range_growth:
        lines.append(f"range_growth = {profile.range_growth!r}")
    if profile.conditions_reach != 1.0:
        lines.append(f"conditions_reach = {profile.conditions_reach!r}")
        lines.append(f"conditions_growth = {profile.conditions_growth!r}")
        if profile.conditions_siblings:
            lines.append(f"conditions_siblings = {profile.conditions_siblings!r}")
            lines.append(f"conditions_siblings_s = {profile.conditions_siblings_s!r}")
            if profile.torque_siblings_spread:
                lines.append(f"torque_siblings_spread = {profile.torque_siblings_spread!r}")
            if profile.slow_siblings:
                lines.append(f"slow_siblings = {profile.slow_siblings!r}")
            if profile.torque_slow_siblings:
                lines.append(f"torque_slow_siblings = {profile.torque_slow_siblings!r}")
            if profile.voltage_slow_siblings:
                lines.append(f"voltage_slow_siblings = {profile.voltage_slow_siblings!r}")
    if profile.equation_bands:
        lines.append(f"equation_bands = {profile.equation_bands!r}")
    if profile.speed_against_siblings:
        lines.append(f"speed_against_siblings = {profile.speed_against_siblings!r}")
    lines += [
        "",
        "[steady]",
        f"kind = {_toml_string(profile.steady.kind)}",
        *(f"{f.name} = {getattr(profile.steady, f.name)!r}" for f in fields(profile.steady)),  # type: ignore[arg-type]
        "",
        "[persistence]",
        f"default_announce_s = {profile.persistence.default_announce_s!r}",
        f"clear_s = {profile.persistence.clear_s!r}",
    ]
    if profile.persistence.max_gap_s != float("inf"):
        lines.append(f"max_gap_s = {profile.persistence.max_gap_s!r}")
    if profile.persistence.max_depth != 1:
        lines.append(f"max_depth = {profile.persistence.max_depth!r}")

    if profile.persistence.announce_s:
        lines += ["", "[persistence.announce_s]"]
        lines += [
            f"{_toml_string(label)} = {float(value)!r}" for label, value in profile.persistence.announce_s
        ]
    if profile.persistence.announce_per_activity_s:
        lines += ["", "[persistence.announce_per_activity_s]"]
        lines += [
            f"{_toml_string(label)} = {float(value)!r}"
            for label, value in profile.persistence.announce_per_activity_s
        ]
    check = profile.vehicle_check
    lines += [
        "",
        "[vehicle_check]",
        f"speed_departure = {check.speed_departure!r}",
        f"min_samples = {check.min_samples!r}",
        f"min_span_s = {check.min_span_s!r}",
        f"min_motors = {check.min_motors!r}",
    ]
    if profile.detection.on:
        d = profile.detection
        lines += [
            "",
            "[detection]",
            f"false_alarms_per_100h = {d.false_alarms_per_100h!r}",
            f"reference_sigmas = {d.reference_sigmas!r}",
            f"min_observations = {d.min_observations!r}",
        ]
        if d.hold_sigmas:
            lines.append(f"hold_sigmas = {d.hold_sigmas!r}")
    lines += ["", "[plausibility]"]
    lines += [f"{name} = {value!r}" for name, value in profile.plausibility.__dict__.items()]
    if source:
        lines += ["", "[source]"] + [f"{k} = {_toml_string(str(v))}" for k, v in source.items()]
    return "\n".join(lines) + "\n"


#: the sections a vehicle file adds to a motor file (``fit LOG --out``): see :func:`load_vehicle_params`
VEHICLE_SECTIONS = ("esc", "current", "per_motor", "noise")
#: the most motor outputs an autopilot drives (ArduPilot and PX4: 32)
MAX_MOTOR_NUMBER = 32


def load_vehicle_params(name_or_path: str | Path = DEFAULT_MOTOR) -> VehicleParams:
    """A vehicle from a params TOML: the ``[motor]`` type (:func:`load_motor_params`) and, where the file
    was written by identification (``fit LOG --out``), ``[esc]`` (the command → duty map), ``[current]``
    (how the ESCs report current), ``[per_motor.N]`` (motor N's R and k_e) and ``[noise.N]`` (motor N's
    balance residuals). A motor file without them gives a vehicle with no ESC map."""
    path = resolve_params_file(name_or_path, "motors")
    motor = load_motor_params(path)
    data = read_toml(path)
    top = _Section(data, path, "")
    esc: EscMap | None = None
    if "esc" in data:
        section = top.table("esc")
        esc = EscMap(idle_offset=section.number("idle_offset", minimum=-0.1, maximum=0.5, unit="(command)"))
        section.done()
    current: CurrentReading | None = None
    if "current" in data:
        section = top.table("current")
        side = section.text("side", "input")
        if side not in CURRENT_SIDES:
            raise ConfigError(
                f"{side!r}", path=path, key="current.side", expected=f"one of {', '.join(CURRENT_SIDES)}"
            )
        current = CurrentReading(
            side=side,
            gain=section.number("gain", 1.0, minimum=0.01, maximum=100.0),
            gain_from=section.text("gain_from", "assumed"),
            offset_a=section.number("battery_offset_a", 0.0, unit="A"),
        )
        section.done()
    per_motor: dict[int, MotorParams] = {}
    for number, section in _motor_tables(top, "per_motor", path):
        values = {
            "R_ohm": section.number("R_ohm", motor.R_ohm, minimum=1e-6, unit="ohm"),
            "k_e": section.number("k_e", motor.k_e, minimum=1e-7, unit="V*s/rad"),
        }
        section.done()
        per_motor[number] = motor.replace(**values, name=f"{motor.name}, motor {number}")
    noise: dict[int, dict[str, float]] = {}
    for number, section in _motor_tables(top, "noise", path):
        noise[number] = {
            key: section.number(key, minimum=None if key in SIGNED_NOISE_KEYS else 0.0, unit=unit)
            for key, unit in (("voltage_v", "V"), ("torque_nm", "N*m"), *NOISE_KEYS.items())
            if key in section.data
        }
        section.done()
    raw_source = data.get("source", {})
    source = {str(k): str(v) for k, v in raw_source.items()} if isinstance(raw_source, Mapping) else {}
    return VehicleParams(
        motor=motor, per_motor=per_motor, esc=esc, current=current, noise=noise, source=source
    )


#: the profile a vehicle is diagnosed with unless one is named: bands in units of its own noise where its
#: file carries the noise (written by ``fit``), else the flight profile's absolute bands
VEHICLE_PROFILE, FALLBACK_PROFILE = "flight_vehicle", "flight"


def default_profile(vehicle: VehicleParams) -> str:
    """:data:`VEHICLE_PROFILE` for a vehicle file that carries each motor's band noise, else
    :data:`FALLBACK_PROFILE` (a bundled motor, a bench fit, a vehicle file from before the noise)."""
    return VEHICLE_PROFILE if band_noise_of(vehicle.noise) else FALLBACK_PROFILE


def check_profile_for_vehicle(profile: ThresholdProfile, vehicle: VehicleParams) -> None:
    """Refuse a profile with bands in amperes and rad/s (``noise_bands`` 0) for a vehicle file that
    carries the vehicle's own band noise (written by ``fit`` from its flight): those bands were set on the
    project's simulated hexacopter and ignore the noise this vehicle was measured to have; on vehicles
    unlike the simulator's, and on the real PX4 quad in shared/real_logs, they raise faults on healthy
    motors (docs/flight.md)."""
    if profile.noise_bands == 0 and band_noise_of(vehicle.noise):
        raise ConfigError(
            f"profile {profile.name!r} has bands in amperes and rad/s set on the project's simulated "
            "hexacopter, while the vehicle file carries this vehicle's own noise (identified from its "
            f"flight); on other vehicles such bands name faults on healthy motors. Use {VEHICLE_PROFILE!r} "
            "(the default for this file)",
            key="profile",
            expected=f"a profile with bands in noise units (noise_bands > 0), such as {VEHICLE_PROFILE!r}",
        )


def _motor_tables(top: _Section, name: str, path: Path) -> list[tuple[int, _Section]]:
    """``[name.N]`` tables keyed by motor number N (1..32)."""
    section = top.table(name)
    out = []
    for key in list(section.data):
        if not (str(key).isdigit() and 1 <= int(key) <= MAX_MOTOR_NUMBER):
            raise ConfigError(
                f"{key!r}", path=path, key=f"{name}.{key}", expected=f"a motor number 1..{MAX_MOTOR_NUMBER}"
            )
        out.append((int(key), section.table(str(key))))
    section.done()
    return out


def dump_vehicle_params(vehicle: VehicleParams, source: Mapping[str, str] | None = None) -> str:
    """TOML text for a vehicle that :func:`load_vehicle_params` reads back exactly."""
    lines = [dump_motor_params(vehicle.motor).rstrip("\n")]
    if vehicle.esc is not None:
        lines += [
            "",
            "[esc]  # duty = clip((command - idle_offset) / (1 - idle_offset), 0, 1), command 0..1",
            f"idle_offset = {float(vehicle.esc.idle_offset)!r}",
        ]
    if vehicle.current is not None:
        c = vehicle.current
        lines += [
            "",
            "[current]  # side: input (battery side, duty x motor current) | motor (phase) | unusable",
            f"side = {_toml_string(c.side)}",
            f"gain = {float(c.gain)!r}  # reading / true current",
            f"gain_from = {_toml_string(c.gain_from)}",
            f"battery_offset_a = {float(c.offset_a)!r}  # the rest of the vehicle's draw",
        ]
    for number, params in sorted(vehicle.per_motor.items()):
        lines += ["", f"[per_motor.{number}]", f"R_ohm = {params.R_ohm!r}", f"k_e = {params.k_e!r}"]
    for number, values in sorted(vehicle.noise.items()):
        finite = {k: v for k, v in values.items() if math.isfinite(v)}
        if finite:
            lines += ["", f"[noise.{number}]"] + [f"{k} = {float(v)!r}" for k, v in finite.items()]
    merged = {**vehicle.source, **(source or {})}
    if merged:
        lines += ["", "[source]"] + [f"{k} = {_toml_string(str(v))}" for k, v in merged.items()]
    return "\n".join(lines) + "\n"
