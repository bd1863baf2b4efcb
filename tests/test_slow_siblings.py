"""The slow look's bands bounded by how its siblings' slow averages run (``slow_siblings``;
diagnosis/rules/tree.py, "The slow look as its siblings run"), and the torque's slow look by the spread of
its siblings' slow torque averages (``torque_slow_siblings``; diagnosis/rules/equations.py, "The torque's
slow look as its siblings run"), and an open transistor read in the voltage balance's slow average against
how its siblings run (``voltage_slow_siblings``; diagnosis/rules/voltage.py)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from streaming import streams_as_replay


@pytest.fixture(scope="module")
def world4(tmp_path_factory):
    """Development world 4 (ESCs at 30 Hz reporting their input current) identified from its 150-s
    healthy flight, as ``fit`` does: its folder and vehicle."""
    from mav_motor_health.evaluation.worlds import identify_world

    folder = tmp_path_factory.mktemp("world4")
    _, _, vehicle = identify_world(4, folder)
    return folder, vehicle


def test_an_open_transistor_in_moderate_air_is_named_against_the_siblings_and_friction_as_before(
    world4,
) -> None:
    """Development world 4 (ESCs at 30 Hz reporting their input current), identified from its 150-s
    healthy flight, 30-s flights in moderate air: the slow look's own bands, extrapolated beyond the
    identification flight's activity, leave the open transistor NORMAL after onset; bounded by the
    siblings' slow averages it is named on about a third of them (36 %; not in the slow look's own wait
    after each input step, frequent in moderate air). Friction, named in the torque balance, is named
    as often either way, and no other motor is announced in any of the four diagnoses."""
    from mav_motor_health.config import load_profile

    # the deviations' slow look alone: without the voltage balance's, which names it too (the test below)
    shipped = dataclasses.replace(load_profile("flight_vehicle"), voltage_slow_siblings=0.0)
    with_siblings = dataclasses.replace(shipped, slow_siblings=1.0)
    own_alone = dataclasses.replace(shipped, slow_siblings=0.0)
    accuracy = {
        fault: _moderate_two_ways(world4, fault, (own_alone, with_siblings))[2] for fault in ("F4.1", "F1.1")
    }
    assert accuracy["F4.1"][0] < 0.1 and accuracy["F4.1"][1] > 0.3, accuracy
    assert accuracy["F1.1"][1] == accuracy["F1.1"][0] > 0.5, accuracy


def test_a_siblings_mean_square_is_a_reference_only_once_it_holds_a_time_constant_of_samples() -> None:
    """The live noise's counted mean (rules/bands.py, :func:`counted_mean`): a motor counted for a moment
    gives its siblings no reference, one counted for a time constant does (the mean of what it counted),
    a long gap fades it until a time constant's worth is counted again (one sample after the gap does
    not bridge it), and the same values come from the samples given in calls of any length."""
    from mav_motor_health.diagnosis.rules.bands import counted_mean

    tau, dt = 2.0, 0.05
    time_s = np.arange(0.0, 30.0, dt)[None, :]
    rng = np.random.default_rng(7)
    values = (3.0 + rng.normal(0.0, 0.5, time_s.shape)) ** 2
    counted = np.zeros(time_s.shape, dtype=bool)
    counted[0, (time_s[0] >= 1.0) & (time_s[0] < 1.5)] = True  # a moment: a quarter of tau
    counted[0, (time_s[0] >= 5.0) & (time_s[0] < 9.0)] = True  # two time constants
    counted[0, (time_s[0] >= 20.0) & (time_s[0] < 20.05)] = True  # one sample after a gap of 5 tau
    counted[0, (time_s[0] >= 25.0)] = True  # counted again from 25 s
    nan = np.full(1, np.nan)
    mean, *_ = counted_mean(time_s, values, counted, tau, nan, nan, nan, nan)
    t = time_s[0]
    assert np.isnan(mean[0, t < 5.0]).all()  # before, and after the moment: nothing
    assert np.isnan(mean[0, (t >= 5.0) & (t < 5.0 + tau * 0.95)]).all()
    ready = (t >= 5.0 + tau * 1.05) & (t < 9.0)
    assert np.isfinite(mean[0, ready]).all()
    assert abs(mean[0, t < 9.0][-1] - values[0, (t >= 5.0) & (t < 9.0)].mean()) < 1.5
    # held while not counted, then faded: by one time constant after the last counted sample at most
    # (the weight was below 1 there), and not back with one sample after the gap
    held = np.isfinite(mean[0]) & (t >= 9.0) & (t < 20.0)
    assert held[(t >= 9.0) & (t < 9.5)].all() and not held[t >= 9.0 + tau].any()
    assert np.isnan(mean[0, (t >= 20.0) & (t < 25.0 + 0.95 * tau)]).all()
    assert np.isfinite(mean[0, t >= 25.0 + 1.05 * tau]).all()
    # in calls of random lengths, each carrying the last one's state
    carry = [nan, nan, nan, nan]
    parts, at = [], 0
    while at < t.size:
        n = int(rng.integers(1, 40))
        part = slice(at, min(at + n, t.size))
        got, last_t, last_sum, last_weight = counted_mean(
            time_s[:, part], values[:, part], counted[:, part], tau, *carry
        )
        carry = [np.array(last_t), np.array(last_sum), np.array(last_weight), time_s[:, part][:, -1]]
        parts.append(got)
        at = part.stop
    np.testing.assert_allclose(np.concatenate(parts, axis=1), mean, rtol=1e-9, equal_nan=True)


def test_the_siblings_band_is_the_narrower_only_where_they_give_one_and_the_slow_averages_have_settled(
    paper_motor,
) -> None:
    """The slow look's share against its siblings (rules/tree.py, ``SlowLook._as_siblings_run``), one
    sample per row, the same departure of 10 rad/s below the model in each: where three or more siblings
    give a mean square (here 1 (rad/s)², a band of 4.5 rad/s) the departure's share is theirs; where none
    do (NaN) it stays the motor's own, not one of the quiet σ's band; and in the slow look's own wait
    after an input step, or beyond the motor's identified speeds, it stays its own too."""
    from mav_motor_health.config import load_profile
    from mav_motor_health.diagnosis.noise import BandNoise, EquationNoise
    from mav_motor_health.diagnosis.rules.base import SlowAverages
    from mav_motor_health.diagnosis.rules.tree import SlowLook

    profile = dataclasses.replace(load_profile("flight_vehicle"), slow_siblings=1.0)
    quiet = EquationNoise(0.5, 0.0)
    noise = [
        BandNoise(
            5.0, 0.3, omega_low_rad_s=400.0, omega_high_rad_s=600.0, slow_speed=quiet, slow_current=quiet
        )
    ] * 4
    rows = (4, 1)
    frame = _one_sample_per_row(paper_motor, profile, noise)
    frame.omega_model_rad_s = np.array([500.0, 500.0, 500.0, 700.0])[:, None]
    frame.omega_mean_rad_s = np.array([490.0, 490.0, 490.0, 690.0])[:, None]
    settle = 2.4
    frame.since_step_s = np.array([5.0, 5.0, 1.0, 5.0])[:, None]
    frame.siblings_slow_ms_speed = np.array([1.0, np.nan, 1.0, 1.0])[:, None]
    frame.siblings_slow_ms_current = np.full(rows, np.nan)
    deviation = np.full(rows, -10.0)
    slow = SlowAverages(deviation, np.zeros(rows), np.ones(rows, dtype=bool), settle)
    own = np.full(rows, -0.5)  # the departure's share of the motor's own band
    look = SlowLook(fraction=profile.slow_band_fraction)
    speed, current, narrower, siblings_speed = look._as_siblings_run(frame, slow, own.copy(), np.zeros(rows))
    theirs = -10.0 / (profile.noise_bands * profile.slow_siblings * 1.0)
    np.testing.assert_allclose(speed[:, 0], [theirs, -0.5, -0.5, -0.5])
    assert narrower[0][:, 0].tolist() == [True, False, False, False]
    assert not narrower[1].any() and (current == 0).all()
    # the share of the siblings' band itself (what the speed alone is judged in): only where they give one
    # and the motor is neither in the wait nor beyond its identified speeds, NaN elsewhere
    assert siblings_speed is not None
    np.testing.assert_allclose(siblings_speed[:, 0], [theirs, np.nan, np.nan, np.nan])


