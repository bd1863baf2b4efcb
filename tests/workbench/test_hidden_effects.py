"""Data with a hidden effect: explain must find it, and fitting with it must reach the noise floor."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.cli import main
from mav_motor_health.model.effects import BUILTIN_EFFECTS, load_effects_file
from mav_motor_health.model.effects.fit import fit_effects
from mav_motor_health.model.params import MotorParams
from mav_motor_health.telemetry.csv import write_csv
from mav_motor_health.telemetry.table import TelemetryTable
from mav_motor_health.workbench import WorkbenchData, explain, fit_base, noise_floor

from .conftest import HIDDEN, session

WITHIN_NOISE = 1.10  # "within 10 % of the noise floor"


@pytest.mark.parametrize("name", sorted(HIDDEN))
def test_explain_ranks_the_hidden_effect_first_and_fitting_it_reaches_the_noise_floor(
    name: str, hidden_sessions: dict[str, TelemetryTable]
) -> None:
    data = WorkbenchData.from_table(hidden_sessions[name])
    result = explain(data, seed=0)
    assert result.effects[0].name == name, result.report()
    assert result.best is not None and result.best.name == name
    assert result.effects[0].heldout_before > 1.15, "the hidden effect should be visible above noise"

    nf = noise_floor(data.time_s, data.motor, data.voltage_v, data.omega_rad_s, data.current_a)
    base = fit_base(data).params
    fit = fit_effects(
        base,
        [BUILTIN_EFFECTS[name]],
        data.voltage_v,
        data.omega_rad_s,
        data.current_a,
        data.context,
        sigma=(nf.omega_rad_s, nf.current_a),
    )
    assert fit.rmse_omega_rad_s <= WITHIN_NOISE * nf.omega_rad_s, fit.report()
    assert fit.rmse_current_a <= WITHIN_NOISE * nf.current_a, fit.report()
    # The hidden parameters are recovered (loosely: near-aliased effects may trade a little).
    for key, truth in HIDDEN[name].items():
        got = dict(fit.params.effects[0][1])[key]
        if key == "delta_k":  # the exponent is k + Δk, whichever integer k the fit chose
            got, truth = fit.params.k + got, base.k * 0 + 3.0 + truth
        scale = max(abs(truth), 0.05 * (BUILTIN_EFFECTS[name].parameters[0].upper))
        assert abs(got - truth) <= 0.35 * scale, (key, got, truth)


def test_no_hidden_effect_reports_nothing_significant(paper_motor: MotorParams) -> None:
    data = WorkbenchData.from_table(session(paper_motor, [], seed=5))
    result = explain(data, seed=0)
    assert result.best is None, result.report()
    assert not result.significant_variables, result.report()
    assert "nothing explains the residual beyond noise" in result.verdict()
    assert not any(e.significant for e in result.effects)


USER_EFFECT_FILE = '''
"""A made-up effect no library has: the current sensor's zero drifts with the ESC's temperature."""
from mav_motor_health.model.effects import Effect, EffectParameter


def hall_sensor_drift(terms, p, data):
    """Hall current sensor zero drift: the reported current is offset by gain·(T_esc − 25 °C)."""
    drift = p["gain_a_per_k"] * (data["esc_temp_c"] - 25.0)
    return terms.replace(current_offset_a=terms.current_offset_a + drift)


EFFECTS = [
    Effect(
        "hall_drift",
        hall_sensor_drift,
        (EffectParameter("gain_a_per_k", "A/K", -0.1, 0.1, 0.0, 0.0, "offset per kelvin"),),
        needs=("esc_temp_c",),
    )
]
'''


def _made_up_truth(terms, p, data):
    """Truth of the made-up effect, written independently of the user's file."""
    return terms.replace(current_offset_a=terms.current_offset_a + 0.015 * (data["esc_temp_c"] - 25.0))


@pytest.fixture(scope="module")
def unknown_effect_table(paper_motor: MotorParams) -> TelemetryTable:
    from mav_motor_health.model.effects import Effect, EffectParameter

    truth = Effect(
        "truth", _made_up_truth, (EffectParameter("unused", "1", 0.0, 1.0, 0.0),), needs=("esc_temp_c",)
    )
    return session(paper_motor, [(truth, {})], seed=7)


def test_unknown_effect_names_the_variable_and_a_user_effect_repairs_it(
    unknown_effect_table: TelemetryTable, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = WorkbenchData.from_table(unknown_effect_table)
    result = explain(data, seed=0)
    assert result.variables[0].name == "esc_temp_c", result.report()
    assert result.variables[0].significant
    best = result.effects[0]
    assert best.heldout_after > WITHIN_NOISE, "no library effect should repair a made-up effect"

    effect_file = tmp_path / "hall_drift.py"
    effect_file.write_text(USER_EFFECT_FILE, encoding="utf-8")
    (user,) = load_effects_file(effect_file)
    nf = noise_floor(data.time_s, data.motor, data.voltage_v, data.omega_rad_s, data.current_a)
    fit = fit_effects(
        fit_base(data).params,
        [user],
        data.voltage_v,
        data.omega_rad_s,
        data.current_a,
        data.context,
        sigma=(nf.omega_rad_s, nf.current_a),
    )
    assert fit.rmse_omega_rad_s <= WITHIN_NOISE * nf.omega_rad_s
    assert fit.rmse_current_a <= WITHIN_NOISE * nf.current_a
    assert dict(fit.params.effects[0][1])["gain_a_per_k"] == pytest.approx(0.015, rel=0.1)

    # Ranked exactly like the built-ins: explain with the user's file puts it first (command line, JSON).
    csv = tmp_path / "session.csv"
    write_csv(unknown_effect_table, csv)
    assert main(["explain", str(csv), "--effects-file", str(effect_file), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["effects"][0]["name"] == "hall_drift"
    assert out["variables"][0]["name"] == "esc_temp_c"
    assert {"name", "error_before", "error_after", "parameters"} <= set(out["effects"][0])
    assert {"name", "score"} <= set(out["variables"][0])
    assert np.isfinite(out["effects"][0]["error_after"]["omega_rad_s"])
