"""The vectorised streaming kernels against the per-sample logic they replace (issue 18).

Seeded random inputs, with the awkward cases the core meets: missing inputs, gaps, restarts, an undefined
start, time constants that vary per sample; fed whole, in random chunks and one sample at a time.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mav_motor_health.diagnosis.pairing import (
    PairingCarry,
    _loosest_pairing_rows,
    loosest_pairing,
    pairing_error_rows,
)
from mav_motor_health.diagnosis.persistence import PersistenceCarry, announce
from mav_motor_health.diagnosis.profile import PersistenceRule
from mav_motor_health.model.dynamics import (
    ResponseCarry,
    affine_recurrence,
    first_order_response,
    first_order_responses,
)
from mav_motor_health.model.params import MotorParams

RESTART_DECAY = 600.0


# -- the per-sample definitions (as the code read before the vectorised kernels) -----------------------
def response_per_sample(t, x, tau, carry=None):
    """The first-order lag sample by sample: the definition the vectorised filter must reproduce."""
    carry = carry or ResponseCarry()
    tau = np.broadcast_to(np.asarray(tau, dtype=float), np.shape(t))
    out = np.empty(len(t))
    y, prev_t, prev_x = carry.output, carry.time_s, carry.input
    for k, (tk, xk, tau_k) in enumerate(zip(np.asarray(t).tolist(), np.asarray(x).tolist(), tau.tolist())):
        dt = max(tk - prev_t, 0.0) if math.isfinite(tk - prev_t) else math.inf
        decay = dt / tau_k if math.isfinite(tau_k) and tau_k > 0 else math.inf
        if not math.isfinite(xk):
            pass
        elif not math.isfinite(decay) or decay >= RESTART_DECAY or not math.isfinite(y):
            y = xk
        else:
            mean_in = 0.5 * (prev_x + xk) if math.isfinite(prev_x) else xk
            a = float(np.exp(-decay))  # numpy's exp, as the code's (libm's can differ in the last bit)
            y = a * y + (1.0 - a) * mean_in
        out[k] = y
        prev_t, prev_x = tk, xk
    # the last input as it is (NaN where missing): a next call's first interval then averages from its
    # own input alone, as it would in one array
    return out, ResponseCarry(time_s=float(t[-1]), input=float(x[-1]), output=float(out[-1]))


def announce_per_run(hold_s, time_s, state, eligible, carry=None, max_gap_s=float("inf"),
                     hold_per_activity_s=None, activity=None, rate=None):  # fmt: skip
    """Persistence run by run, as it read before it was vectorised."""
    carry = carry or PersistenceCarry()
    t = np.asarray(time_s, dtype=float)
    s = np.asarray(state, dtype=np.int64)
    idx = np.flatnonzero(eligible)
    change_at: list[int] = []
    change_to: list[int] = []
    announced, candidate, since = carry.announced, carry.candidate, carry.candidate_since_s
    held_s = carry.candidate_held_s
    if idx.size:
        te, se = t[idx], s[idx]
        boundaries = np.flatnonzero((np.diff(se) != 0) | (np.diff(te) > max_gap_s)) + 1
        starts = np.concatenate([[0], boundaries])
        ends = np.concatenate([boundaries, [se.size]])
        for start, end in zip(starts.tolist(), ends.tolist()):
            run_state = int(se[start])
            continues = start == 0 and run_state == candidate and te[0] - carry.last_eligible_s <= max_gap_s
            run_since = since if continues else float(te[start])
            candidate, since = run_state, run_since
            if rate is not None:
                steps = np.diff(te[start:end], prepend=carry.last_eligible_s if continues else te[start])
                held = (held_s if continues else 0.0) + np.cumsum(rate[idx[start:end]] * steps)
            else:
                held = te[start:end] - run_since
            held_s = float(held[-1])
            if run_state == announced:
                continue
            hold = float(hold_s[run_state])
            extra = None
            if hold_per_activity_s is not None and activity is not None and hold_per_activity_s[run_state]:
                extra = float(hold_per_activity_s[run_state]) * np.nan_to_num(activity[idx[start:end]])
            if rate is None and extra is None:
                j = start + int(np.searchsorted(te[start:end], run_since + hold, side="left"))
            else:
                need = hold if extra is None else hold + extra
                reached = np.flatnonzero(held >= need)
                j = start + (int(reached[0]) if reached.size else end - start)
            if j < end:
                announced = run_state
                change_at.append(int(idx[j]))
                change_to.append(run_state)
    out = np.full(t.size, carry.announced, dtype=np.int8)
    if change_at:
        positions = np.asarray(change_at)
        which = np.searchsorted(positions, np.arange(t.size), side="right") - 1
        values = np.asarray(change_to, dtype=np.int8)
        has = which >= 0
        out[has] = values[which[has]]
    last = float(t[idx[-1]]) if idx.size else carry.last_eligible_s
    return out, PersistenceCarry(announced, candidate, since, last, held_s)


# -- inputs ----------------------------------------------------------------------------------------------
def lag_inputs(seed: int, n: int):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.06, n))
    t[rng.random(n) < 0.01] += rng.uniform(0.5, 400.0)  # gaps, some long enough to restart the filter
    t = np.maximum.accumulate(t)
    x = rng.normal(3.0, 2.0, n)
    x[rng.random(n) < 0.05] = np.nan  # missing inputs hold the output
    x[: rng.integers(0, 5)] = np.nan  # sometimes an undefined start
    tau = rng.uniform(1e-3, 2.0, n)
    tau[rng.random(n) < 0.01] = np.nan  # no lag: the target itself
    tau[rng.random(n) < 0.005] = 0.0
    return t, x, tau


def chunks(n: int, rng: np.random.Generator):
    k = 0
    while k < n:
        step = int(rng.integers(1, 300))
        yield slice(k, min(k + step, n))
        k += step


def same_carry(a: ResponseCarry, b: ResponseCarry) -> bool:
    """Equal carries, a missing (NaN) input equal to a missing one."""
    return all(x == y or (math.isnan(x) and math.isnan(y)) for x, y in zip(a, b))


def assert_close(got, want):
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12, equal_nan=True)


# -- the affine recurrence --------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [0, 1, 5, 128, 129, 1000, 64 * 64 * 3 + 17])
def test_affine_recurrence_is_the_loop(n: int) -> None:
    rng = np.random.default_rng(n)
    a = rng.uniform(0.0, 1.0, n)
    a[rng.random(n) < 0.05] = 0.0
    a[rng.random(n) < 0.05] = 1.0
    b = rng.normal(0.0, 5.0, n)
    want = np.empty(n)
    y = 2.5
    for k in range(n):
        y = a[k] * y + b[k]
        want[k] = y
    assert_close(affine_recurrence(a, b, 2.5), want)


def test_affine_recurrence_rows_are_independent() -> None:
    rng = np.random.default_rng(7)
    a = rng.uniform(0.0, 1.0, (5, 3000))
    b = rng.normal(size=(5, 3000))
    y0 = rng.normal(size=5)
    together = affine_recurrence(a, b, y0)
    for r in range(5):
        assert_close(together[r], affine_recurrence(a[r], b[r], y0[r]))


# -- the first-order filter -----------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_first_order_response_whole_chunked_and_one_by_one_match_the_per_sample_definition(seed: int) -> None:
    t, x, tau = lag_inputs(seed, 5000)
    want, want_carry = response_per_sample(t, x, tau)
    whole, whole_carry = first_order_response(t, x, tau)
    assert_close(whole, want)
    assert whole_carry.time_s == want_carry.time_s
    assert whole_carry.input == want_carry.input or (
        math.isnan(whole_carry.input) and math.isnan(want_carry.input)
    )
    assert whole_carry.output == pytest.approx(want_carry.output, rel=1e-12, abs=1e-12)
    # In chunks (the agent's batches) against the definition fed the same chunks, and against the whole
    # array: a chunk that ends on a missing input carries it as missing (NaN), so that the next chunk's
    # first interval averages from its own input alone, as the whole array does (a chunk that carried
    # the last finite input instead had made the agent differ from replay there, issue 18)
    rng = np.random.default_rng(seed)
    carry, ref_carry, parts, ref_parts = ResponseCarry(), ResponseCarry(), [], []
    for part in chunks(t.size, rng):
        y, carry = first_order_response(t[part], x[part], tau[part], carry)
        ref, ref_carry = response_per_sample(t[part], x[part], tau[part], ref_carry)
        parts.append(y)
        ref_parts.append(ref)
    assert_close(np.concatenate(parts), np.concatenate(ref_parts))
    assert_close(np.concatenate(parts), want)
    assert not np.isfinite(x).all()  # (missing inputs, some of them at a chunk's end)
    carry, ones = ResponseCarry(), []
    for k in range(600):
        y, carry = first_order_response(t[k : k + 1], x[k : k + 1], tau[k : k + 1], carry)
        ones.append(y)
    ref_carry, ref_ones = ResponseCarry(), []
    for k in range(600):
        ref, ref_carry = response_per_sample(t[k : k + 1], x[k : k + 1], tau[k : k + 1], ref_carry)
        ref_ones.append(ref)
    np.testing.assert_array_equal(np.concatenate(ones), np.concatenate(ref_ones))  # the same loop


def test_chunks_without_missing_inputs_give_the_whole_array_result() -> None:
    t, x, tau = lag_inputs(21, 4000)
    x = np.where(np.isfinite(x), x, 1.0)
    want, _ = response_per_sample(t, x, tau)
    carry, parts = ResponseCarry(), []
    for part in chunks(t.size, np.random.default_rng(21)):
        y, carry = first_order_response(t[part], x[part], tau[part], carry)
        parts.append(y)
    assert_close(np.concatenate(parts), want)


def test_first_order_response_from_a_carry_with_a_scalar_time_constant() -> None:
    t, x, _ = lag_inputs(11, 3000)
    start = ResponseCarry(time_s=t[0] - 0.02, input=1.0, output=-4.0)
    want, _ = response_per_sample(t, x, 0.3, start)
    got, _ = first_order_response(t, x, 0.3, start)
    assert_close(got, want)


def test_stacked_rows_give_what_one_call_per_row_gives() -> None:
    t, x, tau = lag_inputs(3, 2000)
    rng = np.random.default_rng(3)
    rows = np.stack([x, 2.0 * x - 1.0, np.where(rng.random(x.size) < 0.2, np.nan, x)])
    carries = [ResponseCarry(), ResponseCarry(t[0] - 0.1, 2.0, 2.0), ResponseCarry(t[0] - 0.01, np.nan, 5.0)]
    for sl in (slice(0, 2000), slice(0, 9)):  # the vectorised and the few-samples path
        together, new = first_order_responses(t[sl], rows[:, sl], tau[sl], carries)
        for r, carry in enumerate(carries):
            alone, alone_carry = first_order_response(t[sl], rows[r, sl], tau[sl], carry)
            np.testing.assert_array_equal(together[r], alone)
            assert same_carry(new[r], alone_carry)


def test_rows_of_motors_with_their_own_times_give_what_one_call_per_row_gives() -> None:
    """Several motors' rows (each its own times, full or ragged), several quantities each, time constants
    per sample, some not finite: one call gives each row's own call."""
    rng = np.random.default_rng(11)
    motors, n, quantities = 4, 7, 3
    t = 5.0 + np.cumsum(rng.uniform(0.0, 0.03, (motors, n)), axis=1)
    x = rng.normal(size=(quantities * motors, n))
    x[rng.random(x.shape) < 0.1] = np.nan
    carries = [
        ResponseCarry(4.99, 0.5, 0.25) if r % 3 else ResponseCarry() for r in range(quantities * motors)
    ]
    for tau in (
        rng.uniform(0.05, 0.4, (motors, n)),
        np.where(rng.random((motors, n)) < 0.2, np.nan, 0.2),
        np.full((motors, n), 0.1),
    ):
        for counts in ([n] * motors, [n, 3, 0, 5]):
            together, new = first_order_responses(t, x, tau, carries, counts * quantities)
            for r, carry in enumerate(carries):
                m, count = r % motors, counts[r % motors]
                alone, alone_carry = first_order_response(t[m, :count], x[r, :count], tau[m, :count], carry)
                np.testing.assert_array_equal(together[r, :count], alone)
                assert same_carry(new[r], alone_carry) or (count == 0 and new[r] is carry)


