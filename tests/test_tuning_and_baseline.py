"""Tuning a profile on labelled flights, the tune command, and the PX4-style baseline detector."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.cli import main
from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.diagnosis import diagnose
from mav_motor_health.diagnosis.tuning import fault_masks, tune_profile
from mav_motor_health.evaluation.campaign import FlightCase, run_flights
from mav_motor_health.evaluation.px4_baseline import OVER, UNDER, detect, fit_baseline, fit_current_line
from mav_motor_health.evaluation.score import score

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def calm_flights():
    cases = [
        FlightCase("calm", 71, 24.0),
        FlightCase("calm", 72, 24.0, fault="F2.1", motor=2, onset_s=12.0),
        FlightCase("calm", 73, 24.0, fault="F4.2", motor=5, onset_s=12.0),
        FlightCase("calm", 74, 24.0, fault="F3.1", motor=3, onset_s=12.0),
    ]
    return run_flights(cases, jobs=2)


def test_tuned_profile_has_no_false_event_on_its_flights_and_splits_the_stalls(calm_flights) -> None:
    params = load_motor_params()
    result = tune_profile(calm_flights, params, load_profile("flight_base"), name="t")
    profile = result.profile
    f21 = [c for _, c in result.report["stall_currents"]["F2.1"]]
    f42 = [c for _, c in result.report["stall_currents"]["F4.2"]]
    assert max(f21) < profile.stall_split_a < min(f42)
    assert 0 < profile.speed_band_rad_s < 200 and all(w > 0 for _, w in profile.current_band_a)
    assert result.report["rounds"][-1]["false_events"] == 0
    assert dict(profile.persistence.announce_s)["SLOW"] >= 1.0  # the base's minimum is kept
    # the slow look's share of the bands: its averages are quieter than the fast look's, so it is narrower
    assert 0.2 < profile.slow_band_fraction < 1.0
    assert result.report["slow_look"]["samples"] > 1000
    for flight in calm_flights:
        diagnosis = diagnose(flight.table, params, profile)
        s = score({k: diagnosis[k] for k in diagnosis.names}, flight.truth)
        assert s.false_events == 0
        if flight.truth["faults"]:
            assert s.detection_s is not None and s.fault_accuracy_pct > 90
            healthy, label = fault_masks(diagnosis, flight.truth)
            assert (~healthy).sum() == (label != "").sum() > 0


def test_tune_command_on_labelled_logs(tmp_path: Path, capsys) -> None:
    logs = [
        str(REPO / "sitl_logs" / name)
        for name in ("flight_healthy_calm.csv", "flight_F2.1_moderate.csv", "flight_F4.2_moderate.csv")
    ]
    out = tmp_path / "tuned.toml"
    assert main(["tune", *logs, "--out", str(out)]) == 0
    tuned = load_profile(out)
    assert tuned.name == "flight" and tuned.steady.kind == "balance" and tuned.activity_band
    text = out.read_text()
    assert "flight_healthy_calm.csv" in text  # the record of what it was tuned on
    report = json.loads(capsys.readouterr().out.split("\n", 1)[1])
    assert report["healthy_steady_samples"] > 100
    assert main(["tune", logs[0], "--truth", "a.json", "b.json"]) == 2
    assert "give one --truth per log" in capsys.readouterr().err


def test_px4_baseline_flags_under_and_over_current_after_its_hold() -> None:
    rng = np.random.default_rng(4)
    t = np.arange(0, 30, 0.05)
    throttle = 0.5 + 0.05 * np.sin(t)
    current = 20.0 * throttle - 2.0 + rng.normal(0, 0.2, t.size)
    assert fit_current_line(throttle, current) == pytest.approx((20.0, -2.0), abs=0.3)
    detector = fit_baseline([(t, throttle, current)])
    assert not detect(detector, t, throttle, current).any()  # its own healthy flight: no flag
    low = np.where(t > 15, current - 4.0, current)
    flags = detect(detector, t, throttle, low)
    onset = np.flatnonzero(flags == UNDER)[0]
    assert 15 + detector.hold_s <= t[onset] < 16.5 and not (flags == OVER).any()
    high = np.where(t > 15, current + 4.0, current)
    assert (detect(detector, t, throttle, high)[t > 17] == OVER).all()


def test_tail_hold_extrapolates_exponential_runs() -> None:
    from mav_motor_health.diagnosis.tuning import _tail_hold

    rng = np.random.default_rng(5)
    hours, per_hour, mean_s = 0.5, 2000.0, 0.05
    runs = list(rng.exponential(mean_s, int(hours * per_hour)))
    # runs longer than h come per_hour·exp(−h/mean) times an hour: once per 100 h at
    expected = mean_s * np.log(per_hour / 0.01)
    hold = _tail_hold(runs, hours, 0.01)
    assert abs(hold - expected) < 0.15 * expected
    assert hold > max(runs)  # it reaches beyond what the training flights saw
    assert _tail_hold(runs[:5], hours, 0.01) == 0.0  # too few runs: no extrapolation
