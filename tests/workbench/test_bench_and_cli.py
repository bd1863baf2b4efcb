"""Real bench data through the readers and the workbench; the CLI end to end; diagnosis with effects."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.cli import main
from mav_motor_health.config import load_motor_params
from mav_motor_health.diagnosis.pipeline import diagnose
from mav_motor_health.errors import DataError
from mav_motor_health.model.equations import steady_state
from mav_motor_health.model.params import MotorParams
from mav_motor_health.model.predict import predict_steady
from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.bench import bench_format, read_bench
from mav_motor_health.telemetry.csv import write_csv
from mav_motor_health.telemetry.table import TelemetryTable
from mav_motor_health.workbench import WorkbenchData, compare, explain, fit_base, noise_floor


def test_strawson_reader_speed_is_mechanical_as_the_kv_rating_shows(bench_logs: Path) -> None:
    path = bench_logs / "strawson" / "rawdata" / "a1_11.csv"
    assert bench_format(path) == "strawson"
    table = sources.read(path)  # dispatched by content, not just by extension
    assert table.meta["pole_pairs"] == 1
    assert len(table) == 11
    # Row 1: 3421 RPM at 1050 µs, 11.09 V, 0.511 A.
    assert table["omega_rad_s"][0] == pytest.approx(3421 * 2 * math.pi / 60)
    assert read_bench(path, pole_pairs=7)["omega_rad_s"][0] == pytest.approx(3421 / 7 * 2 * math.pi / 60)
    # The evidence: the back-EMF constant fitted with this reading matches the EMAX RS2205S's 2600 KV.
    k_e = fit_base(WorkbenchData.from_table(table).usable()).params.k_e
    assert k_e == pytest.approx(60 / (2 * math.pi * 2600), rel=0.2)
    assert table["throttle"][0] == pytest.approx(0.05)
    assert table["bus_voltage_v"][0] == pytest.approx(11.0911, abs=1e-3)
    assert "voltage_v" not in table  # the battery's voltage is not the motor's
    assert np.allclose(table.voltage_v(), table["throttle"] * table["bus_voltage_v"])


def test_ctu_and_dtu_readers(bench_logs: Path) -> None:
    ctu = read_bench(bench_logs / "ctu" / "motor_tests_extracted.csv")
    assert ctu.motors() == list(range(1, 11)) and len(ctu) == 60
    assert "2312 920KV" in ctu.meta["motors"][1]
    assert ctu["omega_rad_s"][0] == pytest.approx(5688 * 2 * math.pi / 60)
    dtu = sources.read(bench_logs / "dtu" / "3508-700_14x5.5.txt")
    assert dtu["omega_rad_s"][0] == pytest.approx((8.27 + 8.27) / 2 * 2 * math.pi)
    assert dtu["throttle"][0] == pytest.approx(100 / 1024)
    assert dtu["motor_temp_c"][0] == pytest.approx(38.8)
    assert dtu["thrust_n"][1] == pytest.approx(54 * 9.80665e-3)


def test_reader_errors_name_the_file(tmp_path: Path) -> None:
    bogus = tmp_path / "notes.txt"
    bogus.write_text("hello\n", encoding="utf-8")
    with pytest.raises(DataError, match=r"notes\.txt"):
        sources.read(bogus)
    damaged = tmp_path / "stand.txt"
    damaged.write_text(
        "% Measurement from esc,motor,propeller test\n100 8 8 11 0.1 10 0 30 30\nbroken line\n"
        "200 18 18 11 0.4 54 0 30 30\n300 30 30 11 1.2 136 0 30 30\n",
        encoding="utf-8",
    )
    with pytest.warns(UserWarning, match="line 3"):
        table = sources.read(damaged)
    assert len(table) == 3  # partial data used


def test_workbench_runs_on_every_real_bench_format(bench_logs: Path) -> None:
    files = [
        bench_logs / "dtu" / "3508-700_14x5.5.txt",
        bench_logs / "strawson" / "rawdata" / "a1_11.csv",
    ]
    for path in files:
        data = WorkbenchData.from_table(sources.read(path))
        result = compare(data)
        assert result.forward[0].n >= 8
        assert math.isfinite(result.forward[1].rmse)
    ctu = WorkbenchData.from_table(read_bench(bench_logs / "ctu" / "motor_tests_extracted.csv"))
    one = ctu.select(np.flatnonzero(ctu.motor == 1))
    assert compare(one).forward[0].n == 6


def test_explain_on_real_dtu_bench_finds_the_esc_pwm_effect(bench_logs: Path) -> None:
    """The DTU stand measures battery voltage and battery current: the ESC's PWM is what is missing."""
    data = WorkbenchData.from_table(sources.read(bench_logs / "dtu" / "3508-700_14x5.5.txt"))
    result = explain(data, seed=0)
    assert result.best is not None and result.best.name == "esc_pwm", result.report()
    assert result.best.parameters["bus_current_fraction"] > 0.7


