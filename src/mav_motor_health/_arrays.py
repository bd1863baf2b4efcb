"""Numpy functions of hot paths in fewer or cheaper numpy calls, with the same results.

The live agent calls the core with a few samples at a time, where numpy's own Python-level wrappers cost
more than the arithmetic: :func:`numpy.nan_to_num` (a dozen calls inside) and :func:`numpy.isin` (a sort
or a table) take ten to fifteen microseconds on a handful of values. These give the same arrays.
:func:`distinct` is :func:`numpy.unique` of small integer codes (message ids, lengths, motor numbers),
counted instead of hashed and sorted: a whole log's codes in one pass.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["broadcast_to", "distinct", "nan_to_zero", "one_of", "part_bounds"]

#: codes below this are counted by :func:`distinct` (a table of this many counts at most)
DISTINCT_COUNTED = 1 << 16


def broadcast_to(values: ArrayLike, shape: tuple[int, ...]) -> NDArray:
    """:func:`numpy.broadcast_to`, but an array that has ``shape`` already is given back as it is (numpy's
    Python-level wrapper costs about 5 µs a call, on the live agent's hot path a few dozen times a core
    call). The same values; the caller must not write into the result (numpy's view is read-only)."""
    x = np.asarray(values)
    return x if x.shape == shape else np.broadcast_to(x, shape)


def nan_to_zero(values: ArrayLike) -> NDArray:
    """:func:`numpy.nan_to_num` with its defaults (NaN → 0, ±inf → the largest finite values): a new array."""
    x = np.asarray(values)
    if x.dtype.kind != "f":
        return np.nan_to_num(x)
    out = np.where(np.isnan(x), 0.0, x).astype(x.dtype, copy=False)
    if not np.isfinite(out).all():  # infinities (rare): numpy's own
        return np.nan_to_num(out)
    return out


def one_of(values: ArrayLike, codes: Iterable[int]) -> NDArray[np.bool_]:
    """:func:`numpy.isin` for a few integer codes: where ``values`` is one of them (an enum member is
    compared as its int: as a numpy operand it costs more than the comparison, ``diagnosis.states.Code``)."""
    x = np.asarray(values)
    out = np.zeros(x.shape, dtype=bool)
    for code in codes:
        out |= x == int(code)
    return out


def distinct(values: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """``numpy.unique(values, return_counts=True)`` of integers (1-D) as int64: where every value is in
    0 … :data:`DISTINCT_COUNTED` − 1, counted (one pass, no sort)."""
    x = np.asarray(values)
    if x.size and x.dtype.kind in "iu" and int(x.min()) >= 0 and int(x.max()) < DISTINCT_COUNTED:
        counts = np.bincount(x)
        present = np.flatnonzero(counts)
        return present.astype(np.int64), counts[present].astype(np.int64)
    uniq, counts = np.unique(x, return_counts=True)
    return uniq.astype(np.int64), counts.astype(np.int64)


def part_bounds(series: Sequence[NDArray[np.float64]], size: int) -> NDArray[np.intp] | None:
    """Consecutive parts of several series of times (each in increasing time), taken together in time
    order, of about ``size`` samples each, cut between instants (the samples of one instant stay in one
    part, however many): each series' first sample of each part, one column per part, and a last
    column of the series' lengths. None where a time is not finite or no cut falls after the first
    instant (one part). The caller decides whether the series are long enough to cut."""
    every = np.concatenate(series) if len(series) else np.zeros(0)
    if every.size == 0 or not np.isfinite(every).all():
        return None
    ranked = np.sort(every, kind="stable")  # each series in order already: a merge of sorted runs
    cuts = np.unique(ranked[size::size])
    cuts = cuts[cuts > ranked[0]]  # (every part holds samples; an instant stays whole)
    if cuts.size == 0:
        return None
    # side="left": the samples of a cut's instant go with the part it begins
    starts = np.array([np.searchsorted(row, cuts, side="left") for row in series], dtype=np.intp)
    ends = np.array([row.size for row in series], dtype=np.intp)[:, None]
    return np.concatenate([np.zeros((len(series), 1), dtype=np.intp), starts, ends], axis=1)
