"""Which measured variables the residual depends on: distance correlation with a permutation threshold.

Distance correlation (Székely et al. 2007) is zero only when two variables are independent, so it sees
non-linear and non-monotone dependence that a correlation coefficient misses. Both the residual and each
candidate variable are first taken *beyond voltage*: their mean in each voltage bin is removed, so a
variable that merely follows the operating point (throttle, bus current) does not score for what the
model already uses. Significance: the residual is permuted (seeded) and the largest distance correlation
over all variables is recorded for each permutation; a variable is significant when its score beats the
99th percentile of that maximum (a family-wise 1 % level over all variables).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["VariableScore", "distance_correlation", "rank_variables"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class VariableScore:
    name: str
    score: float
    threshold: float
    significant: bool

    def to_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "score": self.score,
            "threshold": self.threshold,
            "significant": self.significant,
        }


def _centered_distances(x: FloatArray) -> FloatArray:
    x = x.reshape(len(x), -1)
    d = np.sqrt(((x[:, None, :] - x[None, :, :]) ** 2).sum(axis=-1))
    return d - d.mean(axis=0) - d.mean(axis=1)[:, None] + d.mean()


def distance_correlation(x: ArrayLike, y: ArrayLike) -> float:
    """Sample distance correlation of x and y (each 1-D or 2-D with samples in rows), in [0, 1]."""
    a = _centered_distances(np.asarray(x, float))
    b = _centered_distances(np.asarray(y, float))
    return _dcor(a, b, float((a * a).mean()), float((b * b).mean()))


def _dcor(a: FloatArray, b: FloatArray, vaa: float, vbb: float) -> float:
    if vaa <= 0 or vbb <= 0:
        return 0.0
    return float(np.sqrt(max((a * b).mean(), 0.0) / np.sqrt(vaa * vbb)))


def _beyond(values: FloatArray, voltage: FloatArray, bins: int) -> FloatArray:
    edges = np.unique(np.quantile(voltage, np.linspace(0, 1, bins + 1)))
    key = np.clip(np.searchsorted(edges, voltage, side="right") - 1, 0, max(len(edges) - 2, 0))
    out = values.copy()
    for b in np.unique(key):
        sel = key == b
        out[sel] -= values[sel].mean(axis=0)
    return out


def rank_variables(
    residual: ArrayLike,
    voltage_v: ArrayLike,
    variables: Mapping[str, ArrayLike],
    *,
    seed: int = 0,
    max_samples: int = 500,
    permutations: int = 99,
    voltage_bins: int = 10,
) -> list[VariableScore]:
    """Score each variable's dependence with ``residual`` (n×d, already scaled) beyond voltage; best first."""
    r = np.asarray(residual, float).reshape(len(np.asarray(voltage_v)), -1)
    v = np.asarray(voltage_v, float)
    rng = np.random.default_rng(seed)
    ok = np.all(np.isfinite(r), axis=1) & np.isfinite(v)
    usable = {
        name: np.asarray(x, float)
        for name, x in variables.items()
        if np.isfinite(np.asarray(x, float)[ok]).sum() >= 20 and np.nanstd(np.asarray(x, float)[ok]) > 0
    }
    idx = np.flatnonzero(ok)
    if len(idx) > max_samples:
        idx = np.sort(rng.choice(idx, max_samples, replace=False))
    if len(idx) < 8 or not usable:
        return []
    rv, vv = r[idx], v[idx]
    b = _centered_distances(_beyond(rv, vv, voltage_bins))
    vbb = float((b * b).mean())
    mats = {}
    for name, x in usable.items():
        xs = x[idx]
        fill = np.where(np.isfinite(xs), xs, np.nanmedian(xs))
        a = _centered_distances(_beyond(fill, vv, voltage_bins))
        mats[name] = (a, float((a * a).mean()))
    scores = {name: _dcor(a, b, vaa, vbb) for name, (a, vaa) in mats.items()}
    maxima = np.empty(permutations)
    for k in range(permutations):
        p = rng.permutation(len(idx))
        bp = b[np.ix_(p, p)]
        maxima[k] = max(_dcor(a, bp, vaa, vbb) for a, vaa in mats.values())
    threshold = float(np.quantile(maxima, 0.99))
    ranked = sorted(scores, key=lambda n: -scores[n])
    return [VariableScore(n, scores[n], threshold, scores[n] > threshold) for n in ranked]