def test_noise_floor_recovers_known_noise() -> None:
    rng = np.random.default_rng(4)
    v = np.repeat(np.linspace(3, 11, 40), 25)
    t = np.arange(len(v)) * 0.1
    w = 100 * v + rng.normal(0, 4.0, len(v))
    i = 0.05 * v**2 + rng.normal(0, 0.2, len(v))
    nf = noise_floor(t, np.ones(len(v)), v, w, i)
    assert nf.method == "repeated"
    assert nf.omega_rad_s == pytest.approx(4.0, rel=0.08)
    assert nf.current_a == pytest.approx(0.2, rel=0.08)
    # One sample per step: the second-difference estimator over voltage.
    one = np.arange(0, len(v), 25)
    nf1 = noise_floor(t[one], np.ones(len(one)), v[one] + 0.0, w[one], i[one])
    assert nf1.method == "voltage-difference"
    assert nf1.omega_rad_s == pytest.approx(4.0, rel=0.5)


def test_predict_steady_without_effects_is_the_base_model(paper_motor: MotorParams) -> None:
    v = np.linspace(0, 12, 50)
    a, b = predict_steady(paper_motor, v), steady_state(paper_motor, v)
    np.testing.assert_array_equal(a.omega_rad_s, b.omega_rad_s)
    np.testing.assert_array_equal(a.current_a, b.current_a)


def test_fit_with_saves_a_model_that_compare_and_diagnose_use(
    hidden_sessions: dict[str, TelemetryTable],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    testbed_profile,
) -> None:
    table = hidden_sessions["resistance_temperature"]
    csv = tmp_path / "session.csv"
    write_csv(table, csv)
    out = tmp_path / "motor.toml"
    plot = tmp_path / "steps.png"
    assert (
        main(
            [
                "fit",
                str(csv),
                "--with",
                "resistance_temperature",
                "--out",
                str(out),
                "--plot",
                str(plot),
                "--json",
            ]
        )
        == 0
    )
    report = json.loads(capsys.readouterr().out)
    assert {"params", "stderr", "rmse", "accuracy_pct"} <= set(report)  # the fit's own keys are kept
    steps = report["with_effects"]["steps"]
    assert [s["label"] for s in steps][-1] == "+ resistance_temperature"
    assert steps[-1]["rmse"]["omega_rad_s"] < 0.8 * steps[0]["rmse"]["omega_rad_s"]
    assert plot.stat().st_size > 10_000
    # Not overwritten without --force.
    assert main(["fit", str(csv), "--with", "resistance_temperature", "--out", str(out)]) == 2
    capsys.readouterr()

    params = load_motor_params(out)
    assert [name for name, _ in params.effects] == ["resistance_temperature"]
    assert params.effect_params("resistance_temperature")["alpha_per_k"] == pytest.approx(0.0039, rel=0.1)

    assert (
        main(["compare", str(csv), "--params", str(out), "--json", "--plot-dir", str(tmp_path / "plots")])
        == 0
    )
    cmp = json.loads(capsys.readouterr().out)
    assert cmp["effects"] == ["resistance_temperature"]
    assert cmp["forward"]["forward speed"]["rmse"] < 1.1 * cmp["noise_floor"]["omega_rad_s"]
    assert len(list((tmp_path / "plots").glob("*.png"))) == 3

    # Diagnosis uses the effects: its model columns are the composed model's prediction.
    diag = diagnose(table, params, testbed_profile)
    context = {n: diag[n] for n in ("motor_temp_c",)}
    expected = predict_steady(params, diag["voltage_v"], context)
    np.testing.assert_allclose(diag["omega_model_rad_s"], expected.omega_rad_s)
    base_only = diagnose(table, params.replace(effects=()), testbed_profile)
    err_with = np.abs(diag["omega_rad_s"] - diag["omega_model_rad_s"]).mean()
    err_without = np.abs(base_only["omega_rad_s"] - base_only["omega_model_rad_s"]).mean()
    assert err_with < err_without


def test_compare_finds_where_the_model_fails(
    hidden_sessions: dict[str, TelemetryTable], paper_motor: MotorParams
) -> None:
    data = WorkbenchData.from_table(hidden_sessions["resistance_temperature"])
    result = compare(data, paper_motor)
    failing = {r.kind for r in result.failing}
    assert "motor_temp_c" in failing and "voltage_v" in failing
    hot = [r for r in result.regions if r.kind == "motor_temp_c"]
    assert max(hot, key=lambda r: r.ratio_omega).lower >= 50  # worst at the hot end
    assert "exceeds the noise floor" in result.report()


def test_workbench_on_real_flight_logs(bench_logs: Path) -> None:
    """PX4 flight with UAVCAN ESC telemetry: compare and explain run; SITL's constant current is refused."""
    from mav_motor_health.errors import FitError

    px4 = WorkbenchData.from_table(sources.read(bench_logs.parent / "px4" / "esc_status_log.ulg"))
    assert "esc_current_a" not in px4.context  # a copy of current_a is not a variable to explain with
    result = compare(px4)
    assert result.noise.method == "repeated" and result.forward[0].n > 400
    explained = explain(px4, seed=0)
    assert explained.variables and math.isfinite(explained.heldout_base)
    sitl = WorkbenchData.from_table(
        sources.read(bench_logs.parent / "ardupilot_sitl" / "hexa_motor1_half.tlog")
    )
    with pytest.raises(FitError, match=r"current_a takes only the value\(s\) 0.8"):
        compare(sitl)
