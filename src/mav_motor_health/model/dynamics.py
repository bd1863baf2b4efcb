"""The motor's first-order response, for diagnosing while the input moves (flight).

Linearising the mechanical equation J·dω/dt = k_t·i − (C_p·ω^k + B·ω + T_f) with the electrical
eq. 2 (current follows voltage at once: L/R is microseconds) around an operating point gives a first-order
lag of speed toward its steady state with the time constant

    τ(ω) = J / (k_t·k_e/R + k·C_p·ω^(k−1) + B)

(`time_constant_s`). `first_order_response` passes a steady-state prediction through that lag with an
exact step for every (irregular) sample interval, y_n = a_n·y_{n−1} + (1 − a_n)·x̄_n with
a_n = exp(−Δt_n/τ_n) and x̄_n the mean input over the interval. It is evaluated in closed form over blocks
(cumulative sums in log space) so that whole logs run vectorised, and it carries its last output, so that
the live agent feeding one sample at a time gets the very same numbers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .params import MotorParams

__all__ = ["ResponseCarry", "estimate_inertia", "first_order_response", "time_constant_s"]

FloatArray = NDArray[np.float64]

#: Sum of Δt/τ after which a block is closed (exp(−600) is still a normal float64).
_BLOCK_DECAY = 600.0
#: Up to this many samples (the live agent's small batches) the recurrence runs as a plain loop: numpy's
#: per-call overhead would cost more than the arithmetic.
_SCALAR_MAX = 16


def time_constant_s(params: MotorParams, omega_rad_s: ArrayLike) -> FloatArray:
    """Mechanical time constant [s] at each speed; NaN where the motor has no inertia given."""
    w = np.abs(np.asarray(omega_rad_s, dtype=float))
    if params.J_kg_m2 is None:
        return np.full(w.shape, np.nan)
    stiffness = params.k_t * params.k_e / params.R_ohm + params.B
    stiffness = stiffness + params.k * params.C_p * np.power(w, params.k - 1.0)
    return params.J_kg_m2 / stiffness


@dataclass(frozen=True)
class ResponseCarry:
    """Last time, input and output of the filter (NaN before the first sample)."""

    time_s: float = float("nan")
    input: float = float("nan")
    output: float = float("nan")


def first_order_response(
    time_s: ArrayLike, target: ArrayLike, tau_s: ArrayLike, carry: ResponseCarry = ResponseCarry()
) -> tuple[FloatArray, ResponseCarry]:
    """The target passed through a first-order lag with time constant ``tau_s`` (per sample).

    The first sample ever (no carry), and the first finite target after an undefined output, start at
    the target. NaN targets hold the previous output; a NaN time constant means no lag (output = target).
    """
    t = np.asarray(time_s, dtype=float)
    x = np.asarray(target, dtype=float)
    tau = np.broadcast_to(np.asarray(tau_s, dtype=float), t.shape)
    n = t.size
    if n == 0:
        return np.zeros(0), carry
    if n <= _SCALAR_MAX:
        return _response_scalar(t, x, tau, carry)
    prev_t = np.concatenate([[carry.time_s], t[:-1]])
    prev_x = np.concatenate([[carry.input], x[:-1]])
    dt = np.clip(t - prev_t, 0.0, None)
    decay = np.where(np.isfinite(tau) & (tau > 0), dt / np.where(tau > 0, tau, 1.0), np.inf)
    decay = np.where(np.isfinite(dt), decay, np.inf)  # no previous sample: jump to the target
    mean_in = np.where(np.isfinite(prev_x), 0.5 * (prev_x + x), x)
    held = ~np.isfinite(x)
    mean_in = np.where(held, np.nan, mean_in)
    decay = np.where(held, 0.0, decay)  # a missing input: the output holds
    out = np.empty(n)
    y0 = carry.output
    # A reset (no lag, or no previous sample) gives the target itself, held where the target is missing.
    reset = ~np.isfinite(decay) | (decay >= _BLOCK_DECAY)
    reset_at = np.flatnonzero(reset)
    lagged_at = np.flatnonzero(~reset)
    finite_at = np.flatnonzero(np.isfinite(x))
    cum = np.cumsum(np.where(reset, 0.0, decay))
    start = 0
    while start < n:
        if reset[start]:
            # a run of resets, all at once: the targets, the last finite one held over missing ones
            k = int(np.searchsorted(lagged_at, start))
            stop = int(lagged_at[k]) if k < lagged_at.size else n
            values = x[start:stop]
            last = np.maximum.accumulate(np.where(np.isfinite(values), np.arange(values.size), -1))
            out[start:stop] = np.where(last >= 0, values[np.maximum(last, 0)], y0)
            y0 = float(out[stop - 1])
            start = stop
            continue
        k = int(np.searchsorted(reset_at, start))
        next_reset = int(reset_at[k]) if k < reset_at.size else n
        if not np.isfinite(y0):
            # no output yet: undefined until the first finite target, which starts it
            k = int(np.searchsorted(finite_at, start))
            first = int(finite_at[k]) if k < finite_at.size else n
            first = min(first, next_reset)
            out[start:first] = y0
            if first < next_reset:
                y0 = float(x[first])
                out[first] = y0
                first += 1
            start = first
            continue
        # a block: until the next reset, or where the accumulated decay would underflow
        base = cum[start - 1] if start else 0.0
        end = int(np.searchsorted(cum, base + _BLOCK_DECAY, side="right"))
        end = min(max(end, start + 1), next_reset)
        d = decay[start:end]
        a = np.exp(-d)
        log_a = -np.cumsum(d)  # log of the product of a over the block
        weights = (1.0 - a) * np.nan_to_num(mean_in[start:end]) * np.exp(-log_a)
        block = np.exp(log_a) * (y0 + np.cumsum(weights))
        out[start:end] = block
        y0 = float(block[-1])
        start = end
    last_input = x[-1] if np.isfinite(x[-1]) else carry.input
    return out, ResponseCarry(time_s=float(t[-1]), input=float(last_input), output=float(out[-1]))


def _response_scalar(
    t: FloatArray, x: FloatArray, tau: FloatArray, carry: ResponseCarry
) -> tuple[FloatArray, ResponseCarry]:
    """:func:`first_order_response` for a few samples: the same recurrence, sample by sample."""
    out = np.empty(t.size)
    y, prev_t, prev_x = carry.output, carry.time_s, carry.input
    for k, (tk, xk, tau_k) in enumerate(zip(t.tolist(), x.tolist(), tau.tolist())):
        dt = max(tk - prev_t, 0.0) if math.isfinite(tk - prev_t) else math.inf
        decay = dt / tau_k if math.isfinite(tau_k) and tau_k > 0 else math.inf
        if not math.isfinite(xk):
            pass  # a missing input: the output holds
        elif not math.isfinite(decay) or decay >= _BLOCK_DECAY or not math.isfinite(y):
            y = xk  # no lag (or no past): the target itself
        else:
            mean_in = 0.5 * (prev_x + xk) if math.isfinite(prev_x) else xk
            a = math.exp(-decay)
            y = a * y + (1.0 - a) * mean_in
        out[k] = y
        prev_t, prev_x = tk, xk
    last_input = x[-1] if np.isfinite(x[-1]) else carry.input
    return out, ResponseCarry(time_s=float(t[-1]), input=float(last_input), output=float(out[-1]))


def estimate_inertia(
    params: MotorParams,
    runs: Sequence[tuple[ArrayLike, ArrayLike, ArrayLike]],
    candidates_kg_m2: ArrayLike | None = None,
) -> float | None:
    """The rotor + propeller inertia that best explains how speed follows a moving input.

    ``runs`` are (time_s, voltage_v, omega_rad_s) series (one per motor or flight). Each candidate J,
    and "no lag" (None), is scored by the mean squared error between the measured speed and the
    steady-state speed passed through the first-order response (squared, so that the transients, where
    J matters, weigh); the best is returned. A grid search
    in log space: the error is not smooth in J where telemetry is quantised.
    """
    from .equations import steady_state

    grid = (
        np.geomspace(1e-7, 1e-3, 25)
        if candidates_kg_m2 is None
        else np.asarray(candidates_kg_m2, dtype=float)
    )
    prepared = []
    for t, v, w in runs:
        t, v, w = (np.asarray(x, dtype=float) for x in (t, v, w))
        prepared.append((t, steady_state(params, v).omega_rad_s, w))
    best: tuple[float, float | None] = (np.inf, None)
    for inertia in [None, *grid.tolist()]:
        trial = params.replace(J_kg_m2=inertia)
        errors = []
        for t, w_ss, w in prepared:
            pred, _ = first_order_response(t, w_ss, time_constant_s(trial, w_ss))
            errors.append((pred - w) ** 2)
        error = float(np.nanmean(np.concatenate(errors)))
        if error < best[0]:
            best = (error, inertia)
    return best[1]
