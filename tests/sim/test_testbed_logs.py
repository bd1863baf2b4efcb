"""The committed testbed logs reproduce the paper (section IV.A): every fault diagnosed, at least as fast
as the paper's diagnosis times, with the testbed profile and the foundation's ``diagnose``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mav_motor_health.diagnosis.pipeline import diagnose
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.evaluation.score import PAPER, score
from mav_motor_health.telemetry.csv import read_csv

CASES_V = ("4.2", "5.8", "7.6", "9.2", "11.0")
FAULTS = ("F1.1", "F2.1", "F3.1", "F4.1", "F4.2")
#: The one case the paper's own model cannot reproduce: at 4.2 V a lighter propeller can lift the speed
#: by at most V/k_e − ω ≈ 20.4 rad/s, the speed band's width (test_motor.test_f31_speed_rise_is_capped...).
PHYSICS_LIMITED = {("F3.1", "4.2")}


def run(sitl_logs, paper_motor, profile, name):
    path = sitl_logs / f"testbed_{name}.csv"
    result = diagnose(read_csv(path), paper_motor, profile)
    cols = {k: np.asarray(result[k]) for k in ("time_s", "motor", "state", "announced", "steady")}
    truth = json.loads((sitl_logs / f"testbed_{name}.csv.truth.json").read_text())
    return cols, truth, score(cols, truth)


@pytest.mark.parametrize("volts", CASES_V)
@pytest.mark.parametrize("fault", FAULTS)
def test_fault_diagnosed_in_steady_state_as_fast_as_the_paper(
    sitl_logs, paper_motor, testbed_profile, fault, volts
):
    cols, truth, s = run(sitl_logs, paper_motor, testbed_profile, f"{fault}_{volts}V")
    assert truth["faults"][0]["fault"] == fault and truth["voltage_v"] == float(volts)
    if (fault, volts) in PHYSICS_LIMITED:
        assert s.fault_accuracy_pct is not None and s.fault_accuracy_pct > 20.0
        return
    assert s.detection_s is not None, f"{fault} at {volts} V never announced"
    assert s.detection_s <= PAPER["testbed_detection_s"][fault]
    assert MotorState(int(cols["announced"][-1])).label == fault
    assert s.fault_accuracy_pct is not None and s.fault_accuracy_pct > 95.0
    assert s.normal_accuracy_pct == pytest.approx(100.0)  # before the fault


@pytest.mark.parametrize("volts", CASES_V)
def test_healthy_testbed_runs_stay_normal(sitl_logs, paper_motor, testbed_profile, volts):
    _, _, s = run(sitl_logs, paper_motor, testbed_profile, f"healthy_{volts}V")
    assert s.false_events == 0
    assert s.normal_accuracy_pct is not None and s.normal_accuracy_pct > 99.0


def test_manifest_lists_every_committed_log(sitl_logs):
    text = (sitl_logs / "MANIFEST.md").read_text()
    logs = [p for p in sitl_logs.iterdir() if p.suffix in (".csv", ".tlog", ".bin")]
    assert len(logs) >= 30
    for p in logs:
        assert f"`{p.name}`" in text
        assert (sitl_logs / f"{p.name}.truth.json").exists()
    assert sum(p.stat().st_size for p in sitl_logs.iterdir()) < 15e6


def test_committed_logs_regenerate_identically(sitl_logs, tmp_path):
    """sitl_logs/ is reproducible: the same scenario and seed give the same bytes."""
    from mav_motor_health.sim.engine import run_scenario
    from mav_motor_health.sim.scenario import load_scenario
    from mav_motor_health.sim.writers import write_record

    name = "F4.2_5.8V"
    out, truth = write_record(
        run_scenario(load_scenario(f"testbed/{name}")), tmp_path / f"testbed_{name}.csv"
    )
    assert out.read_bytes() == (sitl_logs / f"testbed_{name}.csv").read_bytes()
    committed = json.loads((sitl_logs / f"testbed_{name}.csv.truth.json").read_text())
    assert json.loads(truth.read_text()) == committed
