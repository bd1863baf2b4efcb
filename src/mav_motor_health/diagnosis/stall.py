"""The current of a stalled motor, averaged since the stall began (the tree's F2.1/F4.2 split).

A stalled motor's current tells the two stalls apart (tree rule 1): an open phase (F2.1) draws little, a
broken back-EMF signal (F4.2) keeps driving the phases and draws more than the split (6 A on the paper's
motor). A motor stops within about 0.15 s, while the balance rule's low-passed current (τ up to 1.5 s in
gusty air) still holds mostly the current from before the stall: in the simulated flights the first
stalled samples of an F4.2 read 4.9–5.5 A (the samples themselves 7–8 A) and the tree called them F2.1
for a tenth of a second; after a climb, an F2.1 read 5.4 A and was announced as F4.2 first. A stall is a
new operating point, so its current is averaged over the stall alone: the mean of the samples since the
motor was first seen stopped (:func:`stall_mean`). The first sample weighs as much as the rest, and the
persistence (0.05 s, two or three samples) still asks the split to hold.

**A stall the paired command may predate** (:func:`stall_rows`, with the samples' times). A log pairs each ESC sample with
the last command it logged (telemetry/assemble.py: its age is the table's ``command_age_s``). A motor
the autopilot drove to idle and back between two logged commands stops for a few samples under a command
that asks for thrust, and reads as a stall: held-out world 1009 (24 kg, commands logged at 10 Hz, ESC
reports at 90 Hz), calm healthy flight, motor 3 fell from 174 to 48 rad/s with no current for 60 ms and
was turning again 0.1 s later, and F2.1 was announced after the stall's 0.05-s hold. Which command the
motor had at that instant, the log does not say; that the autopilot still asked for thrust after the
motor stopped, only a command logged after the stall began says. So a stalled sample whose stall is
younger than its command (``time − since < command_age_s``: the command is from before the stall) is
not counted by the persistence (:mod:`.rules.judged`); the stall's hold runs from the first sample
whose command came after the stall began. A source without the command's age gives its pairing, a
bound on it (``pairing_s``, which also holds how much older than its stamp a sample may be). No new
number: the log's own timing. A source pairing each sample with the command of its own instant (the
simulator's table, a CSV) counts every stalled sample as before; on a log whose commands come at 10 Hz
a stall is announced up to one command interval later.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import broadcast_to
from ..model.dynamics import last_of

if TYPE_CHECKING:
    from .profile import ThresholdProfile

__all__ = ["StallCarry", "stall_mean", "stall_rows", "stop_speeds"]


@dataclass(frozen=True)
class StallCarry:
    """The running stall: sum and number of its finite current samples (``stalled`` False: none running)."""

    total_a: float = 0.0
    count: int = 0
    stalled: bool = False
    #: when the running stall began [s] (:func:`stall_rows`; NaN: none running, or no times given)
    since_s: float = math.nan


def stall_mean(
    current_a: NDArray[np.float64], stalled: NDArray[np.bool_], carry: StallCarry = StallCarry()
) -> tuple[NDArray[np.float64], StallCarry]:
    """Mean of the finite currents since each stall began, at every stalled sample (NaN elsewhere, and
    in a stall with no current read yet). A stall runs over consecutive ``stalled`` samples; the carry
    continues one that is running at the end of the previous call."""
    i = np.asarray(current_a, dtype=float)
    run = np.asarray(stalled, dtype=bool)
    if i.size == 0:
        return np.zeros(0), carry
    mean, _, (new,) = stall_rows(i.reshape(1, -1), run.reshape(1, -1), [carry])
    return mean[0], new


def stall_rows(
    current_a: NDArray[np.float64],
    stalled: NDArray[np.bool_],
    carries: list[StallCarry],
    lengths: list[int] | None = None,
    time_s: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], list[StallCarry]]:
    """:func:`stall_mean` of several motors at once, and when each sample's stall began: rows of samples
    (2-D), one carry per row; ``lengths`` each row's number of samples (None: all; the rest is padding
    after them). Returns the stall's mean current, its start [s] (NaN where not stalled, and everywhere
    without ``time_s``; module doc, "A stall the paired command may predate") and each row's new carry (a
    row without samples keeps its own). The runs are found once for both."""
    i = current_a
    rows, n = i.shape
    run = np.asarray(stalled, dtype=bool)
    counts = [n] * rows if lengths is None else lengths
    if lengths is not None:
        run = run & (np.arange(n) < np.asarray(lengths)[:, None])  # padding is no stall
    carried = np.array([c.stalled for c in carries], dtype=bool)
    if not carried.any() and not run.any():  # the usual case: no stall at all
        none = np.full((rows, n), np.nan)
        return none, none.copy(), [StallCarry() if k else c for c, k in zip(carries, counts)]
    finite = np.isfinite(i) & run
    values = np.where(finite, i, 0.0)
    csum = np.cumsum(values, axis=1)
    ccount = np.cumsum(finite, axis=1)
    # Sums and counts up to the sample before each run's first sample, to subtract: at each sample, those
    # of the latest run begun at or before it (none in this call: the carried run's, negated)
    begins = run & ~np.concatenate([carried[:, None], run[:, :-1]], axis=1)
    latest = np.maximum.accumulate(np.where(begins, np.arange(n), -1), axis=1)
    have = latest >= 0
    at = np.maximum(latest, 0)
    base_sum = np.where(
        have,
        np.take_along_axis(csum - values, at, axis=1),
        -np.array([[c.total_a] for c in carries]),
    )
    base_count = np.where(
        have,
        np.take_along_axis(ccount - finite, at, axis=1),
        -np.array([[c.count] for c in carries]),
    )
    total = csum - base_sum
    count: NDArray[np.int64] = ccount - base_count
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = np.where(run & (count > 0), total / np.maximum(count, 1), np.nan)
    since = np.full((rows, n), np.nan)
    if time_s is not None:
        carried_since = np.array([[c.since_s] for c in carries], dtype=float)
        began = np.where(have, np.take_along_axis(np.asarray(time_s, dtype=float), at, axis=1), carried_since)
        since = np.where(run, began, np.nan)
    news = []
    for carry, last_run, last_total, last_count, last_since in zip(
        carries, last_of(run, counts), last_of(total, counts), last_of(count, counts), last_of(since, counts)
    ):
        if last_run is None:
            news.append(carry)
        elif last_run:
            start_s = float(last_since)
            start_s = math.nan if math.isnan(start_s) else start_s  # (math.nan itself: equal carries are ==)
            news.append(StallCarry(float(last_total), int(last_count), True, start_s))
        else:
            news.append(StallCarry())
    return mean, since, news


def stop_speeds(
    profile: ThresholdProfile, expected_rad_s: ArrayLike, cap_rad_s: ArrayLike | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64] | float]:
    """The tree's rule 1 stop speed at each sample (below it a motor is stopped) and its absolute floor
    (the "expects a turning motor" test's): the profile's stop speed, or its share of the
    ``expected_rad_s`` speed if higher, both at most ``cap_rad_s`` where given (tree.py, "The lowest
    input"). The balance rule and the tree both read it here."""
    expected = np.asarray(expected_rad_s, dtype=float)
    stop = np.maximum(profile.stop_speed_rad_s, profile.stop_speed_fraction * expected)
    floor: NDArray[np.float64] | float = profile.stop_speed_rad_s
    if cap_rad_s is not None:
        cap = broadcast_to(np.asarray(cap_rad_s, dtype=float), stop.shape)
        stop, floor = np.fmin(stop, cap), np.fmin(floor, cap)
    return stop, floor
