"""Calibrate a motor model on a healthy stretch of a flight (a hover before anything happened).

``calibrate`` picks what the data can support:

* samples in the window where the input is steady (no step larger than 0.1 V for 0.5 s) and the motor
  turns faster than the stop speed;
* with a trusted current (no plausibility flag on most of them): the paper's two-step estimate;
* without (RPM-only ESCs, a stuck or mis-scaled current): a speed-only calibration, which keeps R, B and k
  from the base motor (:func:`~mav_motor_health.model.estimation.estimate_speed_only`);
* then the inertia J that best explains how speed follows the moving input, or none if a lag does not
  help (:func:`~mav_motor_health.model.dynamics.estimate_inertia`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import FitError
from ..model.dynamics import estimate_inertia
from ..model.estimation import estimate, estimate_speed_only
from ..model.params import MotorParams
from ..telemetry.table import TelemetryTable
from .plausibility import CURRENT_UNTRUSTED, PlausibilityRule, check_motor
from .rules import StepRule
from .steady import steady_mask

__all__ = ["Calibration", "calibrate"]

_CALIBRATION_STEADY = StepRule(step_v=0.1, settle_s=0.5)


@dataclass(frozen=True)
class Calibration:
    params: MotorParams
    speed_only: bool
    samples: int
    current_trusted_share: float
    report: str


def calibrate(
    table: TelemetryTable,
    base: MotorParams,
    start_s: float,
    end_s: float,
    *,
    stop_speed_rad_s: float = 100.0,
    plausibility: PlausibilityRule | None = None,
    min_trusted_share: float = 0.9,
) -> Calibration:
    """A motor model for ``table``'s motors from the samples in [start_s, end_s] (see module doc)."""
    # Plausibility needs the history: a reading frozen since take-off is stuck in a calm hover too.
    ordered = table.sorted_by_motor_time()
    history = ordered.select(ordered["time_s"] <= end_s)
    window = history.select(history["time_s"] >= start_s)
    if len(window) == 0:
        raise FitError(f"no samples between {start_s} s and {end_s} s to calibrate on")
    volts = window.voltage_v()
    use = np.zeros(len(window), dtype=bool)
    trusted = np.zeros(len(window), dtype=bool)
    rule = plausibility or PlausibilityRule()
    command = window.get("throttle")
    reported = window.get("esc_current_a")
    runs = []
    for motor in window.motors():
        sel = np.flatnonzero(window["motor"] == motor)
        t = window["time_s"][sel]
        steady, _ = steady_mask(_CALIBRATION_STEADY, t, volts[sel])
        use[sel] = steady & (window["omega_rad_s"][sel] > stop_speed_rad_s)
        past = np.flatnonzero(history["motor"] == motor)
        flags, _ = check_motor(
            rule,
            history["time_s"][past],
            None if command is None else history["throttle"][past],
            history["current_a" if reported is None else "esc_current_a"][past],
            history["omega_rad_s"][past],
        )
        flags = flags[-sel.size :]  # the window is the end of the motor's history
        trusted[sel] = ((flags & CURRENT_UNTRUSTED) == 0) & np.isfinite(window["current_a"][sel])
        runs.append((t, volts[sel], window["omega_rad_s"][sel]))
    if use.sum() < 10:
        raise FitError(
            f"only {int(use.sum())} steady samples of a turning motor between {start_s} s and {end_s} s"
        )
    share = float(trusted[use].mean())
    speed_only = share < min_trusted_share
    if speed_only:
        fit = estimate_speed_only(volts[use], window["omega_rad_s"][use], base, min_samples=3)
        params, text = (
            fit.params,
            f"speed-only fit of {', '.join(fit.fit.values)}: rmse {fit.fit.rmse:.3g} rad/s",
        )
    else:
        result = estimate(volts[use], window["current_a"][use], window["omega_rad_s"][use], min_samples=3)
        params, text = result.params.replace(J_kg_m2=base.J_kg_m2), result.report()
    inertia = estimate_inertia(params, runs)
    params = params.replace(J_kg_m2=inertia, name=f"calibrated on {start_s:g}-{end_s:g} s")
    text += f"\ninertia J: {'no lag' if inertia is None else f'{inertia:.3g} kg*m^2'}"
    return Calibration(
        params=params, speed_only=speed_only, samples=int(use.sum()), current_trusted_share=share, report=text
    )
