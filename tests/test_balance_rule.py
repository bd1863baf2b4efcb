"""The balance rule (model/balance.py, steady kind "balance"): the model's equations checked at every
sample, low-passed, turned into the steady-state deviations the tree judges."""

from __future__ import annotations

import numpy as np
import pytest

from mav_motor_health.config import dump_profile, load_motor_params, load_profile
from mav_motor_health.diagnosis.pipeline import StreamingDiagnoser, diagnose
from mav_motor_health.diagnosis.plausibility import SensorIssue
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.diagnosis.steady import warm_mask
from mav_motor_health.diagnosis.tuning import _activity_band
from mav_motor_health.evaluation.campaign import FlightCase, run_flights
from mav_motor_health.model.balance import (
    BalanceCarry,
    balance_deviations,
    balance_deviations_rows,
    censored_mean,
    input_activity,
    linearised_slopes,
)
from mav_motor_health.model.equations import steady_state
from mav_motor_health.replay import events_from_diagnosis
from mav_motor_health.sim.faults import FaultEffects
from mav_motor_health.sim.motor import MotorBank, MotorDynamics
from mav_motor_health.telemetry.table import TelemetryTable


@pytest.fixture(scope="module")
def motor():
    return load_motor_params("paper_x2212")


@pytest.fixture(scope="module")
def flights():
    """One healthy calm flight and the three faults whose signature is a deviation, motor 2 at 12 s."""
    cases = [
        FlightCase("calm", 5100, 24.0),
        FlightCase("calm", 5101, 24.0, fault="F1.1", motor=2, onset_s=12.0),
        FlightCase("calm", 5102, 24.0, fault="F3.1", motor=2, onset_s=12.0),
        FlightCase("calm", 5103, 24.0, fault="F4.1", motor=2, onset_s=12.0),
    ]
    return dict(zip(("healthy", "F1.1", "F3.1", "F4.1"), run_flights(cases, jobs=2)))


def test_steady_state_of_the_model_has_no_deviation(motor) -> None:
    t = np.arange(200) * 0.02
    v = np.repeat([5.0, 8.0, 11.0, 6.5], 50)
    ss = steady_state(motor, v)
    res, _ = balance_deviations(motor, t, v, ss.omega_rad_s, ss.current_a, 0.15, 0.5)
    settled = np.tile(np.arange(50) >= 45, 4)  # the low-passes mix two points just after each step
    assert np.max(np.abs(res.delta_omega_rad_s[settled])) < 0.5
    assert np.max(np.abs(res.delta_current_a[settled])) < 0.02


def test_speed_deviation_does_not_use_the_current(motor) -> None:
    rng = np.random.default_rng(3)
    t = np.arange(300) * 0.03
    v = 7.0 + rng.normal(0, 0.5, t.size)
    w = steady_state(motor, v).omega_rad_s + rng.normal(0, 10, t.size)
    a, _ = balance_deviations(motor, t, v, w, rng.uniform(0, 10, t.size), 0.15, 0.5)
    b, _ = balance_deviations(motor, t, v, w, np.full(t.size, np.nan), 0.15, 0.5)
    np.testing.assert_allclose(a.delta_omega_rad_s, b.delta_omega_rad_s)
    assert np.all(np.isnan(b.delta_current_a)) and np.all(np.isfinite(a.delta_current_a))


def test_esc_input_current_is_weighted_by_the_duty_not_divided_by_it(motor) -> None:
    """A healthy motor whose command zigzags between 10-ms steps (as in gusty air), the ESC sensing its
    input current d·i through a 20-ms filter as a shunt does. The motor current derived per sample
    (reading / the sample's duty) is biased high: duty and current rise and fall together. Weighting the
    electrical balance by the duty instead recovers what the true motor current gives."""
    rng = np.random.default_rng(21)
    dt, bus, n = 0.005, 11.1, 4000
    phase = np.sign(np.sin(np.arange(n) * np.pi / 2 + 0.3))
    duty = np.clip(0.55 + 0.08 * phase + rng.normal(0.0, 0.03, n), 0.2, 1.0)
    w0 = float(steady_state(motor, 0.55 * bus).omega_rad_s)
    bank = MotorBank(MotorDynamics(motor, inertia_kg_m2=motor.J_kg_m2), 1, rng, omega0_rad_s=w0)
    w, i, sensed = np.zeros(n), np.zeros(n), np.zeros(n)
    blend = 1.0 - np.exp(-dt / 0.02)
    for k in range(n):
        bank.step(np.array([duty[k] * bus]), dt, FaultEffects.healthy(1))
        w[k], i[k] = bank.omega_rad_s[0], bank.current_a[0]
        product = duty[k] * i[k]
        sensed[k] = product if k == 0 else sensed[k - 1] + blend * (product - sensed[k - 1])
    t, v = np.arange(n) * dt, duty * bus
    settled = t > 5.0

    def mean_delta_i(current, **esc) -> float:
        res, _ = balance_deviations(motor, t, v, w, current, 0.3, 0.5, **esc)
        return float(np.mean(res.delta_current_a[settled]))

    truth = mean_delta_i(i)
    assert abs(truth) < 0.05
    assert mean_delta_i(sensed / duty) > truth + 0.5  # divided: biased
    assert mean_delta_i(sensed / duty, input_current_a=sensed, duty=duty) == pytest.approx(truth, abs=0.05)


