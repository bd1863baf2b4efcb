"""The bench fit through the ESC map (issue 16): the DTU stand's one motor on four propellers, and the
other stands' files through the same path.

The DTU files give the ESC command (0..1024 = 1..2 ms) and the *battery* voltage and current, so the fit
must find the ESC's idle offset and the side the current is read on. The issue's "done when" bounds are
not reached on these files (k_e spread over the four propellers 13.7 %, asked 3 %; docs/model.md, "The
ESC map in the bench fit"): what is tested here is what holds, and the figures stand in the docs.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.cli import main
from mav_motor_health.commands.fit import fit_table
from mav_motor_health.config import load_motor_params, read_toml
from mav_motor_health.model.equations import steady_state
from mav_motor_health.model.esc import IDLE_OFFSET_RANGE
from mav_motor_health.model.estimation import FitResult, estimate, estimate_with_esc
from mav_motor_health.model.params import MotorParams
from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.table import TelemetryTable

PROPELLERS = ("14x5.5", "18x5.5", "8x3.8", "9x4.5")
#: 60/(2π·700): the back-EMF constant of a 700 KV motor [V·s/rad]
KV_K_E = 60.0 / (2.0 * math.pi * 700.0)


def dtu_file(real_logs: Path, propeller: str) -> Path:
    return real_logs / "bench" / "dtu" / f"3508-700_{propeller}.txt"


@pytest.fixture(scope="module")
def dtu_fits(real_logs: Path) -> dict[str, FitResult]:
    return {prop: fit_table(sources.read(dtu_file(real_logs, prop)), esc_map=True) for prop in PROPELLERS}


def spread(values: list[float]) -> float:
    return max(values) / min(values) - 1.0


def test_the_dtu_fit_goes_through_the_esc_map_and_reports_it(dtu_fits: dict[str, FitResult]) -> None:
    for prop, result in dtu_fits.items():
        assert result.esc is not None, prop
        assert result.esc.current_side in ("input", "motor")
        assert set(result.esc.residual_v) == {"input", "motor"}
        assert result.esc.current_side == min(result.esc.residual_v, key=result.esc.residual_v.__getitem__)
        assert IDLE_OFFSET_RANGE[0] <= result.esc.esc.idle_offset <= IDLE_OFFSET_RANGE[1]
        p = result.params
        assert min(p.C_p, p.B, p.T_f) >= 0.0 and p.R_ohm > 0 and p.k_e > 0, prop
        text = result.report()
        assert (
            "ESC map: idle offset" in text and f"current read on the {result.esc.current_side} side" in text
        )
        assert "forward accuracy from voltage:" in text and "idle_offset" in result.to_dict()["stderr"]
        assert result.to_dict()["esc"]["current_side"] == result.esc.current_side


def test_the_esc_map_narrows_the_motor_across_the_propellers(
    real_logs: Path, dtu_fits: dict[str, FitResult]
) -> None:
    """Taking command × battery voltage for the motor's voltage (as before) spreads k_e over 52 %."""
    ideal = []
    for prop in PROPELLERS:
        table = sources.read(dtu_file(real_logs, prop))
        arrays = (table.voltage_v(), table["current_a"], table["omega_rad_s"])
        ideal.append(estimate(*arrays, min_samples=1).params.k_e)
    with_map = [r.params.k_e for r in dtu_fits.values()]
    assert spread(with_map) < 0.5 * spread(ideal)
    assert max(abs(k / KV_K_E - 1) for k in with_map) < max(abs(k / KV_K_E - 1) for k in ideal)


def test_the_dtu_propeller_loads_stay_physical(dtu_fits: dict[str, FitResult]) -> None:
    for prop, result in dtu_fits.items():
        assert min(result.params.C_p, result.params.B, result.params.T_f) >= 0.0, prop


