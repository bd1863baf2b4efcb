"""The CSV table and the fit / predict / diagnose / demo commands, called as a user would."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.cli import main
from mav_motor_health.config import load_motor_params
from mav_motor_health.errors import DataError
from mav_motor_health.model import steady_state
from mav_motor_health.sim.steady import PAPER_VOLTAGES_V, steady_measurements
from mav_motor_health.telemetry import TelemetryTable, read_csv, write_csv


def bench_csv(tmp_path: Path, paper_motor, *, throttle: bool = False) -> Path:
    rng = np.random.default_rng(42)
    v, i, w = steady_measurements(paper_motor, PAPER_VOLTAGES_V, 300, rng)
    cols = {
        "time_s": np.arange(v.size) / 40.0,
        "motor": np.ones(v.size, int),
        "rpm": w * 60 / (2 * math.pi),
        "current_a": i,
        "esc_temp_c": np.full(v.size, 35.0),
    }
    if throttle:
        cols.update(bus_voltage_v=np.full(v.size, 12.0), throttle=v / 12.0)
    else:
        cols["voltage_v"] = v
    path = tmp_path / "bench.csv"
    write_csv(TelemetryTable(cols | {"omega_rad_s": w}), path, columns=list(cols))
    return path


def test_csv_reads_rpm_and_context(tmp_path, paper_motor) -> None:
    table = read_csv(bench_csv(tmp_path, paper_motor))
    assert {"time_s", "motor", "omega_rad_s", "current_a", "voltage_v", "esc_temp_c"} <= set(table.names)
    assert table["omega_rad_s"].max() == pytest.approx(908, abs=15)


def test_csv_throttle_and_bus_voltage(tmp_path, paper_motor) -> None:
    table = read_csv(bench_csv(tmp_path, paper_motor, throttle=True))
    np.testing.assert_allclose(table.voltage_v(), table["throttle"] * 12.0)


def test_csv_bad_cells_are_kept_as_missing_with_one_warning(tmp_path) -> None:
    path = tmp_path / "t.csv"
    path.write_text(
        "time_s,motor,rpm,current_a,voltage_v,note\n0,1,5000,3.0,8,ok\n0.1,1,oops,3.1,8,x\n"
        "0.2,1,5010,3.2,8,y\n0.3,x,5010,3.2,8,z\n"
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = read_csv(path)
    messages = [str(w.message) for w in caught]
    assert any("column 'rpm'" in m and "line 3" in m for m in messages)
    assert any("no valid motor number" in m and "line 5" in m for m in messages)
    assert len(table) == 3 and np.isnan(table["omega_rad_s"][1]) and "note" not in table


def test_csv_missing_columns_error_names_file_and_what_is_expected(tmp_path) -> None:
    path = tmp_path / "t.csv"
    path.write_text("time_s,motor,rpm\n0,1,5\n")
    with pytest.raises(DataError) as info:
        read_csv(path)
    assert str(path) in str(info.value) and "current_a" in str(info.value) and "voltage_v" in str(info.value)


def test_fit_json_and_params_round_trip(tmp_path, paper_motor, capsys) -> None:
    data = bench_csv(tmp_path, paper_motor)
    out = tmp_path / "fitted.toml"
    assert main(["fit", str(data), "--json", "--out", str(out)]) == 0
    result = json.loads(capsys.readouterr().out)
    assert set(result["params"]) == {"R_ohm", "k_e", "C_p", "B", "T_f", "k"}
    assert "stderr" in result and "rmse" in result
    assert result["params"]["R_ohm"] == pytest.approx(0.165, rel=0.03)
    fitted = load_motor_params(out)
    assert fitted.k_e == pytest.approx(result["params"]["k_e"])
    # the written file is accepted by every command taking --params, and never overwritten silently
    assert main(["predict", "--voltage", "11", "--params", str(out), "--json"]) == 0
    pred = json.loads(capsys.readouterr().out)[0]
    assert pred["omega_rad_s"] == pytest.approx(float(steady_state(fitted, 11.0).omega_rad_s))
    before = out.read_text()
    assert main(["fit", str(data), "--out", str(out)]) == 2
    assert "exists already" in capsys.readouterr().err and out.read_text() == before


def test_diagnose_prints_a_state_per_sample(tmp_path, paper_motor, capsys) -> None:
    data = bench_csv(tmp_path, paper_motor)
    assert main(["diagnose", str(data), "--profile", "testbed"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("time_s,motor,state,announced,steady")
    assert len(lines) == 1 + 11 * 300
    states = [line.split(",")[3] for line in lines[1:]]
    assert states.count("NORMAL") / len(states) > 0.99


def test_diagnose_summary_and_bad_file(tmp_path, paper_motor, capsys) -> None:
    assert main(["diagnose", str(bench_csv(tmp_path, paper_motor)), "--summary"]) == 0
    assert capsys.readouterr().out.startswith("motor 1: final NORMAL")
    assert main(["diagnose", str(tmp_path / "missing.csv")]) == 2
    assert "file not found" in capsys.readouterr().err


def test_demo_diagnoses_every_fault(capsys) -> None:
    from mav_motor_health.commands.demo import run_demo

    text, results = run_demo(seed=3)
    assert "Calibration" in text
    assert len(results) == 25
    for (fault, _volts), (final, delay) in results.items():
        assert final == fault and delay < 5.0  # F3.1 at 4.2 V too: see the next test


def test_propeller_loss_at_low_voltage_is_named_within_the_free_speed_headroom(
    paper_motor, testbed_profile, capsys
) -> None:
    # Even with no propeller at all the motor cannot exceed its free speed V/k_e; at 4.2 V that is only
    # ~20.4 rad/s above the model, the ±20 rad/s band itself. The tree's band above the model is
    # clip(0.5·headroom, band/2, band) = 10.2 rad/s there, so the committed 4.2 V run ends in F3.1,
    # and the healthy 4.2 V run stays NORMAL.
    no_prop = steady_state(paper_motor.replace(C_p=0.0, B=0.0, T_f=0.0), 4.2).omega_rad_s
    model = steady_state(paper_motor, 4.2).omega_rad_s
    free = 4.2 / paper_motor.k_e
    assert no_prop == pytest.approx(free)  # with no load at all, the free speed
    assert testbed_profile.speed_band_rad_s < free - model < 1.05 * testbed_profile.speed_band_rad_s
    fraction = testbed_profile.free_speed_headroom_fraction
    assert fraction * (free - model) < 0.55 * testbed_profile.speed_band_rad_s
    logs = Path(__file__).resolve().parents[1] / "sitl_logs"
    assert main(["diagnose", str(logs / "testbed_F3.1_4.2V.csv"), "--summary", "--profile", "testbed"]) == 0
    assert capsys.readouterr().out.startswith("motor 1: final F3.1")
    assert (
        main(["diagnose", str(logs / "testbed_healthy_4.2V.csv"), "--summary", "--profile", "testbed"]) == 0
    )
    out = capsys.readouterr().out
    assert out.startswith("motor 1: final NORMAL") and "NORMAL 100.0 %" in out