def test_a_report_averaged_over_a_command_dip_is_not_divided_by_the_dip(motor) -> None:
    """An ESC that reports its input current averaged since its last report, paired with a command that
    dipped to near idle at the sample (gusty air, an ESC at 10-34 Hz behind 50-Hz commands): the report
    holds the current of the duty before the dip, the sample the dip's small duty. Divided by it, one such
    sample reads several times the motor current and the low-passed torque jumps by far more than the
    healthy noise, on this motor and on the siblings it is a reference for (docs/flight.md, "The torque
    through the duty as a ratio of means"); read as the electrical balance reads it, it moves little."""
    t = np.arange(1500) * 0.02
    bus = 11.1
    duty = np.full(t.size, 0.6)
    dips = np.zeros(t.size, dtype=bool)
    dips[500::97] = True
    duty[dips] = 0.12
    ss = steady_state(motor, 0.6 * bus)
    w = np.full(t.size, float(ss.omega_rad_s))
    i = np.full(t.size, float(ss.current_a))
    sensed = 0.6 * i  # the report: its window's mean of d·i, at the duty before the dip
    v = duty * bus

    def torque(**esc) -> np.ndarray:
        res, _ = balance_deviations(motor, t, v, w, sensed / duty, 0.15, 0.5, **esc)
        return res.torque_residual_nm[t > 5.0]

    divided = torque()
    weighted = torque(input_current_a=sensed, duty=duty, torque_through_duty=True)
    # a motor current (the ESC reads its motor's own, d·i given as the input): read as it is, as before
    np.testing.assert_array_equal(torque(input_current_a=sensed, duty=duty), divided)
    load = motor.k_t * float(ss.current_a)  # the torque the motor makes
    assert np.max(divided) > 0.4 * load  # each dip: nearly half the motor's torque, for a while
    assert np.max(np.abs(weighted)) < 0.15 * load  # the dip's share of mean(d): a tenth


def test_the_load_through_the_duty_holds_where_the_current_is_missing(motor) -> None:
    """Read through the duty, the torque averages the load over the samples whose current it averages: a
    speed that moves while the current reading is missing (a dropped report) moves it no more than it
    moves the motor current's k_t·(i − load), which holds there. At a constant duty the two readings are
    the same numbers (mean(s)/d = mean(s/d))."""
    rng = np.random.default_rng(7)
    t = np.arange(600) * 0.02
    bus, duty = 11.1, np.full(600, 0.6)
    ss = steady_state(motor, 0.6 * bus)
    w = float(ss.omega_rad_s) + rng.normal(0.0, 5.0, t.size)
    i = float(ss.current_a) + rng.normal(0.0, 0.2, t.size)
    missing = (t > 4.0) & (t < 5.0)
    w[missing] += 150.0  # the speed moves while no current is read
    i[missing] = np.nan
    sensed = duty * i

    def torque(**esc) -> np.ndarray:
        res, _ = balance_deviations(motor, t, duty * bus, w, i, 0.15, 0.5, **esc)
        return res.torque_residual_nm

    through = torque(input_current_a=sensed, duty=duty, torque_through_duty=True)
    motor_current = torque()
    known = np.isfinite(i)
    assert np.array_equal(np.isfinite(through), known)
    np.testing.assert_allclose(through[known], motor_current[known], rtol=0, atol=1e-9)


