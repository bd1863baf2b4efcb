"""Persistence: a state is announced only after it has held for a set time (per state).

The announced state is what the live agent publishes and what replay writes as ``announced``. Only
*eligible* samples count (steady ones, plus states the profile allows in transients); other samples keep
the announcement as it is and neither confirm nor break a run. The rule carries its state between calls,
so streaming one sample at a time and replaying whole arrays give identical results.

Whole arrays are judged with numpy for all runs at once: the announcement is the state of the latest run
that reached its hold, and a run with a rate reaches it where its own sum of rate·Δt does (one cumulative
sum over all runs finds the few that come near; only those are summed run by run, as the hold is
defined, so that the result is exact). A few samples (the live agent's) run sample by sample in plain
Python; both give the same announcements and carries.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._arrays import nan_to_zero
from .states import MotorState

__all__ = ["PersistenceCarry", "announce", "run_hold"]

#: Up to this many samples (the live agent's batches) the rule runs sample by sample in plain Python
_SCALAR_MAX = 32


@dataclass(frozen=True)
class PersistenceCarry:
    """What persistence remembers between calls for one motor."""

    announced: int = int(MotorState.NORMAL)
    candidate: int = int(MotorState.NORMAL)
    candidate_since_s: float = float("-inf")
    last_eligible_s: float = float("-inf")
    candidate_held_s: float = 0.0  # the candidate's hold so far (its time, weighted by the rate if given)


def announce(
    hold_s: NDArray[np.float64],
    time_s: NDArray[np.float64],
    state: NDArray[np.integer],
    eligible: NDArray[np.bool_],
    carry: PersistenceCarry = PersistenceCarry(),
    max_gap_s: float = float("inf"),
    hold_per_activity_s: NDArray[np.float64] | None = None,
    activity: NDArray[np.float64] | None = None,
    rate: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.int8], PersistenceCarry]:
    """Announced state per sample given raw states; ``hold_s[code]`` is each state's hold time.

    A run of one state also ends where two eligible samples are more than ``max_gap_s`` apart: a state
    seen once, then again after a long silence, has not *held* in between. With ``hold_per_activity_s``
    and ``activity`` a state's hold grows with the input activity at each sample,
    ``hold_s[code] + hold_per_activity_s[code]·activity``: in gusty air a false state flickers longer.

    ``rate`` (≥ 1 per sample; None: 1) makes a run's time count faster: the interval before each sample
    counts ``rate`` times (the tree's depth, capped by the profile: a departure twice the band deep is
    held twice as fast). The hold is then reached when Σ rate·Δt over the run's eligible samples
    reaches it (:func:`run_hold`).
    """
    t = np.asarray(time_s, dtype=float)
    s = np.asarray(state, dtype=np.int64)
    if t.size <= _SCALAR_MAX:
        return _announce_scalar(hold_s, t, s, eligible, carry, max_gap_s, hold_per_activity_s, activity, rate)
    idx = np.flatnonzero(eligible)
    out = np.full(t.size, carry.announced, dtype=np.int8)
    if idx.size == 0:
        return out, carry
    te, se = t[idx], s[idx]
    # The runs of one state among the eligible samples; only the first may continue the carried one
    boundaries = np.flatnonzero((se[1:] != se[:-1]) | (te[1:] - te[:-1] > max_gap_s)) + 1
    starts = np.concatenate([[0], boundaries])
    ends = np.concatenate([boundaries, [se.size]])
    run_state = se[starts]
    continues = bool(run_state[0] == carry.candidate and te[0] - carry.last_eligible_s <= max_gap_s)
    run_since = te[starts]
    if continues:
        run_since[0] = carry.candidate_since_s
    lengths = ends - starts
    run_of = np.repeat(np.arange(starts.size), lengths)  # each eligible sample's run
    hold = np.asarray(hold_s, dtype=float)[run_state]
    slope = None  # the hold added per volt of input activity, per run (None: no state has one)
    if hold_per_activity_s is not None and activity is not None:
        slope = np.asarray(hold_per_activity_s, dtype=float)[run_state]
        if not slope.any():
            slope = None
    held_carried = carry.candidate_held_s if continues else 0.0
    first_step = te[0] - carry.last_eligible_s if continues else 0.0
    if rate is None:
        # the hold each sample of its run has reached is its time since the run began
        since = run_since[run_of]
        reached = te >= since + hold[run_of]  # a fixed hold in time: the first sample at or after it
        if slope is not None:
            extra = slope[run_of] * nan_to_zero(np.asarray(activity, dtype=float)[idx])
            by_activity = (slope != 0)[run_of]
            reached = np.where(by_activity, te - since >= hold[run_of] + extra, reached)
        first_reached = _first_true_per_run(reached, starts, ends)
        held_last = float(te[-1] - run_since[-1])
    else:
        # Σ rate·Δt over each run (run by run, as the hold is defined: exact for the runs that matter)
        steps = np.empty(te.size)
        steps[0] = first_step
        steps[1:] = te[1:] - te[:-1]
        steps[starts[1:]] = 0.0
        weighted = np.asarray(rate, dtype=float)[idx] * steps
        need = hold[run_of]
        if slope is not None:
            need = need + slope[run_of] * nan_to_zero(np.asarray(activity, dtype=float)[idx])
        candidates = _runs_near_hold(weighted, need, starts, ends, held_carried)
        first_reached = _first_held(weighted, need, starts, ends, held_carried, candidates)
        last_start = int(starts[-1])
        held_last = float(
            ((held_carried if starts.size == 1 else 0.0) + np.cumsum(weighted[last_start:]))[-1]
        )
    # A run that reaches its hold announces its state there (a run of the state already announced changes
    # nothing): the announcement is the state of the latest run that reached its hold
    announcing = np.flatnonzero(first_reached >= 0)
    announced = carry.announced
    if announcing.size:
        at = idx[first_reached[announcing]]
        values = run_state[announcing].astype(np.int8)
        latest = np.maximum.accumulate(np.where(_marks(at, t.size), np.arange(t.size), -1))
        value_at = np.full(t.size, carry.announced, dtype=np.int8)
        value_at[at] = values
        has = latest >= 0
        out[has] = value_at[latest[has]]
        announced = int(values[-1])
    return out, PersistenceCarry(
        announced=announced,
        candidate=int(run_state[-1]),
        candidate_since_s=float(run_since[-1]),
        last_eligible_s=float(te[-1]),
        candidate_held_s=held_last,
    )


def _announce_scalar(
    hold_s: NDArray[np.float64],
    t: NDArray[np.float64],
    s: NDArray[np.int64],
    eligible: NDArray[np.bool_],
    carry: PersistenceCarry,
    max_gap_s: float,
    hold_per_activity_s: NDArray[np.float64] | None,
    activity: NDArray[np.float64] | None,
    rate: NDArray[np.float64] | None,
) -> tuple[NDArray[np.int8], PersistenceCarry]:
    """:func:`announce` for a few samples, sample by sample: the same runs, holds and announcements.

    A run's hold with a rate is its carried hold plus the sum of rate·Δt since this call began, summed
    in the same order as the run-by-run form, so that both give the same numbers."""
    holds = np.asarray(hold_s, dtype=float).tolist()
    slopes = None
    acts: list[float] = []  # the activities, worked out when a hold first needs them
    if hold_per_activity_s is not None and activity is not None:
        slopes = np.asarray(hold_per_activity_s, dtype=float).tolist()
    rates = None if rate is None else np.asarray(rate, dtype=float).tolist()
    out = np.empty(t.size, dtype=np.int8)
    announced, candidate, since = carry.announced, carry.candidate, carry.candidate_since_s
    last = carry.last_eligible_s
    base, summed = carry.candidate_held_s, 0.0  # a run's hold: base + Σ rate·Δt within this call
    first = True
    for k, (tk, sk, ok) in enumerate(zip(t.tolist(), s.tolist(), np.asarray(eligible, dtype=bool).tolist())):
        if ok:
            if first:
                new_run = not (sk == candidate and tk - last <= max_gap_s)
            else:
                new_run = sk != candidate or tk - last > max_gap_s
            if new_run:
                candidate, since, base, summed = sk, tk, 0.0, 0.0
                step = 0.0
            else:
                step = tk - last
            first = False
            if rates is not None:
                summed = summed + rates[k] * step
                held = base + summed
            else:
                held = tk - since
            last = tk
            if sk != announced:
                hold = holds[sk]
                slope = slopes[sk] if slopes is not None else 0.0
                if rates is None and not slope:
                    reached = tk >= since + hold
                else:
                    if slope and not acts:
                        acts = nan_to_zero(np.asarray(activity, dtype=float)).tolist()
                    reached = held >= (hold + slope * acts[k] if slope else hold)
                if reached:
                    announced = sk
        out[k] = announced
    if first:  # no eligible sample: nothing changes
        return out, carry
    held_s = base + summed if rates is not None else last - since
    return out, PersistenceCarry(
        announced=announced,
        candidate=candidate,
        candidate_since_s=since,
        last_eligible_s=last,
        candidate_held_s=held_s,
    )


def _marks(positions: NDArray[np.int64], n: int) -> NDArray[np.bool_]:
    marks = np.zeros(n, dtype=bool)
    marks[positions] = True
    return marks


def _first_true_per_run(
    values: NDArray[np.bool_], starts: NDArray[np.int64], ends: NDArray[np.int64]
) -> NDArray[np.int64]:
    """The index of each run's first True (−1: none)."""
    true_at = np.flatnonzero(values)
    k = np.searchsorted(true_at, starts)
    found = np.where(k < true_at.size, true_at[np.minimum(k, true_at.size - 1)], -1) if true_at.size else None
    if found is None:
        return np.full(starts.size, -1, dtype=np.int64)
    return np.where((found >= 0) & (found < ends), found, -1)


