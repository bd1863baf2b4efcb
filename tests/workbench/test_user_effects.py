"""User effects: a file on the command line and an installed entry point, found and used like built-ins."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.config import dump_motor_params, load_motor_params
from mav_motor_health.errors import ConfigError
from mav_motor_health.model.effects import ENTRY_POINT_GROUP, available_effects, load_effects_file
from mav_motor_health.model.params import MotorParams
from mav_motor_health.model.predict import predict_steady
from mav_motor_health.workbench import distance_correlation

MODULE = '''
from mav_motor_health.model.effects import Effect, EffectParameter


def esc_idle_current(terms, p, data):
    """The ESC's own consumption adds a constant current to what the bus sensor reports."""
    return terms.replace(current_offset_a=terms.current_offset_a + p["idle_a"])


EFFECTS = [Effect("esc_idle", esc_idle_current, (EffectParameter("idle_a", "A", 0.0, 2.0, 0.1, 0.0),))]
'''


def test_an_installed_entry_point_is_found_and_a_saved_model_uses_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, paper_motor: MotorParams
) -> None:
    (tmp_path / "demo_effects_mod.py").write_text(MODULE, encoding="utf-8")
    dist = tmp_path / "demo_effects-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: demo-effects\nVersion: 0.1\n", encoding="utf-8"
    )
    (dist / "entry_points.txt").write_text(
        f"[{ENTRY_POINT_GROUP}]\nidle = demo_effects_mod:EFFECTS\n", encoding="utf-8"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    registry = available_effects()
    assert "esc_idle" in registry and "resistance_temperature" in registry

    # A motor saved with the user effect loads back and predicts with it (what replay/agent do).
    params = paper_motor.replace(effects=(("esc_idle", (("idle_a", 0.5),)),))
    path = tmp_path / "motor.toml"
    path.write_text(dump_motor_params(params), encoding="utf-8")
    loaded = load_motor_params(path)
    v = np.linspace(4, 11, 8)
    with_effect = predict_steady(loaded, v)
    base = predict_steady(paper_motor, v)
    np.testing.assert_allclose(with_effect.current_a - base.current_a, 0.5)
    np.testing.assert_allclose(with_effect.omega_rad_s, base.omega_rad_s)


def test_unknown_effect_in_a_model_is_a_clear_error(paper_motor: MotorParams) -> None:
    params = paper_motor.replace(effects=(("no_such_effect", (("x", 1.0),)),))
    with pytest.raises(ConfigError, match=r"no_such_effect.*entry point"):
        predict_steady(params, [5.0])


def test_effects_file_errors_name_the_file(tmp_path: Path) -> None:
    empty = tmp_path / "empty.py"
    empty.write_text("x = 1\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"empty\.py.*declares no effect"):
        load_effects_file(empty)
    broken = tmp_path / "broken.py"
    broken.write_text("raise RuntimeError('oops')\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"broken\.py.*oops"):
        load_effects_file(broken)
    with pytest.raises(ConfigError, match="not found"):
        load_effects_file(tmp_path / "missing.py")


def test_distance_correlation_sees_non_linear_dependence() -> None:
    rng = np.random.default_rng(9)
    x = rng.uniform(-1, 1, 300)
    parabola = x**2 + rng.normal(0, 0.05, 300)
    assert abs(np.corrcoef(x, parabola)[0, 1]) < 0.2  # invisible to correlation
    assert distance_correlation(x, parabola) > 0.4
    assert distance_correlation(x, rng.normal(size=300)) < 0.15