def test_activity_sees_zigzags_not_steps_or_ramps() -> None:
    t = np.arange(400) * 0.02
    zigzag = 7.0 + 0.5 * (-1.0) ** np.arange(400)  # up, down, up...: 1 V between samples
    step = np.where(t < 4.0, 6.0, 9.0)
    ramp = 5.0 + 0.5 * t
    a_zig, _ = input_activity(t, zigzag, 0.5)
    a_step, _ = input_activity(t, step, 0.5)
    a_ramp, _ = input_activity(t, ramp, 0.5)
    assert a_zig[-1] == pytest.approx(1.0, rel=0.02)
    assert np.max(a_step) == 0.0 and np.max(a_ramp) == 0.0


def test_warm_mask_restarts_at_gaps_and_steps() -> None:
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0, 2.1])
    v = np.array([5, 5, 5, 5, 5, 5, 5, 5, 8, 8, 8, 8], dtype=float)
    warm, _ = warm_mask(t, v, 0.15, 0.5, 1.0)
    # start at 0 → warm from 0.2; gap before 1.5 → warm from 1.7; step at 1.8 → warm from 2.0
    assert warm.tolist() == [False, False, True, True, True, False, False, True, False, False, True, True]
    # split anywhere: the same
    w1, c1 = warm_mask(t[:7], v[:7], 0.15, 0.5, 1.0)
    w2, _ = warm_mask(t[7:], v[7:], 0.15, 0.5, 1.0, c1)
    assert np.concatenate([w1, w2]).tolist() == warm.tolist()


def _motor2_after(result, t0: float) -> np.ndarray:
    sel = (result["motor"] == 2) & (result["time_s"] > t0) & result["steady"]
    return sel


def test_faults_show_their_signature_as_deviations(motor, flights) -> None:
    profile = load_profile("flight")
    dev = {}
    for name, flight in flights.items():
        r = diagnose(flight.table, motor, profile)
        sel = _motor2_after(r, 14.0)
        dev[name] = (
            np.median((r["omega_judged_rad_s"] - r["omega_model_rad_s"])[sel]),
            np.median((r["current_judged_a"] - r["current_model_a"])[sel]),
        )
    w0, i0 = dev["healthy"]
    assert abs(w0) < 5 and abs(i0) < 0.2
    # F1.1: torque the model lacks: slower, more current; F3.1: the reverse; F4.1: voltage lost, both lower
    assert dev["F1.1"][0] < -20 and dev["F1.1"][1] > 1.0
    assert dev["F3.1"][0] > 50 and dev["F3.1"][1] < -1.0
    assert dev["F4.1"][0] < -50 and dev["F4.1"][1] < -0.5


def test_each_fault_departs_in_its_own_equation(motor, flights) -> None:
    """The result carries the two balances apart: friction and a lighter propeller are torque the model
    lacks (or has too much of) with the voltage accounted for, an open transistor is voltage lost with the
    torque accounted for; and the current deviation is their sum in amperes, (k_e·r_T − G·r_V)/D."""
    profile = load_profile("flight")
    torque, voltage, announced = {}, {}, {}
    for name, flight in flights.items():
        r = diagnose(flight.table, motor, profile)
        sel = _motor2_after(r, 14.0)
        torque[name] = np.median(r["torque_residual_nm"][sel])
        voltage[name] = np.median(r["voltage_residual_v"][sel])
        # the event that names the fault says which equation it departs in
        announced[name] = [e["evidence"] for e in events_from_diagnosis(r) if e["state"] == name]
        if name == "healthy":
            g, d = linearised_slopes(motor, r["omega_model_rad_s"][sel])
            parts = (motor.k_e * r["torque_residual_nm"][sel] - g * r["voltage_residual_v"][sel]) / d
            di = (r["current_judged_a"] - r["current_model_a"])[sel]
            # the same deviation up to how the two means weigh a jittering input (within 0.05 A here)
            assert np.median(np.abs(parts - di)) < 0.05
    # a healthy motor: both near zero (the paper motor's k_t is 0.00975 N·m/A: 0.1 A is 0.001 N·m)
    assert abs(torque["healthy"]) < 1e-3 and abs(voltage["healthy"]) < 0.05
    # friction: torque the model lacks; a lighter propeller: torque it has too much of; voltage as healthy
    assert torque["F1.1"] > 10 * 1e-3 and abs(voltage["F1.1"]) < 0.05
    assert torque["F3.1"] < -10 * 1e-3 and abs(voltage["F3.1"]) < 0.05
    # an open transistor: voltage lost (r_V = V − R·i − k_e·ω > 0), torque as healthy
    assert voltage["F4.1"] > 0.2 and abs(torque["F4.1"]) < 2e-3
    assert announced["F1.1"] and announced["F1.1"][0]["torque_residual_nm"] > 5e-3
    assert announced["F3.1"] and announced["F3.1"][0]["torque_residual_nm"] < -5e-3
    assert announced["F4.1"] and announced["F4.1"][0]["voltage_residual_v"] > 0.1


