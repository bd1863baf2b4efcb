"""Logs written by the project's simulator (.tlog, .bin, .csv, with the simulation's truth) read back by
the replay readers, and replayed end to end: the same ESC samples from all three formats."""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.replay import replay_log
from mav_motor_health.sim.engine import run_scenario
from mav_motor_health.sim.scenario import scenario_from_dict
from mav_motor_health.sim.writers import write_record
from mav_motor_health.telemetry import sources

RPM_TO_RAD_S = 2 * math.pi / 60


@pytest.fixture(scope="module")
def record() -> Any:
    scenario = scenario_from_dict(
        {
            "scenario": {
                "name": "replay read-back",
                "mode": "flight",
                "duration_s": 8.0,
                "seed": 5,
                "dt_s": 0.01,
            },
            "fault": [{"kind": "F4.1", "motor": 5, "onset_s": 4.0, "severity": 0.8}],
            "sensors": {"rate_hz": [20.0, 40.0], "dropout": 0.02},
        }
    )
    return run_scenario(scenario)


@pytest.fixture(scope="module")
def written(record: Any, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("sim")
    return {ext: write_record(record, folder / f"flight{ext}")[0] for ext in (".tlog", ".bin", ".csv")}


def _truth(record: Any, motor: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    samples = [s for s in record.esc if s.motor == motor]
    return (
        np.array([s.time_s for s in samples]),
        np.array([s.rpm for s in samples], dtype=float) * RPM_TO_RAD_S,
        np.array([s.esc_current_ca for s in samples], dtype=float) / 100,
    )


@pytest.mark.parametrize("ext", [".bin", ".tlog"])
def test_binary_logs_give_the_simulated_esc_samples(record: Any, written: dict[str, Path], ext: str) -> None:
    table = sources.read(written[ext])
    assert table.motors() == [1, 2, 3, 4, 5, 6]
    assert table.meta["motors"] == [1, 2, 3, 4, 5, 6]
    for motor in range(1, 7):
        t, omega, esc_current = _truth(record, motor)
        rows = table.for_motor(motor)
        fresh = np.isfinite(rows["omega_rad_s"])
        if ext == ".bin":  # every ESC sample is a record, on the simulation's clock
            assert len(rows) == len(t)
            np.testing.assert_allclose(rows["time_s"] + table.meta["time_origin_boot_s"], t, atol=1e-6)
            np.testing.assert_allclose(rows["omega_rad_s"], omega)
            np.testing.assert_allclose(rows["esc_current_a"], esc_current, atol=1e-4)
        else:  # streamed at the telemetry rate: each fresh sample is one the simulation produced
            assert fresh.sum() > 0.5 * len(rows)
            assert set(np.round(rows["omega_rad_s"][fresh], 6)) <= set(np.round(omega, 6))
        moving = fresh & (rows["throttle"] >= 0.05)
        np.testing.assert_allclose(
            rows["current_a"][moving], rows["esc_current_a"][moving] / rows["throttle"][moving], rtol=1e-9
        )


def test_csv_bin_and_tlog_agree_on_the_speeds(written: dict[str, Path]) -> None:
    tables = {ext: sources.read(path) for ext, path in written.items()}
    for motor in (1, 5):
        levels = [np.nanmedian(t.for_motor(motor)["omega_rad_s"]) for t in tables.values()]
        assert max(levels) - min(levels) < 0.02 * max(levels)


def test_simulated_flight_replays_end_to_end(written: dict[str, Path], tmp_path: Path) -> None:
    result = replay_log(written[".bin"], tmp_path / "out", load_motor_params(), load_profile("flight"))
    assert {v.motor for v in result.verdicts} == {1, 2, 3, 4, 5, 6}
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "diagnosis.csv",
        "events.jsonl",
        "report.html",
    ]
    truth = json.loads(Path(str(written[".bin"]) + ".truth.json").read_text())
    assert truth["faults"][0]["motor"] == 5


def test_replay_warns_when_the_log_pairs_samples_and_commands_loosely(record: Any, tmp_path: Path) -> None:
    """The same flight as a .tlog streamed at 10 Hz (each ESC packet up to 100 ms older than its message)
    and at 200 Hz: only the first gets the warning, in the result and in the report; a profile without
    the balance rule (the testbed's) is not warned."""
    motor, flight = load_motor_params(), load_profile("flight")
    outputs = {}
    for rate_hz in (10.0, 200.0):
        scenario = dataclasses.replace(record.scenario, esc_stream_hz=rate_hz, log_hz=rate_hz)
        log, _ = write_record(run_scenario(scenario), tmp_path / f"flight_{rate_hz:g}hz.tlog")
        assert sources.read(log).meta["pairing_s"] == pytest.approx(1.0 / rate_hz, rel=0.05)
        out = tmp_path / f"out{rate_hz:g}"
        if rate_hz < 200:
            with pytest.warns(UserWarning, match="paired with motor commands"):
                outputs[rate_hz] = replay_log(log, out, motor, flight)
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # no warning at all
                outputs[rate_hz] = replay_log(log, out, motor, flight)
    loose = [w for w in outputs[10.0].warnings if "paired with motor commands" in w]
    assert len(loose) == 1 and "about 100 ms" in loose[0]
    assert "paired with motor commands" in (tmp_path / "out10" / "report.html").read_text()
    assert not any("paired with motor commands" in w for w in outputs[200.0].warnings)
    testbed = replay_log(tmp_path / "flight_10hz.tlog", tmp_path / "testbed", motor, load_profile("testbed"))
    assert not any("paired with motor commands" in w for w in testbed.warnings)


def test_a_loosely_paired_gusty_log_is_not_misread(tmp_path: Path) -> None:
    """A healthy gusty flight streamed at 10 Hz (.tlog): paired that loosely, the balance rule announced
    false faults (14 in this minute, docs/flight.md section 6). With the log's pairing weighed the current
    is set aside where the commands move fast and such samples are not judged: no false event. Without
    the samples' pairing (the same table, its ``pairing_s`` column and meta removed) the false events
    come back."""
    from mav_motor_health.diagnosis import diagnose
    from mav_motor_health.diagnosis.plausibility import SensorIssue
    from mav_motor_health.evaluation.score import score
    from mav_motor_health.sim.scenario import load_scenario
    from mav_motor_health.telemetry.table import TelemetryTable

    base = load_scenario("flight/healthy_calm")
    scenario = dataclasses.replace(
        base,
        seed=205,
        duration_s=60.0,
        flight=dataclasses.replace(base.flight, turbulence="gusty"),
        esc_stream_hz=10.0,
        log_hz=10.0,
    )
    log, _ = write_record(run_scenario(scenario), tmp_path / "gusty_10hz.tlog")
    table = sources.read(log)
    assert table.meta["pairing_s"] == pytest.approx(0.1, rel=0.05)
    motor, flight = load_motor_params(), load_profile("flight")
    weighed = diagnose(table, motor, flight)
    unpaired = {name: table[name] for name in table.names if name != "pairing_s"}
    unweighed = diagnose(TelemetryTable(unpaired, source=table.source), motor, flight)
    truth = scenario.truth()
    false_weighed = score({c: weighed[c] for c in weighed.names}, truth).false_events
    false_unweighed = score({c: unweighed[c] for c in unweighed.names}, truth).false_events
    assert false_weighed == 0 and false_unweighed >= 5
    assert np.any((weighed["sensor_flags"] & SensorIssue.CURRENT_UNPAIRED) != 0)
    assert np.all(np.isnan(unweighed["pairing_error_rad_s"]))
