"""Persistence: a state is announced only after it has held for a set time (per state).

The announced state is what the live agent publishes and what replay writes as ``announced``. Only
*eligible* samples count (steady ones, plus states the profile allows in transients); other samples keep
the announcement as it is and neither confirm nor break a run. The rule carries its state between calls,
so streaming one sample at a time and replaying whole arrays give identical results.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .states import MotorState

__all__ = ["PersistenceCarry", "announce", "run_hold"]


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
            # the hold each sample of the run has reached: its time since the run began, or Σ rate·Δt
            if rate is not None:
                steps = np.diff(te[start:end], prepend=carry.last_eligible_s if continues else te[start])
                held = (held_s if continues else 0.0) + np.cumsum(rate[idx[start:end]] * steps)
            else:
                held = te[start:end] - run_since
            held_s = float(held[-1])
            if run_state == announced:
                continue
            hold = float(hold_s[run_state])
            extra = None  # the hold added by the input activity at each sample
            if hold_per_activity_s is not None and activity is not None and hold_per_activity_s[run_state]:
                extra = float(hold_per_activity_s[run_state]) * np.nan_to_num(activity[idx[start:end]])
            if rate is None and extra is None:
                # a fixed hold in time: the first sample at or after it
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
    return out, PersistenceCarry(
        announced=announced,
        candidate=candidate,
        candidate_since_s=since,
        last_eligible_s=last,
        candidate_held_s=held_s,
    )


def run_hold(time_s: NDArray[np.float64], rate: NDArray[np.float64] | None = None) -> float:
    """The hold one run of eligible samples reaches by its last sample: its duration, or Σ rate·Δt."""
    t = np.asarray(time_s, dtype=float)
    if t.size < 2:
        return 0.0
    if rate is None:
        return float(t[-1] - t[0])
    return float(np.sum(np.asarray(rate, dtype=float)[1:] * np.diff(t)))