def test_flight_profile_names_each_fault_and_stays_quiet_when_healthy(motor, flights) -> None:
    profile = load_profile("flight")
    for name, flight in flights.items():
        r = diagnose(flight.table, motor, profile)
        if name == "healthy":
            assert np.all(r["announced"] == MotorState.NORMAL)
            continue
        sel = _motor2_after(r, 14.0)
        assert np.mean(r["state"][sel] == MotorState.from_label(name)) > 0.95, name
        others = (r["motor"] != 2) & r["steady"]
        assert np.all(r["announced"][others] == MotorState.NORMAL), name


def test_streaming_equals_batch_with_the_balance_rule(motor, flights) -> None:
    profile = load_profile("flight")
    table = flights["F4.1"].table
    batch = diagnose(table, motor, profile)
    live = StreamingDiagnoser(motor, profile)
    for motor_number in (2, 5):
        part = table.for_motor(motor_number)
        sel = batch["motor"] == motor_number
        # the ESC currents' sum against the battery is checked across motors (the agent does it as it goes)
        sum_flags = batch["sensor_flags"][sel] & SensorIssue.CURRENT_SUM
        rows = [
            live.update(
                motor_number,
                float(part["time_s"][k]),
                float(part["voltage_v"][k]),
                float(part["omega_rad_s"][k]),
                float(part["current_a"][k]),
                float(part["bus_voltage_v"][k]),
                command=float(part["throttle"][k]),
                sensor_current_a=float(part["esc_current_a"][k]),
                extra_flags=int(sum_flags[k]),
            )
            for k in range(len(part))
        ]
        assert [r["state"] for r in rows] == batch["state"][sel].tolist()
        assert [r["announced"] for r in rows] == batch["announced"][sel].tolist()


def test_profile_round_trips_through_toml(tmp_path) -> None:
    profile = load_profile("flight")
    path = tmp_path / "p.toml"
    path.write_text(dump_profile(profile))
    assert load_profile(path) == profile
    assert profile.steady.kind == "balance" and len(profile.activity_band) > 1


def test_activity_band_covers_every_bin() -> None:
    rng = np.random.default_rng(11)
    activity = rng.uniform(0.05, 3.0, 20000)
    res_w = np.abs(rng.normal(0.0, 5.0 + 20.0 * activity))
    res_i = rng.normal(0.0, 0.1 + 0.5 * activity)  # signed
    base_w, base_i, rows = _activity_band(res_w, res_i, activity, 0.99, 1.5, 12)
    xs = [r[0] for r in rows]
    assert all(b > a for a, b in zip(xs, xs[1:]))
    assert rows[-1][1] > 100.0 and rows[-1][2] > 2.0 and rows[-1][3] > 2.0  # it widens where the noise grows
    edges = np.quantile(activity, np.linspace(0, 1, 13))
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (activity >= lo) & (activity <= hi)
        at = float(np.quantile(activity[sel], 0.9))
        assert base_w + np.interp(at, xs, [r[1] for r in rows]) >= 0.999 * 1.5 * np.quantile(res_w[sel], 0.99)
        # each side of the current band covers its own tail, within the calmest bin's own asymmetry
        slack = 0.1 * base_i
        above = base_i + np.interp(at, xs, [r[2] for r in rows])
        below = base_i + np.interp(at, xs, [r[3] for r in rows])
        assert above >= 1.5 * np.quantile(res_i[sel], 0.995) - slack
        assert below >= 1.5 * np.quantile(-res_i[sel], 0.995) - slack


def test_activity_band_reads_each_side_of_a_skewed_current_off_its_own_tail() -> None:
    """In gusty air the healthy current dips below the model further than it rises above it: the side
    below must widen more with the activity, the side above less, than one width for both would."""
    rng = np.random.default_rng(12)
    activity = rng.uniform(0.05, 3.0, 40000)
    res_w = np.abs(rng.normal(0.0, 10.0, activity.size))
    scale = 0.1 + 0.3 * activity
    # a skewed residual: mean zero, a long tail below (exponential), a short one above
    res_i = scale * (1.0 - rng.exponential(1.0, activity.size))
    _, base_i, rows = _activity_band(res_w, res_i, activity, 0.99, 1.5, 12)
    top = rows[-1]
    assert top[3] > 1.5 * top[2]  # below the model it widens more than above
    gusty = activity > 2.5
    symmetric = 1.5 * np.quantile(np.abs(res_i[gusty]), 0.99)
    assert base_i + top[2] < symmetric < base_i + top[3]


