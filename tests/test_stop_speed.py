"""The stop speed never above what the lowest input given drives a healthy motor at (tree.py, "The lowest
input"): a heavy-lift motor driven to idle and back faster than its log pairs commands is not stalled,
a held rotor is."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mav_motor_health.config import dump_profile, load_profile
from mav_motor_health.diagnosis.pipeline import diagnose_motor
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.diagnosis.tree import classify_depth
from mav_motor_health.errors import ConfigError
from mav_motor_health.model.equations import steady_state
from mav_motor_health.model.params import MotorParams

#: a heavy-lift motor on a 0.8-m propeller (one of the randomised worlds): idle ~25 rad/s, hover ~180
HEAVY = MotorParams(R_ohm=0.176, k_e=0.1447, C_p=3.17e-7, B=1.12e-4, T_f=0.0308, k=3.0, J_kg_m2=0.0035)
BUS_V = 45.0
RATE_HZ = 50.0


def _flight(dip: tuple[float, float], dip_omega: float, idle_at: float | None = 2.0):
    """12 s at 0.6 of the bus in steady state, one sample at idle (0.086) at ``idle_at``, and over ``dip``
    the speed at ``dip_omega`` while the log pairs it with 0.73 of the bus (the idle commands between
    its samples never logged)."""
    t = np.arange(0.0, 12.0, 1.0 / RATE_HZ)
    duty = np.full(t.size, 0.6)
    if idle_at is not None:
        duty[np.argmin(np.abs(t - idle_at))] = 0.086
    inside = (t >= dip[0]) & (t < dip[1])
    duty[inside] = 0.73
    v = duty * BUS_V
    ss = steady_state(HEAVY, v)
    omega, current = (
        np.asarray(ss.omega_rad_s, dtype=float).copy(),
        np.asarray(ss.current_a, dtype=float).copy(),
    )
    omega[inside], current[inside] = dip_omega, 1.0
    return t, v, omega, current, duty


def _announced(profile, flight) -> set[int]:
    t, v, omega, current, duty = flight
    result, _ = diagnose_motor(HEAVY, profile, t, v, omega, current, np.full(t.size, BUS_V), command=duty)
    return {int(s) for s in np.unique(result["announced"])}


@pytest.fixture(scope="module")
def flight_profile():
    profile = load_profile("flight")
    return dataclasses.replace(
        profile, persistence=dataclasses.replace(profile.persistence, default_announce_s=0.05)
    )


def test_a_healthy_dip_towards_idle_is_no_stall_below_half_the_lowest_inputs_free_speed(
    flight_profile,
) -> None:
    dip = _flight((6.0, 6.3), dip_omega=50.0)  # 50 rad/s: above half of idle's free speed (13 rad/s)
    without = dataclasses.replace(flight_profile, stop_speed_lowest_fraction=0.0)
    with_cap = dataclasses.replace(flight_profile, stop_speed_lowest_fraction=0.5)
    assert int(MotorState.F2_1) in _announced(without, dip)  # the paper's 100 rad/s calls it stalled
    assert _announced(with_cap, dip) <= {int(MotorState.NORMAL), int(MotorState.F4_1), int(MotorState.F1_1)}
    assert int(MotorState.F2_1) not in _announced(with_cap, dip)


def test_a_held_rotor_is_still_a_stall(flight_profile) -> None:
    with_cap = dataclasses.replace(flight_profile, stop_speed_lowest_fraction=0.5)
    assert int(MotorState.F2_1) in _announced(with_cap, _flight((6.0, 6.5), dip_omega=2.0))


def test_before_any_low_input_the_cap_is_the_inputs_own(flight_profile) -> None:
    # never at idle: the lowest input is 0.6 of the bus, whose free speed halved (~93 rad/s) caps the stop
    with_cap = dataclasses.replace(flight_profile, stop_speed_lowest_fraction=0.5)
    assert int(MotorState.F2_1) in _announced(with_cap, _flight((6.0, 6.3), dip_omega=50.0, idle_at=None))
    assert int(MotorState.F2_1) not in _announced(with_cap, _flight((6.0, 6.3), dip_omega=97.0, idle_at=None))


def test_the_tree_caps_its_stop_speed_and_its_turning_floor() -> None:
    profile = dataclasses.replace(load_profile("flight"), stop_speed_lowest_fraction=0.5)
    common = dict(omega_model_rad_s=[220.0, 220.0, 40.0], current_a=[1.0] * 3, current_model_a=[20.0] * 3)
    common |= dict(voltage_v=[33.0] * 3, bands=(20.0, np.full(3, 5.0), np.full(3, 5.0)))
    omega = [60.0, 5.0, 5.0]
    plain, _ = classify_depth(profile, omega_rad_s=omega, **common)
    capped, _ = classify_depth(profile, omega_rad_s=omega, stop_cap_rad_s=[13.0] * 3, **common)
    assert plain.tolist()[:2] == [MotorState.F2_1, MotorState.F2_1]
    assert plain[2] != MotorState.F2_1  # 40 rad/s expected: below the paper's turning floor
    assert capped.tolist() == [MotorState.F4_1, MotorState.F2_1, MotorState.F2_1]


def test_the_fraction_is_checked_and_round_trips(tmp_path) -> None:
    with pytest.raises(ConfigError, match="stop_speed_lowest_fraction"):
        dataclasses.replace(load_profile("flight"), stop_speed_lowest_fraction=1.0)
    shipped = load_profile("flight_vehicle")
    assert shipped.stop_speed_lowest_fraction == 0.5
    path = tmp_path / "p.toml"
    path.write_text(dump_profile(shipped))
    assert load_profile(path) == shipped
    path.write_text(
        dump_profile(shipped).replace("stop_speed_lowest_fraction = 0.5", "stop_speed_lowest_fraction = 2")
    )
    with pytest.raises(ConfigError, match="stop_speed_lowest_fraction"):
        load_profile(path)


def test_the_lowest_input_is_carried_from_one_call_to_the_next(flight_profile) -> None:
    profile = dataclasses.replace(flight_profile, stop_speed_lowest_fraction=0.5)
    t, v, omega, current, duty = _flight((6.0, 6.3), dip_omega=50.0)
    bus = np.full(t.size, BUS_V)
    whole, _ = diagnose_motor(HEAVY, profile, t, v, omega, current, bus, command=duty)
    cut = int(np.searchsorted(t, 4.0))  # after the idle sample, before the dip
    first, carry = diagnose_motor(
        HEAVY, profile, t[:cut], v[:cut], omega[:cut], current[:cut], bus[:cut], command=duty[:cut]
    )
    second, _ = diagnose_motor(
        HEAVY, profile, t[cut:], v[cut:], omega[cut:], current[cut:], bus[cut:], carry, command=duty[cut:]
    )
    assert np.array_equal(np.concatenate([first["announced"], second["announced"]]), whole["announced"])
    assert int(MotorState.F2_1) not in set(second["announced"].tolist())
