"""Synthetic bench/flight sessions with a hidden effect, for tests and the worked example.

A session holds the throttle at random levels for a few seconds each while the context drifts slowly
and independently (motor and ESC temperature, altitude, air temperature, climb rate, a sagging battery),
and measures speed and current with the paper's sensor noise (uniform, section III.B).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from ..model.effects.base import Effect, compose, solve
from ..model.params import MotorParams
from ..sim.steady import SensorNoise
from ..telemetry.table import TelemetryTable

__all__ = ["hidden_effect_session"]


def _drift(rng: np.random.Generator, n: int, low: float, high: float, smooth: int) -> NDArray[np.float64]:
    """A slow random wander between ``low`` and ``high`` (low-passed random walk, rescaled)."""
    walk = np.cumsum(rng.normal(size=n + 2 * smooth))
    kernel = np.ones(smooth) / smooth
    x = np.convolve(walk, kernel, mode="same")[smooth : smooth + n]
    x = (x - x.min()) / max(float(np.ptp(x)), 1e-12)
    return low + (high - low) * x


def hidden_effect_session(
    params: MotorParams,
    rng: np.random.Generator,
    effects: Sequence[tuple[Effect, Mapping[str, float]]] = (),
    *,
    duration_s: float = 900.0,
    rate_hz: float = 4.0,
    hold_s: float = 6.0,
    throttle_range: tuple[float, float] = (0.28, 0.95),
    noise: SensorNoise | None = None,
) -> TelemetryTable:
    """One motor's telemetry with ``effects`` hidden in the truth; columns as a flight log has them.

    The effective voltage is ``throttle × bus_voltage_v`` (no ``voltage_v`` column), as flight logs
    give it.
    """
    noise = noise or SensorNoise()
    n = int(duration_s * rate_hz)
    t = np.arange(n) / rate_hz
    steps = int(np.ceil(duration_s / hold_s))
    levels = rng.uniform(*throttle_range, steps)
    throttle = levels[np.minimum((t / hold_s).astype(int), steps - 1)]
    smooth = max(int(60 * rate_hz), 3)
    context = {
        "throttle": throttle,
        "bus_voltage_v": 12.5 - 1.3 * t / duration_s + 0.05 * np.sin(t / 37.0),
        "motor_temp_c": _drift(rng, n, 15.0, 85.0, smooth),
        "esc_temp_c": _drift(rng, n, 15.0, 70.0, smooth),
        "alt_m": _drift(rng, n, 0.0, 3000.0, smooth),
        "air_temp_c": _drift(rng, n, -5.0, 35.0, smooth),
        "climb_m_s": _drift(rng, n, -2.0, 2.0, max(smooth // 4, 3)),
    }
    voltage = throttle * context["bus_voltage_v"]
    truth = solve(compose(params, voltage, context, list(effects)))
    omega = truth.omega_rad_s + rng.uniform(-noise.speed_rad_s, noise.speed_rad_s, n)
    current = truth.current_a + rng.uniform(-1.0, 1.0, n) * noise.current_halfwidth_a(voltage)
    return TelemetryTable.from_columns(
        source="synthetic",
        meta={"hidden_effects": {e.name: dict(v) for e, v in effects}},
        time_s=t,
        motor=np.ones(n, dtype=int),
        omega_rad_s=omega,
        current_a=current,
        **context,
    )