def test_censored_mean_recovers_the_mean_of_a_current_read_unsigned() -> None:
    rng = np.random.default_rng(11)
    for mu, sigma in ((6.0, 1.0), (2.0, 3.0), (0.5, 2.0), (-0.5, 1.0)):
        x = rng.normal(mu, sigma, 200_000)
        readings = np.maximum(x, 0.0)  # the ESC reports a braking motor's current as 0
        share = np.mean(readings == 0.0)
        naive = readings.mean()
        corrected = float(censored_mean(naive, share))
        assert corrected == pytest.approx(mu, abs=0.03), (mu, sigma)
        if share > 0.05:
            assert abs(naive - mu) > 5 * abs(corrected - mu)  # the correction is what brings it back
    # no zeros: the readings' mean as it is; NaN stays NaN
    assert float(censored_mean(4.2, 0.0)) == 4.2
    assert np.isnan(censored_mean(np.nan, np.nan))


@pytest.fixture(scope="module")
def gusty_flight():
    (flight,) = run_flights([FlightCase("gusty", 5110, 40.0)], jobs=1)
    return flight


def test_current_deviation_stays_centred_in_gusty_air(motor, gusty_flight) -> None:
    """In gusty air the commands zigzag between steps, motors brake now and then and their ESCs read 0
    (unsigned); the balance rule, fed the ESC's input current and the command as the pipeline feeds it,
    keeps every healthy motor's current deviation centred (divided by the sample's duty instead, the
    reading puts it amperes high: test_esc_input_current_is_weighted_by_the_duty_not_divided_by_it)."""
    table = gusty_flight.table
    shares, medians = [], []
    for m in table.motors():
        sel = table["motor"] == m
        t, v = table["time_s"][sel], table["voltage_v"][sel]
        w, i = table["omega_rad_s"][sel], table["current_a"][sel]
        esc, duty = table["esc_current_a"][sel], table["throttle"][sel]
        res, _ = balance_deviations(
            motor, t, v, w, i, 0.15, 0.5, activity_ref_v=0.4, tau_max_s=1.5, input_current_a=esc, duty=duty
        )
        judged = (duty >= 0.2) & (t > 5.0)
        shares.append(np.mean(esc[judged] == 0.0))
        medians.append(np.median(res.delta_current_a[judged]))
    assert np.mean(shares) > 0.01  # the flight does have braking motors' zero readings ...
    assert np.max(np.abs(medians)) < 0.25  # ... and the deviation stays centred


def test_activity_counts_sparser_telemetry_as_more_active(motor) -> None:
    """The same zigzag sampled at 6.25 Hz and at 25 Hz: the balance's activity differs by √4 = 2 (an
    average of a quarter as many samples is twice as noisy)."""
    activities = []
    for rate_hz in (6.25, 25.0):
        t = np.arange(0.0, 20.0, 1.0 / rate_hz)
        v = 7.0 + 0.5 * (-1.0) ** np.arange(t.size)
        w = steady_state(motor, np.full(t.size, 7.0)).omega_rad_s
        res, _ = balance_deviations(motor, t, v, w, np.full(t.size, 5.0), 0.15, 0.5)
        activities.append(res.activity_v[-1])
        assert res.zigzag_v[-1] == pytest.approx(1.0, rel=0.02)  # the jumps as measured: what a step is
    assert activities[0] / activities[1] == pytest.approx(2.0, rel=0.02)
    assert activities[1] == pytest.approx(1.0, rel=0.02)  # 25 Hz is the reference rate: as measured
    # a dropout of a second is a gap, not a slower ESC: the activity after it is as before
    t = np.concatenate([np.arange(0.0, 10.0, 0.04), np.arange(11.0, 14.0, 0.04)])
    v = 7.0 + 0.5 * (-1.0) ** np.arange(t.size)
    w = steady_state(motor, np.full(t.size, 7.0)).omega_rad_s
    res, _ = balance_deviations(motor, t, v, w, np.full(t.size, 5.0), 0.15, 0.5)
    assert res.activity_v[-1] == pytest.approx(1.0, rel=0.02)