def test_friction_in_gusty_air_is_named_in_the_torques_slow_look_against_its_siblings_spread(world4) -> None:
    """Development world 4, 30-s flights in gusty air: friction on one motor raises its slow torque
    average against its siblings well beyond its siblings' spread, but the slow look's reach, the fast
    torque band's grown beyond the identification flight's air, leaves it NORMAL on (nearly) every sample
    after onset; bounded by the spread of the siblings' slow torque averages it is named on most of them
    (82 % when written). No other motor is announced, with or without, nor any motor of a healthy gusty
    flight with the bound; and the live agent's path gives replay's states."""
    from mav_motor_health.config import load_profile
    from mav_motor_health.diagnosis.states import MotorState
    from mav_motor_health.evaluation.worlds import diagnose_flight, world_flights

    folder, vehicle = world4
    shipped = load_profile("flight_vehicle")
    assert shipped.torque_slow_siblings == 1.0 and shipped.torque_slow_as_siblings
    own_alone = dataclasses.replace(shipped, torque_slow_siblings=0.0)
    fault, healthy = world_flights(4, duration_s=30.0, healthy_flights=1, levels=("gusty",), faults=("F1.1",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = [diagnose_flight(fault, folder, vehicle, p) for p in (own_alone, shipped)]
        calm = diagnose_flight(healthy, folder, vehicle, shipped)
    accuracy = []
    for r in results:
        assert (r["announced"][r["motor"] != fault.motor] == MotorState.NORMAL).all()
        after = (r["motor"] == fault.motor) & (r["time_s"] > fault.onset_s) & r["steady"].astype(bool)
        accuracy.append(float(np.mean(r["state"][after] == MotorState.F1_1)))
    assert accuracy[0] < 0.1 and accuracy[1] > 0.6, accuracy
    assert (results[1]["announced"][results[1]["motor"] == fault.motor] == MotorState.F1_1).any()
    assert (calm["announced"] == MotorState.NORMAL).all()
    # the live agent's way, in batches: the same states (the slow torque averages and their siblings'
    # spread carried between calls)
    streams_as_replay(fault, folder, vehicle, shipped, results[1])


def test_the_torques_slow_band_is_the_siblings_only_where_they_give_a_spread_and_the_motor_is_in_its_speeds(
    paper_motor,
) -> None:
    """The torque's slow look's share against its siblings (rules/equations.py,
    ``TorqueSlowLook._as_siblings_run``), one sample per row, each a slow torque average 0.05 N·m above
    the motor's slow offset, its slow σ 0.002 N·m quiet and growing by 0.01 N·m per volt of input
    activity, measured up to 0.5 V: where the siblings give a spread of 0.004 N·m in quiet input (a band
    of 4.5 × 0.004) the share is 0.05 / 0.018; a spread below the motor's measured σ counts as that σ, at
    the sample's activity within what was measured (0.3 V: σ 0.0036) and held at its limit beyond (2 V:
    σ at 0.5 V × 1.1, the profile's margin, not the extrapolation); where they give none (NaN), or the
    motor turns beyond its identified speeds, there is no share (NaN: its own band); and a profile without
    the bound gives none at all."""
    from mav_motor_health.config import load_profile
    from mav_motor_health.diagnosis.noise import EquationNoise
    from mav_motor_health.diagnosis.rules.equations import TorqueSlowLook

    profile = load_profile("flight_vehicle")
    frame = _six_conditions(paper_motor, profile, slow_torque=EquationNoise(0.002, 0.01, offset=0.01))
    rows = (6, 1)
    frame.torque_slow_spread_low_nm = np.array([0.004, 0.001, 0.001, 0.001, np.nan, 0.004])[:, None]
    averaged = np.full(rows, 0.06)
    n = profile.equation_bands * profile.slow_band_fraction * profile.torque_slow_siblings
    at_limit = float(np.hypot(0.002, 0.01 * 0.5 * (1.0 + profile.range_margin)))
    share = TorqueSlowLook(profile)._as_siblings_run(frame, averaged)
    assert share is not None
    sigmas = [0.004, 0.002, float(np.hypot(0.002, 0.003)), at_limit]
    np.testing.assert_allclose(share[:, 0], _beyond_two_of_six(0.05, n, sigmas))
    without = TorqueSlowLook(dataclasses.replace(profile, torque_slow_siblings=0.0))
    assert without._as_siblings_run(frame, averaged) is None


def test_an_open_transistor_is_read_in_the_voltage_balance_as_its_siblings_run(world4, tmp_path) -> None:
    """Development world 4, 30-s flights in moderate air: the deviations' slow look against its siblings
    names the open transistor on about a third of the samples after onset (36 %, the test above); reading
    the voltage balance's slow average against its siblings too (the shipped profile) names it on about
    two thirds (69 % when written) and announces it sooner (4.2 s after onset against 8.1 s); friction, which leaves the voltage balance as it was, is
    named as often either way; no other motor is announced, nor any motor of a healthy flight in moderate
    and in gusty air, on which the voltage balance names no sample at all; and the live agent's path gives
    replay's states (the slow voltage averages and their siblings' mean squares carried between calls)."""
    from mav_motor_health.config import load_profile
    from mav_motor_health.diagnosis.states import MotorState
    from mav_motor_health.evaluation.worlds import diagnose_flight, world_flights

    folder, vehicle = world4
    assert all("slow_voltage_v" in n for n in vehicle.noise.values())  # identification measured it
    shipped = load_profile("flight_vehicle")
    assert shipped.voltage_slow_siblings == 1.0 and shipped.voltage_slow_as_siblings
    without = dataclasses.replace(shipped, voltage_slow_siblings=0.0)
    accuracy, first = {}, {}
    for fault in ("F4.1", "F1.1"):
        flight, results, accuracy[fault] = _moderate_two_ways(world4, fault, (without, shipped))
        code = MotorState.from_label(fault)
        first[fault] = [
            float(
                np.min(r["time_s"][(r["motor"] == flight.motor) & (r["announced"] == code)], initial=np.inf)
            )
            for r in results
        ]
        if fault == "F4.1":
            streams_as_replay(flight, tmp_path, vehicle, shipped, results[1])
    assert accuracy["F4.1"][0] < 0.5 and accuracy["F4.1"][1] > accuracy["F4.1"][0] + 0.2, accuracy
    assert first["F4.1"][1] <= first["F4.1"][0] and np.isfinite(first["F4.1"][1]), first
    assert accuracy["F1.1"][1] == accuracy["F1.1"][0] > 0.5, accuracy
    healthy = world_flights(4, duration_s=30.0, healthy_flights=1, levels=("moderate", "gusty"), faults=())
    for flight in healthy:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            before, now = (diagnose_flight(flight, folder, vehicle, p) for p in (without, shipped))
        assert (now["announced"] == MotorState.NORMAL).all(), flight.name
        # not one healthy sample named by the voltage balance (the states as without it: 99.6 % NORMAL in
        # moderate air, 98.5 % in gusty air, where the deviations' slow look reads F4.1 on 14 samples)
        np.testing.assert_array_equal(now["state"], before["state"])


def test_the_voltage_balances_band_is_its_siblings_at_least_the_measured_sigma_within_the_speeds(
    paper_motor,
) -> None:
    """The voltage balance's slow look (rules/voltage.py, ``VoltageSlowLook.share``), one sample per row,
    each a slow voltage average against the siblings 1.0 V above the motor's slow offset (0.1 V), its slow
    σ 0.05 V quiet and growing by 0.2 V per volt of input activity, measured up to 0.5 V: where the
    siblings' mean squares give a root of 0.04 V in quiet input (a band of 4.5 × 0.05, the measured σ being
    the larger) the share is 0.9 / 0.225; a root of 0.1 V: 0.9 / 0.45; at an activity within what was
    measured (0.3 V: σ 0.078) and beyond (2 V: held at 0.5 V × 1.1, the profile's margin); where they give
    none (NaN), or the motor turns beyond its identified speeds, there is no share. On a frame the rule
    judges, a share above 1 names F4.1 with that depth, one below the offset names nothing, nor one whose
    slow speed average lies above its model or is not known, nor one whose slow current lies above its
    model (an open transistor slows its motor and draws less current; friction draws more)."""
    from mav_motor_health.config import load_profile
    from mav_motor_health.diagnosis.noise import EquationNoise
    from mav_motor_health.diagnosis.rules.base import SlowAverages
    from mav_motor_health.diagnosis.rules.voltage import VoltageSlowLook
    from mav_motor_health.diagnosis.states import Code

    profile = load_profile("flight_vehicle")
    quiet = EquationNoise(1.0, 0.0)
    frame = _six_conditions(
        paper_motor,
        profile,
        slow_speed=quiet,
        slow_current=quiet,
        slow_voltage=EquationNoise(0.05, 0.2, offset=0.1),
    )
    rows = (6, 1)
    rms = np.array([0.04, 0.1, 0.01, 0.01, np.nan, 0.1])[:, None]
    averaged = np.full(rows, 1.1)
    look = VoltageSlowLook(profile)
    n = profile.equation_bands * profile.slow_band_fraction * profile.voltage_slow_siblings
    at_limit = float(np.hypot(0.05, 0.2 * 0.5 * (1.0 + profile.range_margin)))
    sigmas = [0.05, 0.1, float(np.hypot(0.05, 0.06)), at_limit]
    np.testing.assert_allclose(look.share(frame, averaged, rms)[:, 0], _beyond_two_of_six(1.0, n, sigmas))
    # judged at a root of 0.1 V: the first two rows named (share 2.2); the same below the offset, with the
    # slow speed average above the model or not known (NaN), or the slow current above it, named nothing
    frame.omega_model_rad_s[:] = 500.0
    frame.omega_mean_rad_s[:] = 500.0
    frame.activity_v[:] = 0.0
    frame.state = np.full(rows, Code.NORMAL, dtype=np.int8)
    frame.depth = np.ones(rows)
    frame.steady = np.ones(rows, dtype=bool)
    frame.sensor_flags = np.zeros(rows, dtype=np.int16)
    frame.voltage_slow_v = np.array([1.1, 1.1, -0.9, 1.1, 1.1, 1.1])[:, None]
    frame.siblings_slow_ms_voltage = np.full(rows, 0.1**2)
    speed = np.array([-5.0, -5.0, -5.0, 5.0, np.nan, -5.0])[:, None]
    current = np.array([-1.0, 0.0, -1.0, -1.0, -1.0, 1.0])[:, None]  # the last draws more than its model
    frame.slow = SlowAverages(speed, current, np.ones(rows, dtype=bool), 2.4)
    look.judge(frame, [None] * 6)
    named = [Code.F4_1, Code.F4_1, Code.NORMAL, Code.NORMAL, Code.NORMAL, Code.NORMAL]
    assert frame.state[:, 0].tolist() == named
    np.testing.assert_allclose(frame.depth[:2, 0], 1.0 / (n * 0.1))


def _moderate_two_ways(world4, fault, profiles):
    """Development world 4's 30-s flight in moderate air with ``fault``, diagnosed with each of
    ``profiles``: the flight, the results, and each one's share of the faulty motor's judged samples after
    onset named ``fault``; no other motor is announced in any."""
    from mav_motor_health.diagnosis.states import MotorState
    from mav_motor_health.evaluation.worlds import diagnose_flight, world_flights

    folder, vehicle = world4
    (flight,) = world_flights(4, duration_s=30.0, healthy_flights=0, levels=("moderate",), faults=(fault,))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = [diagnose_flight(flight, folder, vehicle, p) for p in profiles]
    accuracy = []
    for r in results:
        assert (r["announced"][r["motor"] != flight.motor] == MotorState.NORMAL).all(), fault
        after = (r["motor"] == flight.motor) & (r["time_s"] > flight.onset_s) & r["steady"].astype(bool)
        accuracy.append(float(np.mean(r["state"][after] == MotorState.from_label(fault))))
    return flight, results, accuracy


def _six_conditions(paper_motor, profile, **slow_noise):
    """Six motors of one sample each (:func:`_one_sample_per_row`), their noise's identified speeds
    400-600 rad/s and activity up to 0.5 V with ``slow_noise``: at 500 rad/s in quiet input (the first
    two), at an activity of 0.3 V and 2 V, in quiet input, and at 700 rad/s (beyond the speeds)."""
    from mav_motor_health.diagnosis.noise import BandNoise

    noise = [
        BandNoise(5.0, 0.3, omega_low_rad_s=400.0, omega_high_rad_s=600.0, activity_high_v=0.5, **slow_noise)
    ] * 6
    frame = _one_sample_per_row(paper_motor, profile, noise)
    frame.omega_model_rad_s = np.array([500.0, 500.0, 500.0, 500.0, 500.0, 700.0])[:, None]
    frame.omega_mean_rad_s = frame.omega_model_rad_s.copy()
    frame.activity_v = np.array([0.0, 0.0, 0.3, 2.0, 0.0, 0.0])[:, None]
    return frame


def _beyond_two_of_six(departure, n, sigmas):
    """The shares :func:`_six_conditions`' rows should give: ``departure`` over ``n`` times each of the
    first four rows' ``sigmas``, none on the last two (no siblings' value; beyond the speeds)."""
    return [departure / (n * sigma) for sigma in sigmas] + [np.nan, np.nan]


def _one_sample_per_row(paper_motor, profile, noise):
    """A frame of one sample per row (one row per motor noise given): 500 rad/s, 5 A at 10 V, at 0 s."""
    from mav_motor_health.diagnosis.rules.base import Frame

    rows = (len(noise), 1)
    return Frame(
        params=paper_motor,
        profile=profile,
        time_s=np.zeros(rows),
        voltage_v=np.full(rows, 10.0),
        omega_rad_s=np.full(rows, 500.0),
        current_a=np.full(rows, 5.0),
        counts=[1] * len(noise),
        noise=noise,
    )