#: :func:`_first_held` lays the candidate runs out side by side up to this many values (beyond: run by run)
_HELD_LAYOUT_MAX = 1 << 18


def _first_held(
    weighted: NDArray[np.float64],
    need: NDArray[np.float64],
    starts: NDArray[np.int64],
    ends: NDArray[np.int64],
    held_carried: float,
    candidates: NDArray[np.int64],
) -> NDArray[np.int64]:
    """Per run, the first sample where its hold Σ rate·Δt (the first run's after the carried hold) reaches
    ``need`` (-1: none), worked out for the ``candidates`` only: each one's own cumulative sum, the
    candidates laid out in rows (padded with zeros after their samples: a row's sums up to its last sample
    are its run's own) where that is small, else run by run."""
    first_reached = np.full(starts.size, -1, dtype=np.int64)
    if candidates.size == 0:
        return first_reached
    begin, lengths = starts[candidates], ends[candidates] - starts[candidates]
    width = int(lengths.max())
    if candidates.size * width > _HELD_LAYOUT_MAX:
        for r in candidates.tolist():
            start, end = int(starts[r]), int(ends[r])
            held = (held_carried if r == 0 else 0.0) + np.cumsum(weighted[start:end])
            found = np.flatnonzero(held >= need[start:end])
            if found.size:
                first_reached[r] = start + int(found[0])
        return first_reached
    column = np.arange(width)
    inside = column < lengths[:, None]
    at = np.where(inside, begin[:, None] + column, 0)
    held = np.cumsum(np.where(inside, weighted[at], 0.0), axis=1)
    if candidates[0] == 0:
        held[0] = held_carried + held[0]
    reached = inside & (held >= need[at])
    some = reached.any(axis=1)
    first_reached[candidates[some]] = begin[some] + np.argmax(reached[some], axis=1)
    return first_reached


