"""A PX4-style motor failure detector, as the baseline our diagnosis is measured against.

PX4's failure detector (commander's ``FailureDetector``, motor check) compares each ESC's current with
what the throttle should draw: an expected current ``C2T·u + idle`` (a straight line of current against
throttle, the one a user fits with PX4's ``mfd_fit`` tool on healthy flights), low-passes the residual
(τ = 0.2 s), and declares an under-current or over-current failure when the residual stays outside a
band for a hold time. It sees current and throttle only: it can say "too little / too much current",
never which fault.

Here, as a fair baseline, the line is fitted on the same healthy flights our profile is tuned on, and the
bands are set as narrow as those flights allow without a false event (:func:`fit_baseline`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..model.dynamics import ResponseCarry, first_order_response
from ..telemetry.table import TelemetryTable

__all__ = ["Px4Baseline", "detect", "fit_baseline", "fit_current_line", "motor_series", "table_flags"]

UNDER, OK, OVER = -1, 0, 1


@dataclass(frozen=True)
class Px4Baseline:
    """Expected ESC current ``c2t_a · throttle + idle_a``; flags when the low-passed residual leaves
    ``[-low_band_a, +high_band_a]`` for ``hold_s`` at a throttle of at least ``min_throttle``."""

    c2t_a: float
    idle_a: float
    low_band_a: float
    high_band_a: float
    tau_s: float = 0.2
    hold_s: float = 0.3
    min_throttle: float = 0.2


def fit_current_line(
    throttle: ArrayLike, esc_current_a: ArrayLike, min_throttle: float = 0.2
) -> tuple[float, float]:
    """Least-squares line of ESC current against throttle (PX4's ``mfd_fit``): returns (C2T, idle)."""
    u = np.asarray(throttle, dtype=float)
    i = np.asarray(esc_current_a, dtype=float)
    use = np.isfinite(u) & np.isfinite(i) & (u >= min_throttle)
    if use.sum() < 10:
        raise ValueError("too few samples above the minimum throttle to fit the current line")
    slope, intercept = np.polyfit(u[use], i[use], 1)
    return float(slope), float(intercept)


def _residual(
    detector: Px4Baseline,
    time_s: NDArray[np.float64],
    throttle: NDArray[np.float64],
    esc_current_a: NDArray[np.float64],
) -> NDArray[np.float64]:
    expected = detector.c2t_a * throttle + detector.idle_a
    filtered, _ = first_order_response(time_s, esc_current_a - expected, detector.tau_s, ResponseCarry())
    return filtered


def detect(
    detector: Px4Baseline, time_s: ArrayLike, throttle: ArrayLike, esc_current_a: ArrayLike
) -> NDArray[np.int8]:
    """Per sample of one motor: -1 under-current failure, +1 over-current failure, 0 none (after the hold)."""
    t = np.asarray(time_s, dtype=float)
    u = np.asarray(throttle, dtype=float)
    residual = _residual(detector, t, u, np.asarray(esc_current_a, dtype=float))
    raw = np.zeros(t.size, dtype=np.int8)
    active = u >= detector.min_throttle
    raw[active & (residual < -detector.low_band_a)] = UNDER
    raw[active & (residual > detector.high_band_a)] = OVER
    # hold: a flag counts once it has lasted hold_s without interruption
    out = np.zeros(t.size, dtype=np.int8)
    for value in (UNDER, OVER):
        on = raw == value
        start = np.where(on & ~np.concatenate([[False], on[:-1]]), t, np.nan)
        idx = np.maximum.accumulate(np.where(np.isfinite(start), np.arange(t.size), 0))
        since = start[idx]
        out[on & (t - since >= detector.hold_s)] = value
    return out


def fit_baseline(
    flights: Sequence[tuple[NDArray, NDArray, NDArray]],
    *,
    tau_s: float = 0.2,
    hold_s: float = 0.3,
    min_throttle: float = 0.2,
    margin: float = 1.1,
) -> Px4Baseline:
    """Fit the line on healthy (time, throttle, esc current) series, one per motor and flight, then set
    each band ``margin ×`` the largest low-passed residual seen there: no false event on them."""
    u = np.concatenate([f[1] for f in flights])
    i = np.concatenate([f[2] for f in flights])
    c2t, idle = fit_current_line(u, i, min_throttle)
    probe = Px4Baseline(c2t, idle, np.inf, np.inf, tau_s, hold_s, min_throttle)
    low = high = 0.0
    for t, thr, cur in flights:
        res = _residual(probe, t, thr, cur)
        active = (thr >= min_throttle) & np.isfinite(res)
        if active.any():
            low = max(low, float(-res[active].min()))
            high = max(high, float(res[active].max()))
    return Px4Baseline(
        c2t, idle, margin * max(low, 1e-3), margin * max(high, 1e-3), tau_s, hold_s, min_throttle
    )


def motor_series(tables: Sequence[TelemetryTable]) -> list[tuple[NDArray, NDArray, NDArray]]:
    """Each motor's (time, throttle, ESC current) of each table: the series :func:`fit_baseline` takes."""
    series = []
    for table in tables:
        for motor in table.motors():
            rows = table.for_motor(motor)
            series.append((rows["time_s"], rows["throttle"], rows["esc_current_a"]))
    return series


def table_flags(detector: Px4Baseline, table: TelemetryTable) -> NDArray[np.int8]:
    """:func:`detect` on every motor of a telemetry table: one flag per row of the table."""
    flags = np.zeros(len(table), dtype=np.int8)
    for motor in table.motors():
        sel = np.flatnonzero(table["motor"] == motor)
        flags[sel] = detect(
            detector, table["time_s"][sel], table["throttle"][sel], table["esc_current_a"][sel]
        )
    return flags