def test_a_command_that_dips_between_two_samples_is_as_active_as_one_that_zigzags(motor) -> None:
    """Both samples' inputs alike, the command having dipped by e in between (a 10 Hz ESC report in 50 Hz
    commands, telemetry/assemble.py ``input_excursion_v``): the activity is that of a zigzag of e per
    sample, not the nothing the two inputs show."""
    t = np.arange(0.0, 20.0, 0.04)
    w = steady_state(motor, np.full(t.size, 7.0)).omega_rad_s
    i = np.full(t.size, 5.0)
    zigzag, _ = balance_deviations(motor, t, 7.0 + 0.5 * (-1.0) ** np.arange(t.size), w, i, 0.15, 0.5)
    flat, _ = balance_deviations(motor, t, np.full(t.size, 7.0), w, i, 0.15, 0.5)
    dips, _ = balance_deviations(
        motor, t, np.full(t.size, 7.0), w, i, 0.15, 0.5, input_excursion_v=np.full(t.size, 1.0)
    )
    assert flat.activity_v[-1] == 0.0
    assert dips.activity_v[-1] == pytest.approx(zigzag.activity_v[-1], rel=1e-6)
    # a zigzag larger than the excursions is the zigzag's; NaN (no sample) is no excursion
    larger, _ = balance_deviations(
        motor,
        t,
        7.0 + 0.5 * (-1.0) ** np.arange(t.size),
        w,
        i,
        0.15,
        0.5,
        input_excursion_v=np.full(t.size, 0.3),
    )
    assert larger.activity_v[-1] == pytest.approx(zigzag.activity_v[-1], rel=1e-9)
    missing, _ = balance_deviations(
        motor, t, np.full(t.size, 7.0), w, i, 0.15, 0.5, input_excursion_v=np.full(t.size, np.nan)
    )
    assert missing.activity_v[-1] == 0.0


def test_the_step_allowance_over_changes_sees_a_command_that_zigzags_between_repeated_reports(motor) -> None:
    """An ESC reporting five times per command (50 Hz reports, commands at 10 Hz, as on held-out world
    1009) of a command that zigzags by ±0.5 V: most samples repeat the input, so the samples' own zigzag
    (the activity, the step's allowance by default) sees a change next to a repeat, never two changes;
    over the command's changes (``steady.step_over_changes``, an option) the allowance is 1 V, as at one
    report per command, and the bus voltage's wobble at every sample does not hide it where the command is
    given. A staircase (changes of one sign) is no zigzag. Calls of any length give the same allowance
    (the live agent's batches)."""
    t = np.arange(0.0, 20.0, 0.02)
    update = np.arange(t.size) // 5
    command = 0.5 + 0.5 / 14.0 * (-1.0) ** update  # ±0.5 V on a 14 V bus
    bus = 14.0 + 0.002 * np.sin(2.0 * np.pi * 7.0 * t)  # a little sag at every sample
    v = command * bus
    w = steady_state(motor, np.full(t.size, 7.0)).omega_rad_s
    i = np.full(t.size, 5.0)

    def allowance(volts, cmd, cuts=(0, t.size), over_changes=True):
        carry, parts = [BalanceCarry()], []
        for a, b in zip(cuts, cuts[1:]):
            part, carry = balance_deviations_rows(
                motor,
                t[None, a:b],
                volts[None, a:b],
                w[None, a:b],
                i[None, a:b],
                0.15,
                0.5,
                carry,
                command=None if cmd is None else cmd[None, a:b],
                zigzag_over_changes=over_changes,
            )
            parts.append(part)
        return parts

    (res,) = allowance(v, command)
    assert res.zigzag_v[0, -1] == pytest.approx(1.0, rel=0.02)
    # by default the allowance is the samples' own zigzag, the activity as measured: it does not see it
    (default,) = allowance(v, command, over_changes=False)
    assert default.zigzag_v[0, -1] < 0.1
    np.testing.assert_array_equal(default.zigzag_v[0], input_activity(t, v, 0.5)[0])
    # without the command, a change is any change of the input: the wobble next to each jump hides it
    (blind,) = allowance(v, None)
    assert blind.zigzag_v[0, -1] < 0.1
    # a staircase of the same updates is no zigzag
    stairs = 0.3 + 0.002 * update
    (up,) = allowance(stairs * 14.0, stairs)
    assert np.max(up.zigzag_v) == 0.0
    # in calls of uneven lengths (a command's repeats cut anywhere), the same allowance
    parts = allowance(v, command, cuts=(0, 7, 8, 13, 301, 302, 640, t.size))
    np.testing.assert_allclose(
        np.concatenate([p.zigzag_v[0] for p in parts]), res.zigzag_v[0], rtol=1e-9, atol=1e-12
    )


