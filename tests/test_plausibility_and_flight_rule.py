"""Plausibility checks, the speed-only tree, the dynamic (flight) steady rule and the ESC mapping."""

from __future__ import annotations

import numpy as np
import pytest

from mav_motor_health.diagnosis import MotorState, StreamingDiagnoser, ThresholdProfile, classify, diagnose
from mav_motor_health.diagnosis.plausibility import (
    CurrentSumCheck,
    PlausibilityRule,
    SensorIssue,
    check_motor,
    stuck_mask,
    sum_mismatch,
)
from mav_motor_health.diagnosis.rules import DynamicRule
from mav_motor_health.model import steady_state
from mav_motor_health.model.dynamics import first_order_response, time_constant_s
from mav_motor_health.model.esc import motor_current_a, motor_voltage_v
from mav_motor_health.telemetry import TelemetryTable

RULE = PlausibilityRule()


def test_esc_mapping_round_trip() -> None:
    duty = np.array([0.0, 0.02, 0.5, 1.0, 1.2])
    np.testing.assert_allclose(motor_voltage_v(duty, 16.0), [0, 0.32, 8, 16, 16])
    i = motor_current_a([0.1, 0.1, 5.0, 10.0, 10.0], duty)
    assert np.isnan(i[0]) and np.isnan(i[1])
    np.testing.assert_allclose(i[2:], [10.0, 10.0, 10.0])


def test_constant_current_while_the_command_moves_is_stuck() -> None:
    t = np.arange(0, 10, 0.1)
    command = 0.5 + 0.1 * np.sin(t)
    stuck, _ = stuck_mask(RULE, t, np.full(t.size, 0.80), command)
    assert not stuck[t < 2.0].any() and stuck[t >= 2.5].all()
    # a real, noisy sensor is not stuck; a constant current at constant command is not either
    rng = np.random.default_rng(0)
    noisy, _ = stuck_mask(RULE, t, np.round(5 + rng.normal(0, 0.05, t.size), 2), command)
    assert not noisy.any()
    idle, _ = stuck_mask(RULE, t, np.zeros(t.size), np.zeros(t.size))
    assert not idle.any()


def test_stuck_carry_split_equals_whole() -> None:
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.02, 0.1, 500))
    value = np.round(np.repeat(rng.normal(5, 1, 50), 10), 1)
    value[200:400] = 0.8
    command = np.clip(0.5 + np.cumsum(rng.normal(0, 0.01, 500)), 0, 1)
    whole, _ = stuck_mask(RULE, t, value, command)
    assert whole[300:400].any()
    for cut in (1, 150, 250, 499):
        a, carry = stuck_mask(RULE, t[:cut], value[:cut], command[:cut])
        b, _ = stuck_mask(RULE, t[cut:], value[cut:], command[cut:], carry)
        np.testing.assert_array_equal(np.concatenate([a, b]), whole)


def test_range_and_missing_flags() -> None:
    flags, _ = check_motor(
        RULE, [0.0, 0.1, 0.2, 0.3], None, [1.0, -5.0, np.nan, 300.0], [100.0, 100.0, -1.0, 1e5]
    )
    assert flags[0] == 0
    assert flags[1] & SensorIssue.CURRENT_RANGE
    assert flags[2] & SensorIssue.CURRENT_MISSING and flags[2] & SensorIssue.SPEED_RANGE
    assert flags[3] & SensorIssue.CURRENT_RANGE and flags[3] & SensorIssue.SPEED_RANGE
    assert SensorIssue.describe(int(flags[2])) == "current_missing,speed_range"


def test_sum_of_esc_currents_against_battery() -> None:
    t = np.arange(0, 60, 0.1)
    battery = 40 + 5 * np.sin(t / 3)
    good, ratio, _ = sum_mismatch(RULE, t, battery * 0.97, battery)
    assert not good[t > 10].any() and ratio[-1] == pytest.approx(0.97, abs=0.01)
    half, _, _ = sum_mismatch(RULE, t, battery * 0.5, battery)
    assert half[t > 10].all()


