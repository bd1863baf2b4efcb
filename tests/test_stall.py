"""The stalled motor's current, averaged since the stall began (diagnosis/stall.py), splits F2.1 from F4.2."""

from __future__ import annotations

import numpy as np
import pytest

from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.diagnosis import MotorState, diagnose
from mav_motor_health.diagnosis.stall import StallCarry, stall_mean
from mav_motor_health.evaluation.campaign import FlightCase, run_flights


def test_stall_mean_averages_each_stall_from_its_first_sample() -> None:
    current = np.array([9.0, 9.0, 2.0, 4.0, np.nan, 6.0, 9.0, 7.0, 8.0])
    stalled = np.array([0, 0, 1, 1, 1, 1, 0, 1, 1], dtype=bool)
    mean, carry = stall_mean(current, stalled)
    np.testing.assert_allclose(mean, [np.nan, np.nan, 2.0, 3.0, 3.0, 4.0, np.nan, 7.0, 7.5])
    assert carry == StallCarry(15.0, 2, True)  # the second stall runs on into the next call
    more, _ = stall_mean(np.array([9.0, 1.0]), np.array([True, False]), carry)
    np.testing.assert_allclose(more, [8.0, np.nan])


def test_stall_mean_split_anywhere_equals_whole() -> None:
    rng = np.random.default_rng(11)
    current = rng.normal(5.0, 2.0, 300)
    current[rng.random(300) < 0.05] = np.nan
    stalled = np.repeat(rng.random(30) < 0.5, 10)
    whole, _ = stall_mean(current, stalled)
    for cut in (1, 95, 150, 299):
        a, carry = stall_mean(current[:cut], stalled[:cut])
        b, _ = stall_mean(current[cut:], stalled[cut:], carry)
        np.testing.assert_allclose(np.concatenate([a, b]), whole, rtol=1e-12)  # sums in another order


@pytest.fixture(scope="module")
def stalls():
    """Stalls in moderate air on motor 3 at 12 s. Averaging the current over the balance rule's low-pass
    (which still holds the flight's 4–5 A) named the first samples of both F4.2 stalls F2.1, and announced
    F2.1 first in the second; averaged over the stall alone each stall is named from its first sample."""
    cases = [
        FlightCase("moderate", 5110, 20.0, fault="F4.2", motor=3, onset_s=12.0),
        FlightCase("moderate", 5111, 20.0, fault="F4.2", motor=3, onset_s=12.0),
        FlightCase("moderate", 5114, 20.0, fault="F2.1", motor=3, onset_s=12.0),
    ]
    return list(zip(cases, run_flights(cases, jobs=2)))


def test_each_stall_is_named_from_its_first_stopped_sample(stalls) -> None:
    motor, profile = load_motor_params("paper_x2212"), load_profile("flight")
    for case, flight in stalls:
        r = diagnose(flight.table, motor, profile)
        after = (r["motor"] == case.motor) & (r["time_s"] >= case.onset_s)
        stopped = after & np.isin(r["state"], [MotorState.F2_1, MotorState.F4_2])
        assert stopped.sum() > 20, case.name
        assert np.all(r["state"][stopped] == MotorState.from_label(case.fault)), case.name
        announced = r["announced"][after]
        assert announced[announced != MotorState.NORMAL][0] == MotorState.from_label(case.fault), case.name