def _runs_near_hold(
    weighted: NDArray[np.float64],
    need: NDArray[np.float64],
    starts: NDArray[np.int64],
    ends: NDArray[np.int64],
    held_carried: float,
) -> NDArray[np.int64]:
    """The runs whose hold Σ rate·Δt may reach ``need`` somewhere: a superset, from one cumulative sum.

    The cumulative sum over all runs differs from each run's own by rounding only, bounded by
    (n + 1)·ε·Σ|terms|; a run within that of its need is kept (and then computed run by run).
    """
    if not (np.all(np.isfinite(weighted)) and np.isfinite(held_carried)):
        return np.arange(starts.size)
    total = np.cumsum(weighted)
    before = np.concatenate([[0.0], total])[starts]  # the sum up to each run's start
    base = np.zeros(starts.size)
    base[0] = held_carried
    lengths = ends - starts
    run_of = np.repeat(np.arange(starts.size), lengths)
    approx = base[run_of] + (total - before[run_of])
    scale = float(np.sum(np.abs(weighted))) + abs(held_carried) + float(np.max(np.abs(need)))
    slack = 4.0 * (weighted.size + 2) * np.finfo(float).eps * scale
    close = approx >= need - slack
    return np.flatnonzero(np.logical_or.reduceat(close, starts)) if close.size else np.zeros(0, np.int64)


def run_hold(time_s: NDArray[np.float64], rate: NDArray[np.float64] | None = None) -> float:
    """The hold one run of eligible samples reaches by its last sample: its duration, or Σ rate·Δt."""
    t = np.asarray(time_s, dtype=float)
    if t.size < 2:
        return 0.0
    if rate is None:
        return float(t[-1] - t[0])
    return float(np.sum(np.asarray(rate, dtype=float)[1:] * np.diff(t)))
