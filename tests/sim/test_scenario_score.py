"""Scenario files are validated with errors naming file and key; the scorer counts what it says."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.cli import main
from mav_motor_health.config import PARAMS_DIR
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.errors import ConfigError
from mav_motor_health.evaluation.score import format_score, read_diagnosis, score
from mav_motor_health.sim.scenario import load_scenario


def test_every_bundled_scenario_loads():
    files = sorted((PARAMS_DIR / "scenarios").rglob("*.toml"))
    assert len(files) >= 30
    for f in files:
        sc = load_scenario(f)
        assert sc.duration_s > 0


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('[scenario]\nmode = "boat"\n', "scenario.mode"),
        ("[scenario]\nduration_s = -1\n", "scenario.duration_s"),
        ('[[fault]]\nkind = "F9.9"\nonset_s = 1\n', "fault[0]"),
        ('[[fault]]\nkind = "F3.1"\nonset_s = 1\nseverity = 3\n', "fault[0]"),  # more than the blade
        ('[[fault]]\nkind = "F1.1"\nonset_s = 1\nseverity = 11\n', "fault[0]"),  # beyond its stronger forms
        ('[flight]\nturbulence = "stormy"\n', "flight.turbulence"),
        ("[sensors]\nrate_hz = [50, 10]\n", "sensors.rate_hz"),
        ("[scenario]\nspeed = 3\n", "scenario"),
    ],
)
def test_bad_scenarios_name_file_and_key(tmp_path: Path, text, key):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    assert str(path) in str(err.value) and key in str(err.value)


def synthetic(onset=10.0, detect_at=10.5, fault=MotorState.F4_1):
    t = np.arange(0.0, 20.0, 0.025)
    state = np.where(t >= onset + 0.2, fault, MotorState.NORMAL)
    state[100] = MotorState.F1_1  # one wrong sample while healthy
    announced = np.where(t >= detect_at, fault, MotorState.NORMAL)
    announced[200:205] = MotorState.F3_1  # one false event
    return {
        "time_s": t,
        "motor": np.ones(t.size, dtype=int),
        "state": state,
        "announced": announced,
        "steady": np.ones(t.size, dtype=bool),
    }


def test_score_counts_accuracy_detection_and_false_events():
    truth = {
        "mode": "testbed",
        "duration_s": 20.0,
        "faults": [{"fault": "F4.1", "motor": 1, "onset_s": 10.0}],
    }
    s = score(synthetic(), truth)
    assert s.detection_s == pytest.approx(0.5, abs=0.026)
    assert s.fault_accuracy_pct == pytest.approx(100 * (1 - 8 / 400), abs=0.3)  # 0.2 s of 10 s missed
    assert s.normal_accuracy_pct == pytest.approx(100 * (1 - 1 / 400), abs=0.01)
    assert s.false_events == 1 and s.false_events_per_hour == pytest.approx(180.0)
    assert s.false_events_by_state == {"F3.1": 1}
    text = format_score(s, truth)
    assert "paper: 0.43 s" in text


def test_score_command_on_a_simulated_testbed_log(tmp_path: Path, capsys):
    out = tmp_path / "run.csv"
    assert main(["simulate", "testbed/F4.1_7.6V", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(out), "--profile", "testbed"]) == 0
    diag = tmp_path / "diag.csv"
    diag.write_text(capsys.readouterr().out)
    data = read_diagnosis(diag)
    assert data["state"].dtype.kind == "i"
    assert main(["score", str(diag), str(out) + ".truth.json", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["fault"] == "F4.1" and result["detection_s"] < 0.43
    assert main(["simulate", "testbed/F4.1_7.6V", "--out", str(out)]) == 2  # never overwrites
