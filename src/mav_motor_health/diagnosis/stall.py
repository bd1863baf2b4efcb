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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["StallCarry", "stall_mean"]


@dataclass(frozen=True)
class StallCarry:
    """The running stall: sum and number of its finite current samples (``stalled`` False: none running)."""

    total_a: float = 0.0
    count: int = 0
    stalled: bool = False


def stall_mean(
    current_a: NDArray[np.float64], stalled: NDArray[np.bool_], carry: StallCarry = StallCarry()
) -> tuple[NDArray[np.float64], StallCarry]:
    """Mean of the finite currents since each stall began, at every stalled sample (NaN elsewhere, and
    in a stall with no current read yet). A stall runs over consecutive ``stalled`` samples; the carry
    continues one that is running at the end of the previous call."""
    i = np.asarray(current_a, dtype=float)
    run = np.asarray(stalled, dtype=bool)
    n = i.size
    if n == 0:
        return np.zeros(0), carry
    if not carry.stalled and not run.any():  # the usual case: no stall at all
        return np.full(n, np.nan), StallCarry()
    previous = np.concatenate([[carry.stalled], run[:-1]])
    begins = run & ~previous
    run_id = np.cumsum(begins)  # 0: the run carried in (if any), k: the k-th run begun in this call
    finite = np.isfinite(i) & run
    values = np.where(finite, i, 0.0)
    csum = np.cumsum(values)
    ccount = np.cumsum(finite)
    # Sums and counts up to the sample before each run's first sample, to subtract
    first = np.flatnonzero(begins)
    base_sum = np.concatenate([[-carry.total_a], csum[first] - values[first]])
    base_count = np.concatenate([[-carry.count], ccount[first] - finite[first]])
    total = csum - base_sum[run_id]
    count = ccount - base_count[run_id]
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = np.where(run & (count > 0), total / np.maximum(count, 1), np.nan)
    last = bool(run[-1])
    new = StallCarry(float(total[-1]), int(count[-1]), True) if last else StallCarry()
    return mean, new