# -- pairing ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_loosest_pairing_of_several_motors_at_once_is_each_motors_own(seed: int) -> None:
    """The live agent's call (every motor's few samples at once, :func:`_loosest_pairing_rows`) against
    :func:`loosest_pairing` one motor at a time, over streams split into random calls: the same pairings
    and carries; and the pairing errors of all motors in one call are each motor's own."""
    rng = np.random.default_rng(seed)
    motors, n = 5, 600
    t = np.cumsum(rng.choice([0.005, 0.01, 0.02, 0.03], (motors, n)), axis=1)
    u = rng.choice([0.0, 0.01, 0.02, 0.05, np.nan], (motors, n), p=[0.3, 0.3, 0.2, 0.1, 0.1])
    if seed % 2:
        u[1] = 0.02  # one motor's stream paired alike throughout
    v = rng.uniform(3.0, 9.0, (motors, n))
    omega = rng.uniform(300.0, 900.0, (motors, n))
    tau = np.full((motors, n), 0.2)
    params = MotorParams(R_ohm=0.165, k_e=0.00975, C_p=1.692e-10, B=1.275e-07, T_f=4.606e-10, k=3.0)
    together = [PairingCarry() for _ in range(motors)]
    alone = [PairingCarry() for _ in range(motors)]
    done = np.zeros(motors, dtype=int)
    while (done < n).any():
        counts = [int(min(n - d, k)) for d, k in zip(done, rng.integers(0, 12, motors))]
        width = max(*counts, 1)

        def rows(x: np.ndarray, counts: list[int] = counts, width: int = width) -> np.ndarray:
            out = np.zeros((motors, width))
            for m, (d, c) in enumerate(zip(done.tolist(), counts)):  # noqa: B023 (called at once)
                out[m, :c] = x[m, d : d + c]
                out[m, c:] = x[m, d + c - 1] if c else 0.0
            return out

        recent = [(c.recent_time_s, c.recent_pairing_s) for c in together]
        picked = _loosest_pairing_rows(rows(t), rows(u), counts, recent)
        if picked is None:  # no samples in this call
            assert sum(counts) == 0
            continue
        error, together = pairing_error_rows(
            params, rows(t), rows(v), rows(omega), rows(u), rows(tau), together, counts
        )
        for m, (d, c) in enumerate(zip(done, counts)):
            sl = slice(d, d + c)
            if c:
                want, *_ = loosest_pairing(
                    t[m, sl], u[m, sl], alone[m].recent_time_s, alone[m].recent_pairing_s
                )
                np.testing.assert_array_equal(picked[0][m, :c], want)
                one_error, (alone[m],) = pairing_error_rows(
                    params,
                    *(x[m : m + 1, sl] for x in (t, v, omega, u, tau)),
                    [alone[m]],
                )
                np.testing.assert_array_equal(error[m, :c], one_error[0])
            np.testing.assert_array_equal(picked[1][m][0], alone[m].recent_time_s)
            np.testing.assert_array_equal(picked[1][m][1], alone[m].recent_pairing_s)
            np.testing.assert_array_equal(together[m].recent_pairing_s, alone[m].recent_pairing_s)
        done += counts


