"""Persistence, the steady rule, and the promise that streaming equals batch."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mav_motor_health.diagnosis import MotorState, StreamingDiagnoser, diagnose
from mav_motor_health.diagnosis.persistence import PersistenceCarry, announce
from mav_motor_health.diagnosis.profile import PersistenceRule
from mav_motor_health.diagnosis.rules import StepRule
from mav_motor_health.diagnosis.steady import SteadyCarry, steady_mask
from mav_motor_health.sim import steady as steady_sim
from mav_motor_health.telemetry import TelemetryTable


def test_state_must_hold_before_it_is_announced() -> None:
    rule = PersistenceRule(default_announce_s=0.3, clear_s=0.5, announce_s=(("F2.1", 0.1),))
    t = np.arange(0, 2.0, 0.1)
    s = np.zeros(t.size, dtype=int)
    s[5:8] = MotorState.F1_1  # 0.2 s long: never announced
    s[10:] = MotorState.F1_1
    out, carry = announce(rule.hold_s(), t, s, np.ones(t.size, bool))
    assert set(out[:13]) == {MotorState.NORMAL}
    assert out[13] == MotorState.F1_1  # 0.3 s after onset at t=1.0
    assert carry.announced == MotorState.F1_1
    # clearing needs 0.5 s of NORMAL
    t2 = np.arange(2.0, 3.0, 0.1)
    out2, _ = announce(rule.hold_s(), t2, np.zeros(t2.size, int), np.ones(t2.size, bool), carry)
    assert out2[4] == MotorState.F1_1 and out2[5] == MotorState.NORMAL


def test_ineligible_samples_neither_confirm_nor_break() -> None:
    rule = PersistenceRule(default_announce_s=0.25)
    t = np.arange(0, 1.0, 0.1)
    s = np.full(t.size, MotorState.F4_1)
    eligible = np.array([1, 1, 0, 0, 1, 1, 1, 1, 1, 1], bool)
    s[2:4] = MotorState.F3_1  # ignored: not eligible
    out, _ = announce(rule.hold_s(), t, s, eligible)
    assert out[4] == MotorState.F4_1 and out[2] == MotorState.NORMAL


def test_steady_rule_waits_after_a_step() -> None:
    t = np.arange(0, 2.0, 0.05)
    v = np.where(t < 1.0, 8.0, 10.0)
    mask, carry = steady_mask(StepRule(step_v=0.2, settle_s=0.3), t, v)
    assert not mask[t < 0.3].any() and mask[(t >= 0.3) & (t < 1.0)].all()
    assert not mask[(t >= 1.0) & (t < 1.29)].any() and mask[t >= 1.3].all()
    assert carry.last_step_time_s == 1.0


@settings(max_examples=25, deadline=None)
@given(
    st.integers(0, 2**31 - 1),
    st.sampled_from(["NORMAL", "F1.1", "F2.1", "F3.1", "F4.1", "F4.2"]),
    st.sampled_from([4.2, 7.6, 11.0]),
)
def test_streaming_equals_batch(paper_motor, testbed_profile, seed, fault, volts) -> None:
    rng = np.random.default_rng(seed)
    cols = steady_sim.testbed_run(paper_motor, fault, volts, rng, duration_s=4.0, fault_at_s=2.0)
    cols["voltage_v"] = cols["voltage_v"] + np.where(cols["time_s"] > 3.0, 0.5, 0.0)  # one step too
    batch = diagnose(TelemetryTable(cols), paper_motor, testbed_profile)
    stream = StreamingDiagnoser(paper_motor, testbed_profile)
    rows = [
        stream.update(1, t, v, w, i)
        for t, v, w, i in zip(cols["time_s"], cols["voltage_v"], cols["omega_rad_s"], cols["current_a"])
    ]
    assert [r["announced"] for r in rows] == batch["announced"].tolist()
    assert [r["state"] for r in rows] == batch["state"].tolist()
    assert [r["steady"] for r in rows] == batch["steady"].tolist()


def test_carries_split_anywhere_give_same_result() -> None:
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.01, 0.05, 400))
    s = rng.choice([0, 1, 4], size=400, p=[0.6, 0.3, 0.1])
    eligible = rng.random(400) > 0.2
    holds = PersistenceRule(default_announce_s=0.08, clear_s=0.12).hold_s()
    whole, _ = announce(holds, t, s, eligible)
    for cut in (1, 57, 200, 399):
        a, carry = announce(holds, t[:cut], s[:cut], eligible[:cut], PersistenceCarry())
        b, _ = announce(holds, t[cut:], s[cut:], eligible[cut:], carry)
        np.testing.assert_array_equal(np.concatenate([a, b]), whole)


def test_steady_carry_split() -> None:
    rng = np.random.default_rng(9)
    t = np.cumsum(rng.uniform(0.01, 0.05, 300))
    v = 8 + np.cumsum(rng.normal(0, 0.08, 300))
    rule = StepRule(step_v=0.1, settle_s=0.1)
    whole, _ = steady_mask(rule, t, v)
    a, carry = steady_mask(rule, t[:123], v[:123], SteadyCarry())
    b, _ = steady_mask(rule, t[123:], v[123:], carry)
    np.testing.assert_array_equal(np.concatenate([a, b]), whole)


def test_hold_grows_with_activity() -> None:
    t = np.arange(0.0, 2.0, 0.02)
    state = np.full(t.size, int(MotorState.F1_1), dtype=np.int8)
    eligible = np.ones(t.size, dtype=bool)
    holds = np.full(len(MotorState), 0.2)
    slopes = np.zeros(len(MotorState))
    slopes[MotorState.F1_1] = 0.5  # s per V
    calm, _ = announce(holds, t, state, eligible, hold_per_activity_s=slopes, activity=np.full(t.size, 0.1))
    gusty, _ = announce(holds, t, state, eligible, hold_per_activity_s=slopes, activity=np.full(t.size, 2.0))

    def first(announced: np.ndarray) -> float:
        return float(t[np.flatnonzero(announced == MotorState.F1_1)[0]])

    assert abs(first(calm) - 0.26) < 0.011  # 0.2 + 0.5·0.1
    assert abs(first(gusty) - 1.2) < 0.011  # 0.2 + 0.5·2.0


def test_a_deep_departure_is_held_sooner() -> None:
    """rate (the tree's depth, capped): the interval before a sample counts rate times toward the hold."""
    t = np.arange(0.0, 1.0, 0.02)
    state = np.full(t.size, int(MotorState.F1_1), dtype=np.int8)
    eligible = np.ones(t.size, dtype=bool)
    holds = np.full(len(MotorState), 0.2)

    def first(rate: np.ndarray | None) -> float:
        out, _ = announce(holds, t, state, eligible, rate=rate)
        return float(t[np.flatnonzero(out == MotorState.F1_1)[0]])

    assert first(None) == pytest.approx(0.2)
    assert first(np.ones(t.size)) == pytest.approx(0.2)
    assert first(np.full(t.size, 2.0)) == pytest.approx(0.1)  # twice as deep: half the time
    assert first(np.full(t.size, 4.0)) == pytest.approx(0.06)  # 3 intervals of 0.02 s × 4 ≥ 0.2


def test_rate_carries_split_anywhere_give_same_result() -> None:
    rng = np.random.default_rng(6)
    t = np.cumsum(rng.uniform(0.01, 0.05, 400))
    s = rng.choice([0, 1, 4], size=400, p=[0.5, 0.35, 0.15])
    eligible = rng.random(400) > 0.2
    rate = rng.uniform(1.0, 3.0, 400)
    holds = PersistenceRule(default_announce_s=0.15, clear_s=0.12).hold_s()
    whole, _ = announce(holds, t, s, eligible, rate=rate)
    assert (whole != 0).any() and (whole == 0).any()
    for cut in (1, 57, 200, 399):
        a, carry = announce(holds, t[:cut], s[:cut], eligible[:cut], PersistenceCarry(), rate=rate[:cut])
        b, _ = announce(holds, t[cut:], s[cut:], eligible[cut:], carry, rate=rate[cut:])
        np.testing.assert_array_equal(np.concatenate([a, b]), whole)
