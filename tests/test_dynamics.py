"""The first-order response: exact steps on irregular samples, vectorised = looped = streamed."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mav_motor_health.model import MotorParams
from mav_motor_health.model.dynamics import first_order_response, time_constant_s


def looped(t, x, tau):
    y = np.empty(len(t))
    for n in range(len(t)):
        if n == 0:
            y[n] = x[n]
            continue
        a = np.exp(-(t[n] - t[n - 1]) / tau[n])
        y[n] = a * y[n - 1] + (1 - a) * 0.5 * (x[n - 1] + x[n])
    return y


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 3000))
def test_vectorised_equals_loop_and_streaming(seed, n) -> None:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.001, 0.2, n))
    x = 500 + np.cumsum(rng.normal(0, 20, n))
    tau = rng.uniform(0.002, 0.3, n)
    y, carry = first_order_response(t, x, tau)
    np.testing.assert_allclose(y, looped(t, x, tau), rtol=1e-9, atol=1e-9)
    cut = n // 3
    a, c = first_order_response(t[:cut], x[:cut], tau[:cut])
    b, _ = first_order_response(t[cut:], x[cut:], tau[cut:], c)
    np.testing.assert_allclose(np.concatenate([a, b]), y, rtol=1e-9, atol=1e-9)
    assert carry.output == pytest.approx(y[-1])


def test_step_response_reaches_63_percent_after_one_time_constant() -> None:
    t = np.arange(0, 1.0, 0.001)
    x = np.where(t < 0.1, 0.0, 1.0)
    y, _ = first_order_response(t, x, 0.05)
    assert y[np.searchsorted(t, 0.15)] == pytest.approx(1 - np.exp(-1), abs=0.02)


def test_long_series_does_not_underflow() -> None:
    t = np.arange(0, 3600, 0.02)  # an hour at 50 Hz, ~2.4e6 time constants
    x = np.sin(t)
    y, _ = first_order_response(t, x, 0.01)
    assert np.all(np.isfinite(y)) and np.max(np.abs(y - x)) < 0.05


def test_missing_input_holds_and_no_inertia_means_no_lag() -> None:
    t = np.arange(5) * 0.1
    y, _ = first_order_response(t, [1.0, 2.0, np.nan, np.nan, 2.0], 0.1)
    assert y[2] == y[3] == y[1]
    y2, _ = first_order_response(t, [1.0, 2.0, 3.0, 4.0, 5.0], np.nan)
    np.testing.assert_allclose(y2, [1, 2, 3, 4, 5])


def test_time_constant_of_the_paper_motor(paper_motor: MotorParams) -> None:
    tau = time_constant_s(paper_motor, [0.0, 600.0])
    # J / (k_e²/R + B) at rest, stiffer (faster) at speed
    assert tau[0] == pytest.approx(paper_motor.J_kg_m2 / (0.00975**2 / 0.165 + 1.275e-7), rel=1e-6)
    assert 0.01 < tau[1] < tau[0]
    assert np.isnan(time_constant_s(paper_motor.replace(J_kg_m2=None), 100.0))


def test_undefined_start_recovers_at_the_first_finite_target() -> None:
    t = np.arange(6) * 0.1
    y, carry = first_order_response(t[:2], [np.nan, np.nan], 0.1)
    assert np.isnan(y).all()
    y2, _ = first_order_response(t[2:], [5.0, 5.0, 6.0, 6.0], 0.1, carry)
    assert y2[0] == 5.0 and y2[1] == 5.0 and 5.0 < y2[2] < 6.0


def test_small_batches_follow_the_same_recurrence_as_whole_logs() -> None:
    """The live agent's few-sample calls run the recurrence as a loop; it must match the block form."""
    import mav_motor_health.model.dynamics as dyn

    rng = np.random.default_rng(1)
    for trial in range(100):
        n = int(rng.integers(1, 40))
        t = np.cumsum(rng.exponential(0.03, n))
        t[rng.random(n) < 0.05] += 50.0  # gaps
        x = rng.normal(0.0, 1.0, n)
        x[rng.random(n) < 0.1] = np.nan  # lost samples
        tau = np.where(rng.random(n) < 0.1, np.nan, rng.uniform(0.01, 1.0, n))
        carry = (
            dyn.ResponseCarry(time_s=t[0] - 0.02, input=0.3, output=0.1) if trial % 2 else dyn.ResponseCarry()
        )
        loop, _ = dyn._response_scalar(t, x, tau, carry)
        # the block form, forced by padding past the loop's size with held (NaN) samples after the n
        padded, _ = dyn.first_order_response(
            np.append(t, t[-1] + 1.0 + np.arange(dyn._SCALAR_MAX)),
            np.append(x, np.full(dyn._SCALAR_MAX, np.nan)),
            np.append(tau, np.full(dyn._SCALAR_MAX, 1.0)),
            carry,
        )
        block = padded[:n]
        np.testing.assert_allclose(loop, block, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_whole_arrays_give_the_sample_by_sample_recurrence_with_gaps_resets_and_missing_values(seed) -> None:
    """The vectorised path (runs of resets at once, blocks between them) equals the plain recurrence:
    missing targets, stretches with no time constant (no lag), long gaps, an undefined start."""
    from mav_motor_health.model.dynamics import ResponseCarry, _response_scalar, first_order_response

    rng = np.random.default_rng(seed)
    n = 3000
    t = np.cumsum(rng.choice([0.01, 0.02, 0.05, 0.3], size=n, p=[0.6, 0.25, 0.1, 0.05]))
    x = rng.normal(500.0, 50.0, n)
    x[rng.random(n) < 0.1] = np.nan
    x[100:400] = np.nan  # a long silence at the start of a stretch
    tau = np.full(n, 0.15)
    tau[800:1600] = np.nan  # no inertia known here: no lag
    tau[2000:2100] = 1e-6  # a decay too strong to carry: resets
    carry = ResponseCarry() if seed % 2 else ResponseCarry(time_s=t[0] - 0.01, input=480.0, output=490.0)
    whole, end = first_order_response(t, x, tau, carry)
    one, end_one = _response_scalar(t, x, tau, carry)
    np.testing.assert_allclose(whole, one, rtol=1e-12, atol=1e-9, equal_nan=True)
    assert end.output == pytest.approx(end_one.output, rel=1e-12, nan_ok=True)