# -- persistence ----------------------------------------------------------------------------------------
def persistence_inputs(seed: int, n: int):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.choice([0.01, 0.02, 0.04, 0.05], n))  # grid times: holds reached exactly on a sample
    t[rng.random(n) < 0.005] += 2.0  # gaps longer than max_gap_s
    s = rng.choice([0, 1, 3, 4, 5], size=n, p=[0.5, 0.2, 0.1, 0.15, 0.05])
    s = np.repeat(s, rng.integers(1, 30, n))[:n]  # runs of many lengths
    eligible = rng.random(n) > 0.15
    activity = rng.uniform(0.0, 2.0, n)
    activity[rng.random(n) < 0.02] = np.nan
    rate = np.minimum(rng.uniform(1.0, 5.0, n), 3.0)  # "rate of 1": Σ Δt meets the holds on grid times
    return t, s, eligible, activity, rate


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("kind", ["time", "activity", "rate", "rate+activity", "rate of 1"])
def test_announce_matches_the_run_by_run_definition_whole_and_chunked(seed: int, kind: str) -> None:
    t, s, eligible, activity, rate = persistence_inputs(seed, 4000)
    rule = PersistenceRule(
        default_announce_s=0.2,
        clear_s=0.3,
        announce_s=(("F2.1", 0.05),),
        announce_per_activity_s=(("F4.1", 0.4), ("NORMAL", 0.1)) if "activity" in kind else (),
    )
    kwargs = {
        "max_gap_s": 1.0,
        "hold_per_activity_s": rule.hold_per_activity_s(),
        "activity": activity if "activity" in kind else None,
        "rate": (np.ones(t.size) if kind == "rate of 1" else rate) if "rate" in kind else None,
    }
    want, want_carry = announce_per_run(rule.hold_s(), t, s, eligible, **kwargs)
    got, got_carry = announce(rule.hold_s(), t, s, eligible, **kwargs)
    np.testing.assert_array_equal(got, want)
    assert got_carry == want_carry
    rng = np.random.default_rng(seed)
    carry, parts = PersistenceCarry(), []
    ref_carry, ref_parts = PersistenceCarry(), []
    for part in chunks(t.size, rng):
        sub = {
            k: (v[part] if isinstance(v, np.ndarray) and v.size == t.size else v) for k, v in kwargs.items()
        }
        out, carry = announce(rule.hold_s(), t[part], s[part], eligible[part], carry, **sub)
        ref, ref_carry = announce_per_run(rule.hold_s(), t[part], s[part], eligible[part], ref_carry, **sub)
        parts.append(out)
        ref_parts.append(ref)
        assert carry == ref_carry
    np.testing.assert_array_equal(np.concatenate(parts), np.concatenate(ref_parts))


# -- the bands, in one call ------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["flight", "flight_dynamic", "testbed"])
def test_bands_in_one_call_are_the_three_bands(name: str) -> None:
    from mav_motor_health.config import load_profile

    profile = load_profile(name)
    rng = np.random.default_rng(2)
    v = rng.uniform(2.0, 12.0, 500)
    activity = rng.uniform(0.0, 1.5, 500)
    activity[::17] = np.nan
    for act in (activity, None):
        speed, above, below = profile.bands(v, act)
        np.testing.assert_array_equal(
            np.broadcast_to(speed, v.shape), np.broadcast_to(profile.speed_band(act), v.shape)
        )
        np.testing.assert_array_equal(above, profile.current_halfwidth_a(v, act))
        np.testing.assert_array_equal(below, profile.current_halfwidth_a(v, act, below=True))