def test_the_esc_map_is_opt_in_and_the_default_bench_fit_is_unchanged(real_logs: Path) -> None:
    table = sources.read(dtu_file(real_logs, "14x5.5"))
    default = fit_table(table)
    assert default.esc is None
    arrays = (table.voltage_v(), table["current_a"], table["omega_rad_s"])
    assert default.params == estimate(*arrays, min_samples=1, name="fitted motor").params


def esc_bench(
    motor: MotorParams, idle_offset: float, side: str, rng: np.random.Generator
) -> tuple[np.ndarray, ...]:
    """18 steady steps of ``motor`` behind an ESC with this idle offset, from a sagging battery, read as
    a test stand reads them: command, bus voltage, current on ``side``, speed, with small noise."""
    command = np.linspace(0.15, 1.0, 18)
    duty = (command - idle_offset) / (1.0 - idle_offset)
    battery = 12.6 - 0.03 * steady_state(motor, duty * 12.6).current_a * duty  # 30 mOhm of battery
    truth = steady_state(motor, duty * battery)
    current = truth.current_a * duty if side == "input" else truth.current_a
    return (
        command,
        battery + rng.normal(0.0, 0.02, command.size),
        current + rng.normal(0.0, 0.02, command.size),
        truth.omega_rad_s + rng.normal(0.0, 1.0, command.size),
    )


@pytest.mark.parametrize("side", ["input", "motor"])
def test_the_esc_map_and_the_motor_are_recovered_from_a_simulated_stand(
    paper_motor: MotorParams, side: str
) -> None:
    for seed in range(3):
        data = esc_bench(paper_motor, 0.06, side, np.random.default_rng(seed))
        result = estimate_with_esc(*data, bin_width_v=None)
        assert result.esc is not None and result.esc.current_side == side
        assert result.esc.esc.idle_offset == pytest.approx(0.06, abs=0.005)
        assert result.params.k_e == pytest.approx(paper_motor.k_e, rel=0.01)
        assert result.params.R_ohm == pytest.approx(paper_motor.R_ohm, rel=0.05)
        assert result.params.k == 3 and result.forward_accuracy_pct["current"] > 99.0


def test_a_table_with_the_motor_voltage_is_fitted_without_an_esc_map(paper_motor: MotorParams) -> None:
    command, bus, current, omega = esc_bench(paper_motor, 0.0, "motor", np.random.default_rng(1))
    table = TelemetryTable.from_columns(
        time_s=np.arange(command.size, dtype=float),
        motor=np.ones(command.size, dtype=int),
        omega_rad_s=omega,
        current_a=current,
        throttle=command,
        bus_voltage_v=bus,
        voltage_v=command * bus,
    )
    result = fit_table(table)
    assert result.esc is None and "ESC map" not in result.report() and "esc" not in result.to_dict()


def test_every_bench_format_runs_through_the_esc_map(real_logs: Path) -> None:
    bench = real_logs / "bench"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the readers' notes on skipped rows are not what is tested here
        tables = {
            "sunny": sources.read(bench / "dtu" / "sunny_300kv_24x7.5_22V.txt"),
            "strawson": sources.read(bench / "strawson" / "rawdata" / "a1_11.csv"),
            "ctu": sources.read(bench / "ctu" / "motor_tests_extracted.csv"),
        }
    for name, table in tables.items():
        result = fit_table(table, motors=[1], esc_map=True)
        assert result.esc is not None, name
        assert min(result.params.C_p, result.params.B, result.params.T_f) >= 0.0, name


def test_fit_out_writes_the_bench_esc_as_provenance(real_logs: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "3508.toml"
    assert main(["fit", str(dtu_file(real_logs, "14x5.5")), "--esc-map", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "ESC map: idle offset" in text
    fitted = load_motor_params(out)
    source = read_toml(out)["source"]
    assert float(source["bench_esc_idle_offset"]) == pytest.approx(0.0349, abs=0.005)
    assert source["bench_current_side"] in ("input", "motor")
    assert "esc" not in read_toml(out)  # the stand's ESC is not a map for flight logs
    assert fitted.k_e == pytest.approx(0.0150, rel=0.02)