def test_warm_mask_restarts_after_idle() -> None:
    t = np.arange(12) * 0.1
    v = np.full(12, 6.0)
    idle = np.zeros(12, dtype=bool)
    idle[4:6] = True  # the motor idles at 0.4-0.5 s: the low-passes fill with spin-down
    warm, _ = warm_mask(t, v, 0.25, 0.5, 1.0, restart=idle)
    # start at 0 → warm from 0.3; idle until 0.5 → warm again from 0.8
    assert warm.tolist() == [False, False, False, True, False, False, False, False, True, True, True, True]


def test_gusty_air_is_judged_not_waited_out(motor, gusty_flight) -> None:
    """Single commands dip to idle all the time in gusty air; only a low-passed input at idle restarts
    the wait (restarting at every dip left a third of the samples judged, against two thirds)."""
    r = diagnose(gusty_flight.table, motor, load_profile("flight"))
    active = r["throttle"] >= 0.2
    assert np.mean(r["steady"][active]) > 0.5
    assert np.mean(r["state"][r["steady"]] == MotorState.NORMAL) > 0.99


def test_a_stream_is_judged_once_its_low_passes_have_filled(motor, gusty_flight) -> None:
    """A new stream waits three time constants of the activity's low-pass and of the deviations' low-pass
    at that sample, which in gusty air the activity has lengthened (judged after the activity's wait
    alone, the first seconds of gusty flights still held the take-off and flickered on healthy motors)."""
    profile = load_profile("flight")
    rule = profile.steady
    r = diagnose(gusty_flight.table, motor, profile)
    for m in r.motors():
        sel = r["motor"] == m
        t, activity = r["time_s"][sel], r["input_activity_v"][sel]
        tau = np.clip(
            rule.residual_tau_s * activity / rule.activity_ref_v, rule.residual_tau_s, rule.residual_tau_max_s
        )
        first = np.flatnonzero(r["steady"][sel])[0]
        assert 3.0 * tau[first] > 3.0 * rule.activity_tau_s  # here the deviations' wait is the longer one
        assert t[first] - t[0] >= 3.0 * tau[first] - 1e-9


@pytest.fixture(scope="module")
def small_faults():
    """Small faults in calm air at 12 s (severity 0.1, a tenth of the paper's), and a healthy flight."""
    cases = [
        FlightCase("calm", 5131, 30.0, fault="F4.1", motor=2, onset_s=12.0, severity=0.1),
        FlightCase("calm", 5133, 30.0, fault="F1.1", motor=4, onset_s=12.0, severity=0.1),
        FlightCase("calm", 5136, 30.0),
    ]
    return list(zip(cases, run_flights(cases, jobs=2)))


def test_slow_look_names_small_lasting_faults_the_fast_look_misses(motor, small_faults) -> None:
    """steady.slow_factor: the deviations averaged four times longer, against the tuned narrower bands,
    name a small F4.1 and F1.1 on far more samples than the fast look alone (about 0.95 against 0.73
    and 0.83 against 0.51 on these flights); no other motor is announced, and a healthy flight stays
    NORMAL."""
    from dataclasses import replace

    shipped = load_profile("flight")
    assert shipped.steady.slow_factor == 4.0 and 0 < shipped.slow_band_fraction < 1
    fast_only = replace(shipped, slow_band_fraction=0.0)
    for case, flight in small_faults:
        r = diagnose(flight.table, motor, shipped)
        if case.fault is None:
            assert np.all(r["announced"] == MotorState.NORMAL)
            assert np.mean(r["state"][r["steady"]] == MotorState.NORMAL) > 0.995
            continue
        fast = diagnose(flight.table, motor, fast_only)
        sel = (r["motor"] == case.motor) & (r["time_s"] >= case.onset_s + 3.0) & r["steady"]
        code = MotorState.from_label(case.fault)
        with_slow, without = np.mean(r["state"][sel] == code), np.mean(fast["state"][sel] == code)
        assert with_slow > 0.75 and with_slow > without + 0.15, (case.name, with_slow, without)
        assert np.any(r["announced"][sel] == code)
        others = (r["motor"] != case.motor) & r["steady"]
        assert np.all(r["announced"][others] == MotorState.NORMAL), case.name


