"""The motor's first-order response, for diagnosing while the input moves (flight).

Linearising the mechanical equation J·dω/dt = k_t·i − (C_p·ω^k + B·ω + T_f) with the electrical
eq. 2 (current follows voltage at once: L/R is microseconds) around an operating point gives a first-order
lag of speed toward its steady state with the time constant

    τ(ω) = J / (k_t·k_e/R + k·C_p·ω^(k−1) + B)

(`time_constant_s`). `first_order_response` passes a steady-state prediction through that lag with an
exact step for every (irregular) sample interval, y_n = a_n·y_{n−1} + (1 − a_n)·x̄_n with
a_n = exp(−Δt_n/τ_n) and x̄_n the mean input over the interval. That is an affine recurrence
y_n = a_n·y_{n−1} + b_n (a hold is a = 1, b = 0; a restart a = 0, b = x_n), which
`affine_recurrence` evaluates over whole arrays: the samples laid out in columns, the recurrence stepped
along them for all rows at once, each row's start then taken from the row before (a product of the a's,
never an exponential that grows). Every step is the sample-by-sample one, in the same order of operations
within a row, so that a whole log, the live agent's few samples per call and one sample at a time agree to
rounding (about 1e-16 of the values); the filter carries its last output between calls.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import broadcast_to
from .params import MotorParams

__all__ = [
    "ResponseCarry",
    "affine_recurrence",
    "estimate_inertia",
    "first_order_response",
    "first_order_responses",
    "last_of",
    "marked_before",
    "previous",
    "time_constant_s",
]

FloatArray = NDArray[np.float64]

#: A step whose Δt/τ reaches this restarts at the target: exp(−600) of the past is below any rounding.
_RESTART_DECAY = 600.0
#: Up to this many values (samples × rows: the live agent's small batches) the recurrence runs as a plain
#: loop: numpy's per-call overhead would cost more than the arithmetic.
_SCALAR_MAX = 16


def time_constant_s(params: MotorParams, omega_rad_s: ArrayLike) -> FloatArray:
    """Mechanical time constant [s] at each speed; NaN where the motor has no inertia given."""
    w = np.abs(np.asarray(omega_rad_s, dtype=float))
    if params.J_kg_m2 is None:
        return np.full(w.shape, np.nan)
    stiffness = params.k_t * params.k_e / params.R_ohm + params.B
    stiffness = stiffness + params.k * params.C_p * np.power(w, params.k - 1.0)
    return params.J_kg_m2 / stiffness


class ResponseCarry(NamedTuple):
    """Last time, input and output of the filter (NaN before the first sample).

    A named tuple, not a frozen dataclass: the live agent's core call builds about a hundred of these
    (every low-pass of every motor), and a tuple is built in about half the time (no ``__init__`` setting
    each field through ``object.__setattr__``)."""

    time_s: float = float("nan")
    input: float = float("nan")
    output: float = float("nan")


#: the carry before the first sample
_NO_SAMPLE = ResponseCarry()


def first_order_response(
    time_s: ArrayLike, target: ArrayLike, tau_s: ArrayLike, carry: ResponseCarry = _NO_SAMPLE
) -> tuple[FloatArray, ResponseCarry]:
    """The target passed through a first-order lag with time constant ``tau_s`` (per sample).

    The first sample ever (no carry), and the first finite target after an undefined output, start at
    the target. NaN targets hold the previous output; a NaN time constant means no lag (output = target).

    The carry keeps the last *finite* target: a call that ends on a NaN target hands the next call an
    older input, which its first interval averages with, where one call over both would take the new
    target alone. Split right after a lost sample, calls so differ from one whole call in how that one
    interval's input is averaged (enough to move a state on a band's edge for a sample or two).
    """
    x = np.asarray(target, dtype=float)
    out, (new,) = first_order_responses(time_s, x.reshape(1, -1), tau_s, (carry,))
    return out[0], new


def first_order_responses(
    time_s: ArrayLike,
    targets: ArrayLike,
    tau_s: ArrayLike,
    carries: Sequence[ResponseCarry],
    lengths: Sequence[int] | NDArray[np.integer] | None = None,
) -> tuple[FloatArray, list[ResponseCarry]]:
    """:func:`first_order_response` of several targets at once, one per row, each with its own carry.

    ``time_s`` is one row shared by all targets, or T rows: several motors, target row j at the times
    of row j mod T (so that the targets of several quantities of T motors, stacked quantity by quantity,
    share their motors' times); ``tau_s`` is a number, one row, T rows, one row per target, or one
    number per target (a column). Intervals and decays are worked out once per distinct row.

    ``lengths`` gives each row's number of samples when the rows are of different lengths (the rest of a
    row is padding after its samples, which cannot change them: the recurrence looks back only); a row's
    carry is taken at its last sample. The results are those of one :func:`first_order_response` per row.
    """
    carries = list(carries)
    rows = len(carries)
    t = np.asarray(time_s, dtype=float)
    n = t.shape[-1]
    if n == 0:
        return np.zeros((rows, 0)), carries
    t = t.reshape(-1, n)
    x = np.asarray(targets, dtype=float).reshape(rows, n)
    tau = np.asarray(tau_s, dtype=float)
    tau = broadcast_to(tau, (1, n)) if tau.ndim < 2 else broadcast_to(tau, (tau.shape[0], n))
    counts = [n] * rows if lengths is None else [int(k) for k in lengths]
    if rows * n <= _SCALAR_MAX:
        return _responses_scalar(t, x, tau, carries, counts)
    # Rows come in groups that share the times (row j: times t[j mod T]) and maybe the time constants:
    # the decays are worked out once per distinct pair
    times = t.shape[0]
    groups = rows // times
    if groups * times != rows or tau.shape[0] not in (1, times, rows):
        raise ValueError(f"{rows} targets for {times} rows of times and {tau.shape[0]} of time constants")
    tau3 = tau.reshape(groups if tau.shape[0] == rows and rows > times else 1, -1, n)
    carried = np.array(carries, dtype=float).reshape(rows, 3)
    carry_t = carried[:, 0].reshape(groups, times)
    carry_x, carry_y = carried[:, 1], carried[:, 2]
    # The decay of each interval, Δt/τ: the first from each row's carried time
    gaps = np.empty(t.shape)
    gaps[:, 0] = 0.0  # (replaced below by the carried time's)
    np.subtract(t[:, 1:], t[:, :-1], out=gaps[:, 1:])
    # (np.maximum(·, 0), not np.clip: the same values, NaN and signed zeros included, without np.clip's
    # layers of Python; the live agent's calls are a few samples, where those layers are the cost)
    np.maximum(gaps, 0.0, out=gaps)
    first_gap = np.maximum(t[:, 0] - carry_t, 0.0)
    if _lagging(tau3):
        decay_all = gaps / tau3
        first_decay = first_gap / tau3[:, :, 0]
        decay = decay_all[..., 1:]
    else:
        first_decay = _decay(first_gap, tau3[:, :, 0])
        decay = _decay(gaps[:, 1:], tau3[:, :, 1:])
    if times == 1:
        out = _responses_one_time_row(
            x, carries, carry_x, carry_y, first_decay.reshape(rows), decay.reshape(-1, n - 1)
        )
        return out, _carries_at_last(t, x, out, carries, counts)
    a3 = np.empty((groups, times, n))
    with np.errstate(invalid="ignore"):
        a3[:, :, 0] = np.exp(-first_decay)
        a3[:, :, 1:] = np.exp(-decay)
    lagged3 = np.empty((groups, times, n), dtype=bool)
    lagged3[:, :, 0] = first_decay < _RESTART_DECAY
    lagged3[:, :, 1:] = decay < _RESTART_DECAY
    a, lagged = a3.reshape(rows, n), lagged3.reshape(rows, n)
    finite = np.isfinite(x)
    all_finite = bool(finite.all())
    prev_x = np.empty((rows, n))
    prev_x[:, 0] = carry_x
    prev_x[:, 1:] = x[:, :-1]
    if all_finite and np.isfinite(carry_x).all():
        mean_in = 0.5 * (prev_x + x)
    else:
        mean_in = np.where(np.isfinite(prev_x), 0.5 * (prev_x + x), x)
    if not all_finite:
        a[~finite] = 1.0  # a missing input holds the output: a = 1, b = 0
    # a restart (no lag, or no previous sample) gives the target itself: a = 0, b = x
    restart = None if lagged.all() else finite & ~lagged
    if restart is not None:
        a[restart] = 0.0
    b = (1.0 - a) * mean_in
    if not all_finite:
        b[~finite] = 0.0
    if restart is not None:
        b[restart] = x[restart]
    if np.isfinite(carry_y).all():  # every row under way (the common case)
        out = affine_recurrence(a, b, carry_y)
        return out, _carries_at_last(t, x, out, carries, counts)
    y0 = carry_y.copy()
    first = np.zeros(rows, dtype=np.int64)
    for r in np.flatnonzero(~np.isfinite(carry_y)).tolist():
        # no output yet: undefined until the first finite target, which starts it
        first[r] = int(np.argmax(finite[r])) if finite[r].any() else n
        if first[r] < n:
            a[r, first[r]], b[r, first[r]] = 0.0, x[r, first[r]]
        y0[r] = 0.0
    out = affine_recurrence(a, b, y0)
    for r in np.flatnonzero(first).tolist():
        out[r, : first[r]] = carries[r].output
    return out, _carries_at_last(t, x, out, carries, counts)


def _responses_one_time_row(
    x: FloatArray,
    carries: Sequence[ResponseCarry],
    carry_x: FloatArray,
    carry_y: FloatArray,
    first_decay: FloatArray,
    decay: FloatArray,
) -> FloatArray:
    """:func:`first_order_responses`' recurrence for targets that share one row of times: the same a's
    and b's, formed with fewer passes over the samples, and the a's of all rows one array where they agree
    (every target finite, one row of time constants). ``decay``: the intervals' decays (one row, or one
    per target); ``first_decay``: each target's first, from its carried time."""
    rows, n = x.shape
    with np.errstate(invalid="ignore"):
        a_first = np.exp(-first_decay)
        a_rest = np.exp(-decay)
    # a restart (no lag, or no previous sample) gives the target itself: a = 0, b = x
    restart_first = ~(first_decay < _RESTART_DECAY)
    unlagged = ~(decay < _RESTART_DECAY)
    a_rest[unlagged] = 0.0
    finite = np.isfinite(x)
    all_finite = bool(finite.all())
    new = ~np.isfinite(carry_y)  # no output yet: undefined until the first finite target, which starts it
    if all_finite:
        restart_first |= new  # the first target: each row's first
    else:
        restart_first &= finite[:, 0]
    a_first[restart_first] = 0.0
    a: FloatArray
    if all_finite and decay.shape[0] == 1 and (a_first == a_first[0]).all():
        row = np.empty(n)
        row[0], row[1:] = a_first[0], a_rest[0]
        a = broadcast_to(row, (rows, n))
        one_minus: FloatArray = 1.0 - row
    else:
        a = np.empty((rows, n))
        a[:, 0], a[:, 1:] = a_first, a_rest
        if not all_finite:
            np.copyto(a, 1.0, where=~finite)  # a missing input holds the output: a = 1, b = 0
        one_minus = 1.0 - a
    # the mean input over each interval (the first: with the carried input, if any; after a missing
    # input: the input itself)
    b = np.empty((rows, n))
    np.add(x[:, :-1], x[:, 1:], out=b[:, 1:])
    b[:, 1:] *= 0.5
    with np.errstate(invalid="ignore"):
        b[:, 0] = np.where(np.isfinite(carry_x), 0.5 * (carry_x + x[:, 0]), x[:, 0])
    if not all_finite:
        np.copyto(b[:, 1:], x[:, 1:], where=~finite[:, :-1])
    b *= one_minus
    if not all_finite:
        np.copyto(b, 0.0, where=~finite)
    b[restart_first, 0] = x[restart_first, 0]
    columns = np.flatnonzero(unlagged.any(axis=0))
    if columns.size:
        at = columns + 1
        restart = broadcast_to(unlagged[:, columns], (rows, columns.size)) & finite[:, at]
        b[:, at] = np.where(restart, x[:, at], b[:, at])
    y0 = np.where(new, 0.0, carry_y)
    first = np.zeros(rows, dtype=np.int64)
    if not all_finite:
        for r in np.flatnonzero(new).tolist():
            first[r] = int(np.argmax(finite[r])) if finite[r].any() else n
            if first[r] < n:
                a[r, first[r]], b[r, first[r]] = 0.0, x[r, first[r]]
    out = affine_recurrence(a, b, y0)
    for r in np.flatnonzero(first).tolist():
        out[r, : first[r]] = carries[r].output
    return out


