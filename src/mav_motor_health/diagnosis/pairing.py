"""How far a log's pairing of ESC samples with motor commands can move the balance rule, per sample.

A log gives each ESC sample the motor command of another moment than the sample's: a ``.tlog`` the ESC's
last packet beside the command of the message's moment, a ``.bin`` the latest RCOU record; the live agent
reads the same messages as a ``.tlog``. Each sample's *pairing uncertainty* ``u_i`` says how far apart the
two can be (the table's and the live samples' ``pairing_s``, worked out causally by the same code for
both, :mod:`..telemetry.assemble`: the held command's age or, if more, the interval of the motor's ESC
messages where the sample is stamped by its message). Over that time the command moves by about its
rate of change times ``u_i``, so the voltage of sample ``i`` can be off by ``|ΔV/Δt|·u_i``. The balance
rule judges *low-passed* deviations, which carry the voltage errors of the samples the low-pass remembers;
their error is taken as

    u = low-pass(|ΔV/Δt|) · U_i,    U_i = 95th percentile of (u_j : t_i − W ≤ t_j ≤ t_i),    W = 1 s

(low-passed as the balances are): the loosest pairing of the last second but the 5 % loosest
(:data:`PAIRING_WINDOW_S`, :data:`PAIRING_SHARE`; the smallest ``u_j`` that 95 % of the window's do not
exceed). That is the whole-log number the guard was first written with (the 95th percentile of the held
command's age, or a .tlog's message interval), taken over the last second instead of the whole log: causal,
the same for replay and the live agent, and equal to ``u`` where all samples have one ``u`` (the rule as
it was for one number). Why not each sample's own ``u_i``, nor a low-pass of ``|ΔV/Δt|·u_i``: a command
stream pairs its samples with ages from 0 (just after a command) to its period (just before the next), so
the low-passed deviation always holds samples paired that loosely, and the bands' shares below were
chosen against the stream's loosest pairing. Measured on the simulator's logs (issue 18), weighing the
low-pass of ``|ΔV/Δt|·u_i`` (about the mean pairing, half the loosest) let back the false announcements
the guard is for (``sitl_logs/flight_healthy_long.tlog``: 17 fault or UNKNOWN announcements → 205;
``flight_F4.1_moderate.bin``: none → 23). Why not the window's largest: a live link stamps messages when
they arrive, and a stalled read makes one message look a whole stall apart from the one before; the
largest weighed that stall for a second (the simulated vehicle streaming at 100 Hz to the agent on a
loaded machine: 28 % of the samples had their current set aside in calm air, and the demo's F3.1 came
0.6–1.2 s after the damage instead of about 0.1 s). Why one second: commands older than that are not used
at all (:data:`~..telemetry.assemble.COMMAND_MAX_AGE_S`), so the window holds a whole period of any stream
that pairs, and it covers the low-pass's memory (a few ``residual_tau_s``). At 10 Hz (ten samples in a
second) the 95th percentile is the largest; at 100 Hz the sixth largest.

In the balance rule a voltage error δV moves the speed deviation by ``k_t·δV/D`` and the current deviation
by ``G·δV/D`` (:func:`~..model.balance.linearised_slopes`): the direction of an open transistor (F4.1),
which is what loosely paired logs are misread as. The *pairing error* is that speed, ``k_t·u/D``
[rad/s]; the pipeline compares it with the bands
(:attr:`~.plausibility.PlausibilityRule.pairing_current_share`, ``pairing_speed_share``): where it is a
sizeable part of the speed band the current is not used (the tree falls back to speed alone, with its
wider band), where it is a sizeable part of even that band the sample is not judged.

Where the source says how far the command went beyond the two samples' commands in between
(``input_excursion_v``, a dip and back between two ESC reports; :mod:`..telemetry.assemble`) and the
balance rule's ``excursion_pairing_weight`` w > 0 (an option, off in the shipped profiles), the input's
rate of change counts that way too: ``(|ΔV| + 2·w·e)/Δt``, the command having moved down and back.

A ``u_i`` of NaN (no command held: no voltage either) counts as none. A source that pairs each sample with
the command of its own instant (the simulator's table, a CSV with both) has no pairing error: no
``pairing_s`` (or 0 for all).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import broadcast_to, nan_to_zero
from ..model.balance import linearised_slopes
from ..model.dynamics import ResponseCarry, first_order_responses, last_of, previous
from ..model.params import MotorParams

__all__ = [
    "PAIRING_SHARE",
    "PAIRING_WINDOW_S",
    "PairingCarry",
    "loosest_pairing",
    "pairing_error_rad_s",
    "pairing_error_rows",
]

#: how far back the loosest pairing is looked for [s] (the module doc): the oldest command a source pairs
#: (``telemetry.assemble.COMMAND_MAX_AGE_S``; the core does not import the sources, a test holds the two
#: equal)
PAIRING_WINDOW_S = 1.0
#: the share of the window's pairings the weighed one covers (the module doc)
PAIRING_SHARE = 0.95

_EMPTY = np.zeros(0)


@dataclass(frozen=True)
class PairingCarry:
    """The last sample seen, the low-pass of the input's rate of change, and the pairings of the samples
    in the last :data:`PAIRING_WINDOW_S` (their times and values)."""

    time_s: float = float("nan")
    voltage_v: float = float("nan")
    rate: ResponseCarry = field(default_factory=ResponseCarry)
    recent_time_s: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)
    recent_pairing_s: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)


def loosest_pairing(
    time_s: NDArray[np.float64],
    pairing_s: NDArray[np.float64],
    carried_time_s: NDArray[np.float64] = _EMPTY,
    carried_pairing_s: NDArray[np.float64] = _EMPTY,
    window_s: float = PAIRING_WINDOW_S,
    share: float = PAIRING_SHARE,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Per sample (1-D, increasing time), the ``share`` quantile of the pairings of the samples in the last
    ``window_s`` (itself and the carried ones included; NaN counts as 0): the smallest pairing that at least
    ``share`` of them do not exceed. And what to carry: the times and pairings of the samples within
    ``window_s`` of the last one. Split anywhere, the parts give the whole's values."""
    t = np.concatenate((carried_time_s, time_s))
    u = np.concatenate((carried_pairing_s, nan_to_zero(pairing_s)))
    n, k = t.size, carried_time_s.size
    if n == 0:
        return np.zeros(0), carried_time_s, carried_pairing_s
    at = np.arange(k, n)
    start = np.minimum(np.searchsorted(t, t[k:] - window_s, side="left"), at)  # the sample itself at least
    length = at - start + 1
    # the rank from the top: 0 the largest; ceil(share·n) of n at or below the value
    rank = length - np.ceil(share * length - 1e-9).astype(np.int64)
    keep = t >= t[-1] - window_s
    if (u == u[0]).all():  # one pairing for all (a steady stream): that one
        return np.full(n - k, u[0]), t[keep], u[keep]
    widest = int(length.max())
    deepest = int(rank.max())
    if n - k <= _DIRECT_MAX or widest <= deepest + 2:
        out = _ranked_direct(u, start, at, rank, widest, deepest)
    else:
        out = _ranked_blocks(u, start, at, rank, widest, deepest)
    return out, t[keep], u[keep]