def test_without_a_slow_look_its_columns_are_empty(motor, flights) -> None:
    """A balance profile without a slow look (slow_factor 0) judges with the fast look alone."""
    from dataclasses import replace

    shipped = load_profile("flight")
    no_slow = replace(shipped, steady=replace(shipped.steady, slow_factor=0.0), slow_band_fraction=0.0)
    r = diagnose(flights["F4.1"].table, motor, no_slow)
    assert np.all(np.isnan(r["omega_slow_judged_rad_s"])) and np.all(np.isnan(r["current_slow_judged_a"]))
    assert not r["slow_ready"].any()
    with_slow = diagnose(flights["F4.1"].table, motor, shipped)
    assert with_slow["slow_ready"].mean() > 0.5  # calm air: most judged samples get the slow look too


def _with_battery_and_repeats(table: TelemetryTable) -> tuple[TelemetryTable, TelemetryTable]:
    """The flight with a battery monitor (the ESC input currents' sum), and the same flight as a .tlog
    reads it: ArduPilot streams every ESC's last packet in each ESC_TELEMETRY message, so between an
    ESC's own samples come rows without speed or current, at the other ESCs' sample times."""
    t, motors = table["time_s"], table["motor"]
    times = np.unique(t)
    battery = np.zeros(times.size)
    for m in table.motors():
        sel = np.flatnonzero(motors == m)
        j = np.searchsorted(t[sel], times, side="right") - 1
        battery += np.where(j >= 0, table["esc_current_a"][sel][np.maximum(j, 0)], 0.0)
    cols = {n: table[n] for n in table.names}
    cols["battery_current_a"] = battery[np.searchsorted(times, t)]
    measured = TelemetryTable(cols, source="flight")
    padded: dict[str, list] = {n: [] for n in cols}
    for m in table.motors():
        sel = np.flatnonzero(motors == m)
        extra = np.setdiff1d(times[times > t[sel][0]], t[sel])
        last = sel[np.searchsorted(t[sel], extra, side="right") - 1]  # the ESC's previous packet
        for n in cols:
            values = cols[n][last].astype(float)
            if n in ("omega_rad_s", "current_a", "esc_current_a"):
                values[:] = np.nan  # a repeated packet: no new measurement
            elif n == "time_s":
                values = extra
            elif n == "battery_current_a":
                values = battery[np.searchsorted(times, extra)]
            padded[n].append(np.concatenate([cols[n][sel].astype(float), values]))
    repeated = TelemetryTable({n: np.concatenate(v) for n, v in padded.items()}, source="flight.tlog")
    repeated = TelemetryTable(
        {**{n: repeated[n] for n in repeated.names}, "motor": repeated["motor"].astype(np.int64)},
        source="flight.tlog",
    )
    return measured, repeated.sorted_by_motor_time()


def test_rows_without_a_measurement_change_nothing(motor, gusty_flight) -> None:
    """A .tlog's repeated ESC packets become rows without speed or current (telemetry/tlog.py). They are
    not samples: the live agent skips them. Diagnosed with them, the flight's measured rows come out as
    without them, and the rows read NO_DATA and keep the announced state. (Before this test the core
    counted them, so that a 10 Hz ESC in 50 Hz messages looked like a 50 Hz one to the input activity,
    and the ESC currents' sum took them as the ESC's latest reading, 0 A, and against the battery monitor
    distrusted nearly every current of a live capture: its replay fell back to speed alone.)"""
    profile = load_profile("flight")
    measured, repeated = _with_battery_and_repeats(gusty_flight.table)
    assert len(repeated) > 2 * len(measured)  # most rows are repeats, as in a live capture
    plain = diagnose(measured, motor, profile)
    padded = diagnose(repeated, motor, profile)
    has = np.isfinite(padded["omega_rad_s"])
    key = np.lexsort((plain["time_s"], plain["motor"]))
    for name in ("state", "announced", "steady", "sensor_flags", "omega_judged_rad_s"):
        np.testing.assert_array_equal(padded[name][has], plain[name][key], err_msg=name)
    assert np.all(padded["state"][~has] == MotorState.NO_DATA)
    for m in padded.motors():
        sel = np.flatnonzero(padded["motor"] == m)
        gaps = sel[~has[sel]]
        previous = sel[has[sel]][np.searchsorted(sel[has[sel]], gaps) - 1]
        np.testing.assert_array_equal(padded["announced"][gaps], padded["announced"][previous])
    assert np.mean((plain["sensor_flags"] & SensorIssue.CURRENT_SUM) != 0) < 0.05