def test_current_sum_check_adds_every_motors_latest_reading_in_any_chunking() -> None:
    """Six ESCs reporting in turn at 50 Hz, the battery monitor reading half their sum from 30 s on; motor
    4 to 6 report from 5 s on. Fed at once (replay) or row by row (the agent): the same flags; none before
    every motor has reported (a sum of three is no sum: counting the silent ones as 0 A flagged the first
    seconds); the misreading battery found after it begins."""
    rng = np.random.default_rng(8)
    n = 3000
    motor = np.tile(np.arange(1, 7), n // 6)
    t = np.repeat(np.arange(n // 6) * 0.02, 6) + (motor - 1) * 0.003
    esc = rng.uniform(4.0, 6.0, n)
    esc[(motor >= 4) & (t < 5.0)] = np.nan
    esc[rng.random(n) < 0.05] = np.nan  # lost readings: the motor's last one stands
    battery = np.full(n, 30.6)
    battery[t >= 30.0] = 15.3
    whole = CurrentSumCheck(RULE, motor).update(t, motor, esc, battery)
    one_by_one = CurrentSumCheck(RULE, range(1, 7))
    rows = [
        one_by_one.update(t[k : k + 1], motor[k : k + 1], esc[k : k + 1], battery[k : k + 1])
        for k in range(n)
    ]
    np.testing.assert_array_equal(np.concatenate(rows), whole)
    assert not whole[t < 30.0].any()
    assert whole[t > 35.0].all()


def test_speed_only_tree(testbed_profile: ThresholdProfile, paper_motor) -> None:
    model = steady_state(paper_motor, 9.0)
    w_m, i_m = float(model.omega_rad_s), float(model.current_a)
    # without a trusted current only a large departure counts: 15 % of the model speed (flight default)
    omegas = [w_m - 0.1 * w_m, w_m - 0.2 * w_m, w_m + 0.2 * w_m, 10.0]
    n = len(omegas)
    codes = classify(
        testbed_profile,
        omega_rad_s=omegas,
        omega_model_rad_s=np.full(n, w_m),
        current_a=np.full(n, 0.8),
        current_model_a=np.full(n, i_m),
        voltage_v=np.full(n, 9.0),
        current_trusted=np.zeros(n, bool),
    )
    assert [MotorState(int(c)).label for c in codes] == ["NORMAL", "SLOW", "FAST", "STALLED"]
    # with no current at all (RPM-only ESC) the same
    codes = classify(
        testbed_profile,
        omega_rad_s=omegas,
        omega_model_rad_s=np.full(n, w_m),
        current_a=np.full(n, np.nan),
        current_model_a=np.full(n, i_m),
        voltage_v=np.full(n, 9.0),
    )
    assert [MotorState(int(c)).label for c in codes] == ["NORMAL", "SLOW", "FAST", "STALLED"]


def sitl_like_flight(paper_motor, slow_motor: int | None = None):
    """Six motors on a fluctuating command with a constant reported current, like stock SITL."""
    rng = np.random.default_rng(8)
    t = np.arange(0, 40, 0.1)
    rows = []
    for motor in range(1, 7):
        duty = np.clip(0.55 + 0.05 * np.sin(t * (1 + motor / 7)) + rng.normal(0, 0.01, t.size), 0, 1)
        v = duty * 16.8
        w = steady_state(paper_motor, v).omega_rad_s + rng.uniform(-10, 10, t.size)
        if motor == slow_motor:
            w = np.where(t > 20, w * 0.55, w)
        rows.append(
            dict(
                time_s=t,
                motor=np.full(t.size, motor),
                omega_rad_s=w,
                esc_current_a=np.full(t.size, 0.8),
                current_a=motor_current_a(0.8, duty),
                throttle=duty,
                bus_voltage_v=np.full(t.size, 16.8),
            )
        )
    return TelemetryTable.concat(TelemetryTable.from_columns(**r) for r in rows)


def test_constant_current_is_reported_and_the_slow_motor_found_from_speed(paper_motor) -> None:
    profile = ThresholdProfile(name="t", steady=DynamicRule())
    result = diagnose(
        sitl_like_flight(paper_motor.replace(J_kg_m2=5e-5), slow_motor=1),
        paper_motor.replace(J_kg_m2=5e-5),
        profile,
    )
    late = result["time_s"] > 25
    for motor in range(1, 7):
        sel = (result["motor"] == motor) & late
        assert (result["sensor_flags"][sel] & SensorIssue.CURRENT_STUCK).all()
        announced = set(result["announced"][sel].tolist())
        assert announced == ({MotorState.SLOW} if motor == 1 else {MotorState.NORMAL})


def test_dynamic_rule_follows_a_fluctuating_input(paper_motor) -> None:
    """A healthy motor on a command that moves faster than it can follow: the dynamic prediction tracks it."""
    params = paper_motor.replace(J_kg_m2=5e-5)
    t = np.arange(0, 20, 0.02)
    v = 8 + 1.5 * np.sign(np.sin(2 * np.pi * t / 0.7))  # square wave, steps of 3 V every 0.35 s
    w_ss = steady_state(params, v).omega_rad_s
    true_w, _ = first_order_response(t, w_ss, time_constant_s(params, w_ss))
    i_true = (v - params.k_e * true_w) / params.R_ohm
    table = TelemetryTable.from_columns(
        time_s=t, motor=np.ones(t.size), voltage_v=v, omega_rad_s=true_w, current_a=i_true
    )
    step = diagnose(table, params, ThresholdProfile(name="step"))
    # the lag criterion alone (no step rule): it must accept samples between the steps
    dyn = diagnose(table, params, ThresholdProfile(name="dyn", steady=DynamicRule(step_v=10.0)))
    assert np.abs(dyn["omega_rad_s"] - dyn["omega_model_rad_s"]).max() < 1.0  # the response is predicted
    assert set(dyn["announced"].tolist()) == {MotorState.NORMAL}
    assert dyn["steady"].mean() > 0.3  # and it accepts samples between the steps
    raw_step = step["state"][step["time_s"] > 1]
    assert np.mean(raw_step != MotorState.NORMAL) > 0.1  # the steady-state model alone misreads transients


def test_streaming_equals_batch_in_flight_mode(paper_motor) -> None:
    params = paper_motor.replace(J_kg_m2=5e-5)
    table = sitl_like_flight(params, slow_motor=2).select(np.arange(2400) % 3 == 0)
    profile = ThresholdProfile(name="t", steady=DynamicRule())
    batch = diagnose(table, params, profile)
    stream = StreamingDiagnoser(params, profile, batch.motors())  # the vehicle's motors: the vehicle check
    order = np.argsort(batch["time_s"], kind="stable")
    rows = {}
    for j in order:
        rows[j] = stream.update(
            int(batch["motor"][j]),
            float(batch["time_s"][j]),
            float(batch["voltage_v"][j]),
            float(batch["omega_rad_s"][j]),
            float(batch["current_a"][j]),
            command=float(batch["throttle"][j]),
            sensor_current_a=float(batch["esc_current_a"][j]),
        )
    assert [rows[j]["announced"] for j in range(len(batch))] == batch["announced"].tolist()
    assert [rows[j]["sensor_flags"] for j in range(len(batch))] == batch["sensor_flags"].tolist()


def test_pairing_error_is_the_speed_a_command_that_far_off_could_move(paper_motor) -> None:
    """A ramp of 2 V/s with commands paired 50 ms off: the voltage can be 0.1 V off, which moves the balance
    rule's speed deviation by k_t·0.1 V/D; fed in pieces it gives the same (the agent's way)."""
    from mav_motor_health.diagnosis.pairing import pairing_error_rad_s

    t = np.arange(0.0, 4.0, 0.02)
    v = 5.0 + 2.0 * t
    w_model = steady_state(paper_motor, v).omega_rad_s
    whole, _ = pairing_error_rad_s(paper_motor, t, v, w_model, 0.05, 0.15)
    p = paper_motor
    g = p.k * p.C_p * w_model ** (p.k - 1.0) + p.B
    expected = p.k_t * 2.0 * 0.05 / (p.k_t * p.k_e + p.R_ohm * g)
    settled = t > 1.0
    np.testing.assert_allclose(whole[settled], expected[settled], rtol=1e-6)
    carry, parts = None, []
    for k in range(0, t.size, 7):
        part, carry = pairing_error_rad_s(
            paper_motor, t[k : k + 7], v[k : k + 7], w_model[k : k + 7], 0.05, 0.15, carry
        )
        parts.append(part)
    np.testing.assert_allclose(np.concatenate(parts), whole)
    still, _ = pairing_error_rad_s(paper_motor, t, np.full(t.size, 7.0), w_model, 0.05, 0.15)
    assert np.all(still == 0.0)  # a command that stands still is paired right whenever it was read


def test_a_command_dip_between_two_samples_counts_as_the_commands_movement(paper_motor) -> None:
    """A command that stands still at the samples but dips by e and back between them (``input_excursion_v``)
    moved 2e per interval: the pairing error of a ramp of 2e/Δt (diagnosis/pairing.py); none given, none."""
    from mav_motor_health.diagnosis.pairing import PairingCarry, pairing_error_rad_s, pairing_error_rows

    t = np.arange(0.0, 4.0, 0.02)
    v = np.full(t.size, 7.0)
    w_model = steady_state(paper_motor, v).omega_rad_s

    def rows(x: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=float).reshape(1, -1)

    tau = np.full((1, t.size), 0.15)
    dips, _ = pairing_error_rows(
        paper_motor,
        rows(t),
        rows(v),
        rows(w_model),
        0.05,
        tau,
        [PairingCarry()],
        input_excursion_v=rows(np.full(t.size, 0.02)),
    )
    ramp, _ = pairing_error_rad_s(paper_motor, t, 7.0 + 2.0 * t, w_model, 0.05, 0.15)
    settled = t > 1.0
    np.testing.assert_allclose(dips[0][settled], ramp[settled], rtol=1e-6)  # 2 × 0.02 V per 0.02 s: 2 V/s
    none, _ = pairing_error_rows(
        paper_motor, rows(t), rows(v), rows(w_model), 0.05, tau, [PairingCarry()], input_excursion_v=None
    )
    assert np.all(none == 0.0)


def test_a_pairing_per_sample_is_the_one_number_where_all_are_equal(paper_motor) -> None:
    """The pairing guard weighs each sample's own pairing (a log's ``pairing_s`` column, the live agent's
    samples'): all equal, it is the guard with that one number — the pairing error, and the whole
    diagnosis of a loosely paired log; varying, each sample is weighed with the 95th percentile of the
    last second's pairings (diagnosis/pairing.py), the same fed whole or in pieces."""
    from pathlib import Path

    from mav_motor_health.config import load_profile
    from mav_motor_health.diagnosis.pairing import PAIRING_WINDOW_S, pairing_error_rad_s
    from mav_motor_health.telemetry import sources

    t = np.arange(0.0, 4.0, 0.02)
    v = 5.0 + 2.0 * t + 0.3 * np.sin(5 * t)
    w_model = steady_state(paper_motor, v).omega_rad_s
    scalar, _ = pairing_error_rad_s(paper_motor, t, v, w_model, 0.05, 0.15)
    per_sample, _ = pairing_error_rad_s(paper_motor, t, v, w_model, np.full(t.size, 0.05), 0.15)
    np.testing.assert_array_equal(per_sample, scalar)
    assert scalar.max() > 0
    # a stream whose commands age from 10 to 90 ms: weighed with its loosest pairing, 90 ms
    sawtooth = 0.01 + 0.02 * (np.arange(t.size) % 5)
    mixed, _ = pairing_error_rad_s(paper_motor, t, v, w_model, sawtooth, 0.15)
    low, _ = pairing_error_rad_s(paper_motor, t, v, w_model, 0.01, 0.15)
    high, _ = pairing_error_rad_s(paper_motor, t, v, w_model, 0.09, 0.15)
    np.testing.assert_array_equal(mixed[t >= 0.08], high[t >= 0.08])
    # one loosely paired sample (a stalled read) among the last second's 50 is not weighed; a stretch of
    # them (more than 5 % of the window) is, for the second it stays in the window
    loose = t[100]  # 2 s
    varying = np.where(t == loose, 0.09, 0.01)
    mixed, _ = pairing_error_rad_s(paper_motor, t, v, w_model, varying, 0.15)
    np.testing.assert_array_equal(mixed[t > 1.0], low[t > 1.0])
    stretch = (t >= loose) & (t < loose + 0.09)  # 5 samples, 10 % of the window
    varying = np.where(stretch, 0.09, 0.01)
    mixed, _ = pairing_error_rad_s(paper_motor, t, v, w_model, varying, 0.15)
    third, last = t[stretch][2], t[stretch][-1]
    weighed = (t >= third) & (t - PAIRING_WINDOW_S <= third)  # 3 of the window's 50: its 95th percentile
    np.testing.assert_array_equal(mixed[weighed], high[weighed])
    gone = t - PAIRING_WINDOW_S > last
    np.testing.assert_array_equal(mixed[gone], low[gone])
    carry, parts = None, []
    for k in range(0, t.size, 7):
        part, carry = pairing_error_rad_s(
            paper_motor, t[k : k + 7], v[k : k + 7], w_model[k : k + 7], varying[k : k + 7], 0.15, carry
        )
        parts.append(part)
    np.testing.assert_allclose(np.concatenate(parts), mixed, rtol=1e-12)

    # the whole diagnosis of a loosely paired log: a column of one value is that value as one number
    table = sources.read(Path(__file__).resolve().parents[1] / "sitl_logs" / "flight_F4.1_moderate.tlog")
    profile = load_profile("flight")
    columns = {name: table[name] for name in table.names if name != "pairing_s"}
    constant = TelemetryTable({**columns, "pairing_s": np.full(len(table), 0.1)}, source=table.source)
    one_number = TelemetryTable(columns, source=table.source, meta={"pairing_s": 0.1})
    a, b = diagnose(constant, paper_motor, profile), diagnose(one_number, paper_motor, profile)
    assert ((a["sensor_flags"] & SensorIssue.CURRENT_UNPAIRED) != 0).any()  # the guard acts
    for name in ("state", "announced", "steady", "sensor_flags", "pairing_error_rad_s", "omega_model_rad_s"):
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_the_pairing_guard_keeps_a_current_further_off_than_the_pairing_could_move_it(tmp_path) -> None:
    """The demo's flight (``flight/healthy_calm``, its seed), 30 s, motor 3's propeller damaged at 20 s,
    logged as a .tlog streaming ESC telemetry and commands at 100 Hz, the rate the simulated vehicle sends
    the agent. The autopilot answers the lost thrust by driving motor 3's command up; each ESC packet is
    paired with a command up to a message interval away, and the pairing error then exceeds the `flight`
    profile's speed band. The current, far below the model, departs further than the pairing could move it
    (diagnosis/rules/pairing.py, "A departure beyond the pairing's reach"), so it is kept and F3.1 is
    announced 0.16 s after the damage; before, the guard set it aside, the motor read FAST on its speed
    alone, and F3.1 came 0.44 s after. No other motor is announced anything."""
    import dataclasses

    from mav_motor_health.config import load_motor_params, load_profile
    from mav_motor_health.diagnosis import MotorState, diagnose
    from mav_motor_health.sim.engine import run_scenario
    from mav_motor_health.sim.faults import FaultSpec
    from mav_motor_health.sim.scenario import load_scenario
    from mav_motor_health.sim.writers import write_record
    from mav_motor_health.telemetry import sources

    scenario = dataclasses.replace(
        load_scenario("flight/healthy_calm"),
        duration_s=30.0,
        esc_stream_hz=100.0,
        log_hz=100.0,
        faults=(FaultSpec("F3.1", 3, 20.0),),
    )
    log, _ = write_record(run_scenario(scenario), tmp_path / "demo.tlog")
    result = diagnose(sources.read(log), load_motor_params(), load_profile("flight"))
    motor, announced, t = result["motor"], result["announced"], result["time_s"]
    assert (announced[motor != 3] == MotorState.NORMAL).all()
    first = t[(motor == 3) & (announced == MotorState.F3_1)].min()
    assert 20.0 < first < 20.25, first
    assert (announced[(motor == 3) & (t < 20.0)] == MotorState.NORMAL).all()