def _carries_at_last(
    t: FloatArray, x: FloatArray, out: FloatArray, carries: Sequence[ResponseCarry], counts: Sequence[int]
) -> list[ResponseCarry]:
    """Each row's carry at its last sample (a row without samples keeps its own)."""
    rows, times = len(carries), t.shape[0]
    n = t.shape[1]
    if all(count == n for count in counts):  # every row full: its last column
        last_times = t[:, -1].tolist() * (rows // times)
        inputs, outputs = x[:, -1].tolist(), out[:, -1].tolist()
    else:
        at = np.maximum(np.asarray(counts) - 1, 0)
        index = np.arange(rows)
        last_times = t[index % times, at].tolist()
        inputs = x[index, at].tolist()
        outputs = out[index, at].tolist()
    # the last input as it is, NaN where it was missing: the next call's first interval then averages
    # from its own input alone, as the same samples in one array do (a missing input's successor)
    if all(counts):  # (the common case: each row's own last values)
        return list(map(ResponseCarry._make, zip(last_times, inputs, outputs)))
    return [
        carry if count == 0 else ResponseCarry(time, value, output)
        for carry, count, time, value, output in zip(carries, counts, last_times, inputs, outputs)
    ]


def _lagging(tau: FloatArray) -> bool:
    """Whether every time constant is finite and positive (so that every decay is Δt/τ)."""
    with np.errstate(invalid="ignore"):
        return bool((tau > 0).all() and np.isfinite(tau).all())


def _decay(dt: FloatArray, tau: FloatArray) -> FloatArray:
    """Δt/τ per interval; infinite or NaN (both: a restart) without a lag (τ not finite and positive) or
    without a previous sample (Δt not finite)."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if np.all(np.isfinite(tau) & (tau > 0)):
            return dt / tau
        return np.where(np.isfinite(tau) & (tau > 0), dt / np.where(tau > 0, tau, 1.0), np.inf)


def previous(values: ArrayLike, carried: ArrayLike) -> FloatArray:
    """Each row's previous sample at every sample (rows of samples, 2-D): the carried one first."""
    v = np.asarray(values, dtype=float)
    out = np.empty(v.shape)
    out[:, 0] = carried
    out[:, 1:] = v[:, :-1]
    return out


def marked_before(
    time_s: FloatArray, marked: NDArray[np.bool_], carried_s: ArrayLike
) -> tuple[NDArray[np.intp], NDArray[np.intp], FloatArray]:
    """For rows of samples (2-D) and the samples ``marked`` in them: each sample's latest marked sample
    at or before it and the latest strictly before it (-1: none in the rows yet), and that one's time
    (the row's ``carried_s`` where there is none: the last marked time of the calls before)."""
    latest, before = latest_marked(marked)
    time_before = np.where(
        before >= 0,
        np.take_along_axis(time_s, np.maximum(before, 0), axis=1),
        np.asarray(carried_s, dtype=float)[:, None],
    )
    return latest, before, time_before


def latest_marked(marked: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """For rows of samples (2-D): each sample's latest ``marked`` sample at or before it, and the latest
    strictly before it (-1: none in the rows yet)."""
    latest = np.maximum.accumulate(np.where(marked, np.arange(marked.shape[1])[None, :], -1), axis=1)
    return latest, previous(latest, -1).astype(np.intp)


def last_of(values: NDArray, lengths: Sequence[int] | NDArray[np.integer]) -> list:
    """Each row's value at its last sample (rows of ``lengths`` samples, then padding), as Python values;
    None for a row without samples."""
    values = np.asarray(values)
    n = values.shape[-1]
    if all(count == n for count in lengths) and n > 0:  # every row full: its last column
        last: list = values[:, -1].tolist()
        return last
    rows = np.arange(len(lengths))
    at = np.maximum(np.asarray(lengths, dtype=np.int64) - 1, 0)
    picked = values[rows, at].tolist()
    return [value if count > 0 else None for value, count in zip(picked, lengths)]


#: columns of :func:`affine_recurrence`'s layout (samples stepped per numpy call: rows × this)
_COLUMNS = 64
#: up to this many values in all, and this many series, the recurrence runs as a plain loop: a step of
#: the loop over columns is three numpy calls for all series, a step of the plain loop a multiply-add
#: in Python for one value (the same two roundings), about a tenth of that
_LOOP_MAX = 256
_LOOP_SERIES = 8


def affine_recurrence(a: ArrayLike, b: ArrayLike, y0: ArrayLike) -> FloatArray:
    """``y_k = a_k·y_(k−1) + b_k`` along a 1-D array or each row of a 2-D one, from ``y_(−1) = y0`` (one
    per row); all finite.

    Short arrays step sample by sample. Longer ones are laid out as rows of :data:`_COLUMNS` samples
    and stepped along the columns for all rows at once, each row started from 0; its true start, the
    previous row's end, follows from the same recurrence over the rows' ends (this function again) and
    enters each sample times the product of the a's since the row began. Within a row the operations are
    the sample-by-sample ones; the start's share is added last (a difference of rounding only). The
    products only shrink (0 ≤ a ≤ 1 in the filter), so nothing grows or overflows.
    """
    a_in = np.asarray(a, dtype=float)
    a2 = a_in.reshape(1, -1) if a_in.ndim == 1 else a_in
    b2 = np.asarray(b, dtype=float).reshape(a2.shape)
    series, n = a2.shape
    start = broadcast_to(np.asarray(y0, dtype=float), (series,))
    if n <= 2 * _COLUMNS:
        out = np.empty((series, n))
        if series * n <= _LOOP_MAX and series <= _LOOP_SERIES:
            for r, (ar, br, y) in enumerate(zip(a2.tolist(), b2.tolist(), start.tolist())):
                row = []
                for ak, bk in zip(ar, br):
                    y = ak * y + bk
                    row.append(y)
                out[r] = row
        else:
            y_col = start.copy()
            for k in range(n):
                y_col = a2[:, k] * y_col + b2[:, k]
                out[:, k] = y_col
        return out.reshape(a_in.shape)
    rows = -(-n // _COLUMNS)
    # one series' a's where all share them (several quantities low-passed at the same times): their
    # products are worked out once, the same numbers for every series
    shared = series > 1 and (a2.strides[0] == 0 or bool((a2[1:] == a2[0]).all()))
    gain = _to_columns(a2[:1] if shared else a2, rows, 1.0)
    local = _to_columns(b2, rows, 0.0)
    gain3 = gain.reshape(_COLUMNS, -1, rows)  # (columns, 1 or series, rows)
    local3 = local.reshape(_COLUMNS, series, rows)
    scratch = np.empty((series, rows))
    for j in range(1, _COLUMNS):
        np.multiply(gain3[j], local3[j - 1], out=scratch)
        local3[j] += scratch
        gain3[j] *= gain3[j - 1]  # the product of the a's since each row began
    ends = affine_recurrence(broadcast_to(gain3[-1], (series, rows)), local3[-1], start)
    starts = np.empty((series, rows))
    starts[:, 0] = start
    starts[:, 1:] = ends[:, :-1]
    for j in range(_COLUMNS):  # the start's share, column by column
        np.multiply(gain3[j], starts, out=scratch)
        local3[j] += scratch
    return _from_columns(local, series, n).reshape(a_in.shape)


#: rows of :func:`affine_recurrence`'s layout moved at a time (a few hundred kB: the moves stay in cache)
_MOVE_ROWS = 512


def _to_columns(values: FloatArray, rows: int, pad: float) -> FloatArray:
    """``values`` (series × n) as :func:`affine_recurrence` steps them: ``rows`` rows of :data:`_COLUMNS`
    samples per series (the last padded with ``pad``), column j of every row of every series one
    contiguous vector: (columns, series × rows)."""
    series, n = values.shape
    out = np.empty((_COLUMNS, series, rows))
    full = n // _COLUMNS
    blocks = values[:, : full * _COLUMNS].reshape(series, full, _COLUMNS)
    for s in range(series):
        for r in range(0, full, _MOVE_ROWS):
            end = min(r + _MOVE_ROWS, full)
            out[:, s, r:end] = blocks[s, r:end].T
    if full < rows:  # the last row: the rest of the samples, then padding
        rest = n - full * _COLUMNS
        out[:rest, :, full] = values[:, full * _COLUMNS :].T
        out[rest:, :, full] = pad
    return out.reshape(_COLUMNS, series * rows)


def _from_columns(columns: FloatArray, series: int, n: int) -> FloatArray:
    """:func:`_to_columns` undone: the first ``n`` samples of each series (series × n)."""
    rows = columns.shape[1] // series
    by_row = columns.reshape(_COLUMNS, series, rows)
    out = np.empty((series, n))
    full = n // _COLUMNS
    blocks = out[:, : full * _COLUMNS].reshape(series, full, _COLUMNS)
    for s in range(series):
        for r in range(0, full, _MOVE_ROWS):
            end = min(r + _MOVE_ROWS, full)
            blocks[s, r:end] = by_row[:, s, r:end].T
    if full < rows:
        out[:, full * _COLUMNS :] = by_row[: n - full * _COLUMNS, :, full].T
    return out


def _response_scalar(
    t: FloatArray, x: FloatArray, tau: FloatArray, carry: ResponseCarry
) -> tuple[FloatArray, ResponseCarry]:
    """:func:`first_order_response` for a few samples, sample by sample (the recurrence's definition)."""
    tau_row = broadcast_to(tau, t.shape).reshape(1, -1)
    out, (new,) = _responses_scalar(t.reshape(1, -1), x.reshape(1, -1), tau_row, (carry,), [t.size])
    return out[0], new


def _responses_scalar(
    t: FloatArray, x: FloatArray, tau: FloatArray, carries: Sequence[ResponseCarry], counts: Sequence[int]
) -> tuple[FloatArray, list[ResponseCarry]]:
    """:func:`first_order_responses` for a few samples: the same recurrence, sample by sample."""
    out = np.full(x.shape, np.nan)
    news = []
    times, taus = t.tolist(), tau.tolist()
    for r, (row, carry, count) in enumerate(zip(x.tolist(), carries, counts)):
        if count == 0:
            news.append(carry)
            continue
        y, prev_t, prev_x = carry.output, carry.time_s, carry.input
        row_t = times[r % len(times)][:count]  # the rows' times and time constants repeat (see above)
        row_tau = taus[r % len(taus)][:count]
        values = out[r]
        # each interval's decay (the times' alone: the previous time is the previous sample's, whatever
        # its input), all exponentials in one numpy call: numpy's exp, as the vectorised path's (libm's
        # differs from numpy's SIMD exp in the last bit for some arguments on some processors, AVX-512,
        # and the paths must agree)
        decays = []
        for tk, tau_k in zip(row_t, row_tau):
            dt = max(tk - prev_t, 0.0) if math.isfinite(tk - prev_t) else math.inf
            decays.append(dt / tau_k if math.isfinite(tau_k) and tau_k > 0 else math.inf)
            prev_t = tk
        factors = np.exp(np.negative(decays)).tolist()
        for k, (xk, decay, a) in enumerate(zip(row[:count], decays, factors)):
            if not math.isfinite(xk):
                pass  # a missing input: the output holds
            elif not math.isfinite(decay) or decay >= _RESTART_DECAY or not math.isfinite(y):
                y = xk  # no lag (or no past): the target itself
            else:
                mean_in = 0.5 * (prev_x + xk) if math.isfinite(prev_x) else xk
                y = a * y + (1.0 - a) * mean_in
            values[k] = y
            prev_x = xk
        last = row[count - 1]
        news.append(
            ResponseCarry(
                time_s=row_t[-1],
                input=last,
                output=float(y),  # (a missing last input: NaN, see above)
            )
        )
    return out, news


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
