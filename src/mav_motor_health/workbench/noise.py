"""The measurement noise floor, estimated from the data itself.

Two estimators, the first that has enough data wins (:attr:`NoiseFloor.method` says which):

``repeated``  consecutive samples of one motor whose input voltage differs by less than ``tol_v`` are
              repeats of the same operating point; for independent noise of level σ,
              ``E[(y₂ − y₁)²] = 2σ²``, so ``σ = √(mean(Δy²)/2)``. Slow context drift between two samples
              adds next to nothing; step changes are excluded by the voltage tolerance.
``voltage-difference``  (data without repeats, such as one sample per bench step) samples sorted by
              voltage; the second difference ``y₋ − 2y₀ + y₊`` removes a smooth (locally linear)
              dependence on voltage and has variance 6σ². This one also counts as noise whatever the
              model does not explain through voltage, so it is an upper bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["NoiseFloor", "noise_floor", "repeat_pairs"]

MIN_PAIRS = 10


@dataclass(frozen=True)
class NoiseFloor:
    """Noise level (one standard deviation) of speed and current, and how it was estimated."""

    omega_rad_s: float
    current_a: float
    method: str
    n_pairs: int

    def to_dict(self) -> dict[str, object]:
        return {
            "omega_rad_s": self.omega_rad_s,
            "current_a": self.current_a,
            "method": self.method,
            "n_pairs": self.n_pairs,
        }


def repeat_pairs(
    time_s: ArrayLike, motor: ArrayLike, voltage_v: ArrayLike, *, tol_v: float = 0.05
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Index pairs (into the given arrays) of consecutive samples of one motor at the same voltage."""
    t = np.asarray(time_s, float)
    m = np.asarray(motor)
    v = np.asarray(voltage_v, float)
    order = np.lexsort((t, m))
    a, b = order[:-1], order[1:]
    same = (m[a] == m[b]) & np.isfinite(v[a]) & np.isfinite(v[b]) & (np.abs(v[b] - v[a]) < tol_v)
    return a[same], b[same]


def noise_floor(
    time_s: ArrayLike,
    motor: ArrayLike,
    voltage_v: ArrayLike,
    omega_rad_s: ArrayLike,
    current_a: ArrayLike,
    *,
    tol_v: float = 0.05,
) -> NoiseFloor:
    """Estimate the speed and current noise (see the module doc for the two estimators)."""
    t = np.asarray(time_s, float)
    m = np.asarray(motor)
    v = np.asarray(voltage_v, float)
    w = np.asarray(omega_rad_s, float)
    i = np.asarray(current_a, float)
    ok = np.isfinite(v) & np.isfinite(w) & np.isfinite(i)
    a, b = repeat_pairs(t, m, v, tol_v=tol_v)
    keep = ok[a] & ok[b]
    a, b = a[keep], b[keep]
    if len(a) >= MIN_PAIRS:
        dw, di = w[b] - w[a], i[b] - i[a]
        return NoiseFloor(
            float(np.sqrt(np.mean(dw * dw) / 2)),
            float(np.sqrt(np.mean(di * di) / 2)),
            "repeated",
            len(a),
        )
    sw: list[float] = []
    si: list[float] = []
    for motor_id in np.unique(m):
        sel = (m == motor_id) & ok
        by_v = np.argsort(v[sel], kind="stable")
        ww, ii = w[sel][by_v], i[sel][by_v]
        if len(ww) >= 3:
            sw += list(ww[:-2] - 2 * ww[1:-1] + ww[2:])
            si += list(ii[:-2] - 2 * ii[1:-1] + ii[2:])
    if len(sw) < 3:
        return NoiseFloor(math.nan, math.nan, "none (too few samples)", len(sw))
    a, b = np.asarray(sw), np.asarray(si)
    return NoiseFloor(
        float(np.sqrt(np.mean(a * a) / 6)), float(np.sqrt(np.mean(b * b) / 6)), "voltage-difference", len(sw)
    )
