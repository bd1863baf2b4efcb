"""Which measured variables the residual depends on: distance correlation with a permutation threshold.

Distance correlation (Székely et al. 2007) is zero only when two variables are independent, so it sees
non-linear and non-monotone dependence that a correlation coefficient misses. Both the residual and each
candidate variable are first taken *beyond voltage*: a straight line in each voltage decile is removed, so a
variable that merely follows the operating point (throttle, bus current) does not score for what the
model already uses; the residual is also divided by its spread in each voltage bin, so sensor noise
that grows with load does not count as dependence. Significance: the residual is permuted (seeded) and the largest distance correlation
over all variables is recorded for each permutation; a variable is significant when its score beats the
99th percentile of that maximum (a family-wise 1 % level over all variables). Variables that drift
together (temperature and altitude in one flight) would all look significant, so selection is greedy:
the strongest significant variable is taken, the residual's dependence on it is removed (a straight line per
decile bin of that variable), and the rest are tested again on what remains. The reported score is
the marginal one; ``significant`` says whether the variable was selected.
"""

from __future__ import annotations

import math
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


def _standardised(values: FloatArray, voltage: FloatArray, bins: int) -> FloatArray:
    """Residual beyond voltage and divided by its spread in each voltage bin: noise that merely grows
    with load (heteroscedastic sensors) then depends on nothing."""
    out = _beyond(values, voltage, bins)
    edges = np.unique(np.quantile(voltage, np.linspace(0, 1, bins + 1)))
    key = np.clip(np.searchsorted(edges, voltage, side="right") - 1, 0, max(len(edges) - 2, 0))
    for b in np.unique(key):
        sel = key == b
        spread = np.sqrt(np.mean(out[sel] ** 2, axis=0))
        out[sel] = out[sel] / np.where(spread > 0, spread, 1.0)
    return out


def _beyond(values: FloatArray, voltage: FloatArray, bins: int) -> FloatArray:
    edges = np.unique(np.quantile(voltage, np.linspace(0, 1, bins + 1)))
    key = np.clip(np.searchsorted(edges, voltage, side="right") - 1, 0, max(len(edges) - 2, 0))
    out = values.copy()
    for b in np.unique(key):
        sel = key == b
        x = voltage[sel] - voltage[sel].mean()
        y = values[sel] - values[sel].mean(axis=0)
        sxx = float(x @ x)
        # A straight line per bin: what follows the variable smoothly is removed, not just its level.
        slope = (x @ y) / sxx if sxx > 0 and sel.sum() >= 3 else 0.0 * y[0]
        out[sel] = y - np.multiply.outer(x, slope)
    return out


def rank_variables(
    residual: ArrayLike,
    voltage_v: ArrayLike,
    variables: Mapping[str, ArrayLike],
    *,
    seed: int = 0,
    max_samples: int = 300,
    permutations: int = 99,
    voltage_bins: int = 10,
    max_selected: int = 3,
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
    b = _centered_distances(_standardised(rv, vv, voltage_bins))
    vbb = float((b * b).mean())
    mats = {}
    for name, x in usable.items():
        xs = x[idx]
        fill = np.where(np.isfinite(xs), xs, np.nanmedian(xs))
        a = _centered_distances(_beyond(fill, vv, voltage_bins))
        mats[name] = (a, float((a * a).mean()))
    scores = {name: _dcor(a, b, vaa, vbb) for name, (a, vaa) in mats.items()}
    first_threshold = math.nan
    selected: list[str] = []
    remaining = _standardised(rv, vv, voltage_bins)
    while len(selected) < max_selected:
        candidates = {n: m for n, m in mats.items() if n not in selected}
        if not candidates:
            break
        bb = _centered_distances(remaining)
        vb = float((bb * bb).mean())
        current = {n: _dcor(a, bb, vaa, vb) for n, (a, vaa) in candidates.items()}
        maxima = np.empty(permutations)
        for k in range(permutations):
            p = rng.permutation(len(idx))
            bp = bb[np.ix_(p, p)]
            maxima[k] = max(_dcor(a, bp, vaa, vb) for a, vaa in candidates.values())
        threshold = float(np.quantile(maxima, 0.99))
        if math.isnan(first_threshold):
            first_threshold = threshold
        best = max(current, key=lambda n: current[n])
        if current[best] <= threshold:
            break
        selected.append(best)
        xs = np.asarray(variables[best], float)[idx]
        remaining = _beyond(remaining, np.where(np.isfinite(xs), xs, np.nanmedian(xs)), 10)
    ranked = sorted(
        scores, key=lambda n: (n not in selected, selected.index(n) if n in selected else -scores[n])
    )
    return [VariableScore(n, scores[n], first_threshold, n in selected) for n in ranked]