#: up to this many new samples :func:`loosest_pairing` picks each one's quantile from its whole window (the
#: live agent's few samples); more go through the blocks of :func:`_ranked_blocks`
_DIRECT_MAX = 256


def _ranked_direct(
    u: NDArray[np.float64],
    start: NDArray[np.int64],
    at: NDArray[np.int64],
    rank: NDArray[np.int64],
    widest: int,
    deepest: int,
) -> NDArray[np.float64]:
    """Per query ``q``, the ``rank[q]``-th largest (0: the largest) of ``u[start[q] : at[q] + 1]`` (at most
    ``widest`` values; ``rank`` at most ``deepest``): each window laid out whole, the largest ones picked."""
    out = np.empty(at.size)
    pad = widest - 1
    negated_u = np.concatenate((np.full(pad, np.inf), -u))
    position = np.concatenate((np.full(pad, -1, dtype=np.int64), np.arange(u.size)))
    windows = np.lib.stride_tricks.sliding_window_view(negated_u, widest)
    positions = np.lib.stride_tricks.sliding_window_view(position, widest)
    chunk = max(1, (1 << 20) // widest)
    for a in range(0, at.size, chunk):
        b = min(a + chunk, at.size)
        # each query's last ``widest`` values (oldest first), those before its window's start set last
        ends = at[a:b]
        negated = np.where(positions[ends] >= start[a:b, None], windows[ends], np.inf)
        if deepest + 1 < widest:  # the deepest+1 largest first (in any order), then sorted
            negated = np.partition(negated, deepest, axis=1)[:, : deepest + 1]
        out[a:b] = -np.sort(negated, axis=1)[np.arange(b - a), rank[a:b]]
    return out


def _ranked_blocks(
    u: NDArray[np.float64],
    start: NDArray[np.int64],
    at: NDArray[np.int64],
    rank: NDArray[np.int64],
    widest: int,
    deepest: int,
) -> NDArray[np.float64]:
    """:func:`_ranked_direct` in O(values × ranks): the values cut into blocks of ``widest``, each position
    holding the ``deepest + 1`` largest of its block up to it and from it on. A window that spans two
    blocks is the end of one and the start of the next, whose largest values merge into the window's; one
    within a block spans two of a second cut, half a block further; the few within a block of both (no
    longer than half a block) are picked whole. The values picked are the windows' own: the same numbers
    as :func:`_ranked_direct`."""
    size, keep = widest, deepest + 1
    out = np.empty(at.size)
    todo = np.arange(at.size)
    for offset in (0, size // 2):
        if todo.size == 0:
            break
        first, last = start[todo] + offset, at[todo] + offset
        spans = first // size != last // size
        if not spans.any():
            continue
        done, first, last = todo[spans], first[spans], last[spans]
        todo = todo[~spans]
        before, upto = _block_tops(u, offset, size, keep)
        blocks = before.shape[-1] // size
        tails = first % size * blocks + first // size  # the tables' columns of the window's first and last
        heads = last % size * blocks + last // size
        # the k-th largest of the window's two parts: the largest over splits (a from the tail, k − a from
        # the head) of the smaller of the tail's a-th and the head's (k − a)-th largest (the 0th: +inf)
        k = rank[done] + 1
        for kk in np.flatnonzero(np.bincount(k)).tolist():
            which = slice(None) if kk == k[0] and (k == kk).all() else np.flatnonzero(k == kk)
            tail, head = tails[which], heads[which]
            best = before[kk - 1].take(tail)  # all from the tail
            np.maximum(best, upto[kk - 1].take(head), out=best)  # all from the head
            for a in range(1, kk):
                np.maximum(best, np.minimum(before[a - 1].take(tail), upto[kk - a - 1].take(head)), out=best)
            out[done[which]] = best
    if todo.size:
        out[todo] = _ranked_direct(
            u, start[todo], at[todo], rank[todo], int((at[todo] - start[todo]).max()) + 1, deepest
        )
    return out


def _block_tops(
    u: NDArray[np.float64], offset: int, size: int, keep: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """For positions cut into blocks of ``size`` (the first ``offset`` short: position p is at p + offset),
    the ``keep`` largest values of each block from a position to its end and from its start up to the
    position: row r the (r+1)-th largest (-inf where fewer), column j·blocks + b for the j-th value of
    block b."""
    blocks = -(-(u.size + offset) // size)
    grid = np.full(blocks * size, -np.inf)
    grid[offset : offset + u.size] = u
    by_column = grid.reshape(blocks, size).T.copy()  # row j: every block's j-th value
    before = np.empty((keep, size, blocks))
    upto = np.empty((keep, size, blocks))
    smaller = np.empty(blocks)
    for tops, columns in ((upto, range(size)), (before, range(size - 1, -1, -1))):
        top = np.full((keep, blocks), -np.inf)
        for j in columns:
            x = by_column[j]
            for r in range(keep - 1, 0, -1):  # x inserted in order, the smallest dropped
                np.minimum(top[r - 1], x, out=smaller)
                np.maximum(top[r], smaller, out=top[r])
            np.maximum(top[0], x, out=top[0])
            tops[:, j] = top
    return before.reshape(keep, -1), upto.reshape(keep, -1)


#: at most this many values in :func:`_loosest_pairing_rows`' layout of every query's window (beyond: row by
#: row, through :func:`loosest_pairing`)
_ROWS_MAX_VALUES = 1 << 18


def _loosest_pairing_rows(
    time_s: NDArray[np.float64],
    pairing_s: NDArray[np.float64],
    counts: list[int],
    recent: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    window_s: float = PAIRING_WINDOW_S,
    share: float = PAIRING_SHARE,
) -> tuple[NDArray[np.float64], list[tuple[NDArray[np.float64], NDArray[np.float64]]]] | None:
    """:func:`loosest_pairing` of several rows at once (rows of ``counts`` samples, then padding; each
    row's carried times and pairings in ``recent``): each query's window picked from its row laid out
    whole, as :func:`_ranked_direct` picks it. The same numbers as row by row; None where it does not
    apply (many samples, times not finite or not increasing), which the caller then does row by row."""
    rows = len(counts)
    carried = [r_t.size for r_t, _ in recent]
    lengths = [k + c for k, c in zip(carried, counts)]
    width = max(lengths)
    queries = sum(counts)
    if queries == 0 or max(counts) > _DIRECT_MAX or queries * width > _ROWS_MAX_VALUES:
        return None
    pieces_t: list[NDArray[np.float64]] = []
    pieces_u: list[NDArray[np.float64]] = []
    for (r_t, r_u), row_t, row_u, count in zip(recent, time_s, pairing_s, counts):
        pieces_t += [r_t, row_t[:count]]
        pieces_u += [r_u, row_u[:count]]
    flat_t = np.concatenate(pieces_t)
    flat_u = nan_to_zero(np.concatenate(pieces_u))
    # row r's values at [r, :lengths[r]], padding after them (+inf times: never in a window)
    offsets = np.cumsum([0, *lengths[:-1]])
    index = np.arange(flat_t.size) + np.repeat(np.arange(rows) * width - offsets, lengths)
    t = np.full((rows, width), np.inf)
    u = np.zeros((rows, width))
    t.ravel()[index] = flat_t
    u.ravel()[index] = flat_u
    if not (np.isfinite(flat_t).all() and (t[:, 1:] >= t[:, :-1]).all()):
        return None
    # the queries: each row's new samples, after its carried ones
    query_row = np.repeat(np.arange(rows), counts)
    at = np.arange(queries) - np.repeat(np.cumsum([0, *counts[:-1]]) - carried, counts)
    # the window's first sample: the first not before t − window_s (np.searchsorted's side="left")
    start = np.minimum((t[query_row] < (t[query_row, at] - window_s)[:, None]).sum(axis=1), at)
    length = at - start + 1
    # the rank from the top: 0 the largest; ceil(share·n) of n at or below the value
    rank = length - np.ceil(share * length - 1e-9).astype(np.int64)
    column = np.arange(width)
    inside = (column >= start[:, None]) & (column <= at[:, None])
    negated = np.where(inside, -u[query_row], np.inf)
    deepest = int(rank.max())
    if deepest + 1 < width:  # the deepest+1 largest first (in any order), then sorted
        negated = np.partition(negated, deepest, axis=1)[:, : deepest + 1]
    out = -np.sort(negated, axis=1)[np.arange(queries), rank]
    # a row with one pairing for all (a steady stream): that one
    valid = column < np.asarray(lengths)[:, None]
    same = ((u == u[:, :1]) | ~valid).all(axis=1)
    if same.any():
        out = np.where(same[query_row], u[query_row, 0], out)
    loosest = np.zeros(time_s.shape)
    loosest[query_row, np.arange(queries) - np.repeat(np.cumsum([0, *counts[:-1]]), counts)] = out
    news = []
    for r, (length_r, count) in enumerate(zip(lengths, counts)):
        if count == 0:
            news.append(recent[r])
            continue
        row_t = t[r, :length_r]
        first = int(np.searchsorted(row_t, row_t[-1] - window_s, side="left"))
        news.append((row_t[first:].copy(), u[r, first:length_r].copy()))
    return loosest, news


def pairing_error_rad_s(
    params: MotorParams,
    time_s: ArrayLike,
    voltage_v: ArrayLike,
    omega_model_rad_s: ArrayLike,
    pairing_s: ArrayLike,
    tau_s: ArrayLike,
    carry: PairingCarry | None = None,
) -> tuple[NDArray[np.float64], PairingCarry]:
    """The speed deviation a command ``pairing_s`` off (one number, or one per sample) could cause, per
    sample (see the module doc)."""
    carry = carry or PairingCarry()
    t = np.asarray(time_s, dtype=float)
    if t.size == 0:
        return np.zeros(0), carry

    def row(x: ArrayLike) -> NDArray[np.float64]:
        return broadcast_to(np.asarray(x, dtype=float), t.shape).reshape(1, -1)

    error, (new,) = pairing_error_rows(
        params, row(t), row(voltage_v), row(omega_model_rad_s), row(pairing_s), row(tau_s), [carry]
    )
    return error[0], new


def pairing_error_rows(
    params: MotorParams,
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    omega_model_rad_s: NDArray[np.float64],
    pairing_s: ArrayLike,
    tau_s: NDArray[np.float64],
    carries: list[PairingCarry],
    lengths: list[int] | None = None,
    input_excursion_v: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], list[PairingCarry]]:
    """:func:`pairing_error_rad_s` of several motors at once: rows of samples (2-D), one carry per row;
    ``pairing_s`` one number or one per sample (2-D like the samples); ``lengths`` each row's number of
    samples (None: all; the rest is padding after them). ``input_excursion_v`` (like the samples; None:
    none): how far the input went beyond the two samples' inputs in between; down and back, it adds twice
    that to the input's movement from one sample to the next (the module doc)."""
    t, v = time_s, voltage_v
    rows, n = t.shape
    counts = [n] * rows if lengths is None else lengths
    previous_t = previous(t, [c.time_s for c in carries])
    previous_v = previous(v, [c.voltage_v for c in carries])
    with np.errstate(divide="ignore", invalid="ignore"):
        moved = np.abs(v - previous_v)
        if input_excursion_v is not None:  # down e and back up e between the two samples
            moved = moved + 2.0 * nan_to_zero(
                broadcast_to(np.asarray(input_excursion_v, dtype=float), t.shape)
            )
        rate = moved / (t - previous_t)
    rate = np.where(np.isfinite(rate) & (t > previous_t), rate, np.nan)  # NaN holds the low-pass
    mean_rate, rate_carries = first_order_responses(t, rate, tau_s, [c.rate for c in carries], counts)
    _, d = linearised_slopes(params, omega_model_rad_s)
    per_sample = np.ndim(pairing_s) > 0
    loosest = np.zeros(t.shape)  # per sample: each one's loosest pairing of the window
    recent = [(c.recent_time_s, c.recent_pairing_s) for c in carries]
    if per_sample:
        u_rows = broadcast_to(np.asarray(pairing_s, dtype=float), t.shape)
        together = _loosest_pairing_rows(t, u_rows, counts, recent) if rows > 1 else None
        if together is not None:  # every motor's few samples at once (the live agent's call)
            loosest, recent = together
        else:
            for r, count in enumerate(counts):
                if count:
                    loosest[r, :count], recent_t, recent_u = loosest_pairing(
                        t[r, :count], u_rows[r, :count], *recent[r]
                    )
                    recent[r] = (recent_t, recent_u)
    # the previous sample is the last one, whatever it holds (as within a call: a split of the samples
    # into calls gives what the whole gives)
    last_t, last_v = last_of(t, counts), last_of(v, counts)
    news = [
        PairingCarry(
            time_s=carry.time_s if time is None else time,
            voltage_v=carry.voltage_v if volts is None else volts,
            rate=rate_carry,
            recent_time_s=recent_t,
            recent_pairing_s=recent_u,
        )
        for carry, time, volts, rate_carry, (recent_t, recent_u) in zip(
            carries, last_t, last_v, rate_carries, recent
        )
    ]
    scale = loosest if per_sample else float(np.asarray(pairing_s))
    error = params.k_t * nan_to_zero(mean_rate) * scale / d
    return error, news
