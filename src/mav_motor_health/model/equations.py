"""The steady-state motor equations as pure, vectorised functions (paper eqs. 2, 7, 9 and 10).

The forward solution eliminates the current between eq. 2 and eq. 7::

    f(ω) = C_p·ω^k + (B + k_e²/R)·ω + T_f − k_e·V/R = 0

For ω ≥ 0 and k ≥ 1, f is increasing and convex, so it has one root when f(0) < 0 (the motor turns)
and none otherwise (friction holds the motor: ω = 0). Newton's method started at an upper bound of the
root descends on it monotonically; a bisection guard keeps it in the bracket for any k.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .params import MotorParams

__all__ = [
    "SteadyState",
    "current_from_speed",
    "steady_state",
    "voltage_from_current_speed",
]

FloatArray = NDArray[np.float64]


class SteadyState(NamedTuple):
    """Steady-state speed [rad/s] and current [A] for each input voltage."""

    omega_rad_s: FloatArray
    current_a: FloatArray


def voltage_from_current_speed(
    params: MotorParams, current_a: ArrayLike, omega_rad_s: ArrayLike
) -> FloatArray:
    """Eq. 9: the voltage the model needs for a measured current and speed, ``V = R·i + k_e·ω``."""
    return params.R_ohm * np.asarray(current_a, dtype=float) + params.k_e * np.asarray(
        omega_rad_s, dtype=float
    )


def current_from_speed(params: MotorParams, omega_rad_s: ArrayLike) -> FloatArray:
    """Eq. 10: the current the model needs to hold a speed, ``i = (C_p·ω^k + B·ω + T_f) / k_t``.

    Negative speeds are treated by their magnitude (a reversed motor loads the same propeller).
    """
    w = np.abs(np.asarray(omega_rad_s, dtype=float))
    return (params.C_p * w**params.k + params.B * w + params.T_f) / params.k_t


def steady_state(
    params: MotorParams, voltage_v: ArrayLike, *, tol_rad_s: float = 1e-9, max_iter: int = 100
) -> SteadyState:
    """Forward solution: steady-state speed and current for arrays of input voltage.

    Voltages below zero are clipped to zero (the ESC does not reverse the motor). Below
    :attr:`MotorParams.start_voltage_v` the motor stands still and draws ``V/R``. NaN voltages give NaN.
    """
    v = np.asarray(voltage_v, dtype=float)
    shape = v.shape
    v = np.clip(v.ravel(), 0.0, None)
    R: float | FloatArray = params.R_ohm
    ke: float | FloatArray = params.k_e
    start: float | FloatArray = params.start_voltage_v
    Cp, k = params.C_p, params.k
    if np.ndim(R) or np.ndim(ke):  # several motors' rows (MotorRows): each element its own motor's R, k_e
        R, ke, start = (np.broadcast_to(x, shape).ravel() for x in (R, ke, start))
    linear: float | FloatArray = params.B + ke * ke / R
    drive = ke * v / R - params.T_f  # −f(0): positive when the motor turns
    # the same test as start_voltage_v, so that a voltage at the start voltage itself (up to rounding of
    # the two forms) stands still
    turning = (drive > 0) & (v > start)
    omega = np.zeros_like(v)
    omega[np.isnan(v)] = np.nan
    if np.any(turning):
        d = drive[turning]
        if isinstance(linear, np.ndarray):
            linear = linear[turning]
        hi = d / linear  # root of the linear part: an upper bound since C_p·ω^k ≥ 0
        if Cp > 0:
            hi = np.minimum(hi, (d / Cp) ** (1.0 / k))  # root of the power part: another upper bound
        lo = np.zeros_like(hi)
        w = _closed_form_start(Cp, linear, d, k, hi)
        if Cp > 0 and k in (2, 3):
            # The closed form is the root up to rounding: one Newton step polishes it.
            f = Cp * w**k + linear * w - d
            w = np.clip(w - f / (Cp * k * w ** (k - 1.0) + linear), 0.0, hi)
            max_iter = 0
        for _ in range(max_iter):
            f = Cp * w**k + linear * w - d
            # Keep the bracket [lo, hi] around the root, then take a Newton step inside it.
            above = f > 0
            hi = np.where(above, w, hi)
            lo = np.where(above, lo, w)
            fprime = Cp * k * np.power(w, k - 1.0, where=w > 0, out=np.zeros_like(w)) + linear
            step = f / fprime
            w_new = w - step
            outside = (w_new < lo) | (w_new > hi)
            w_new = np.where(outside, 0.5 * (lo + hi), w_new)
            done = np.abs(w_new - w) <= tol_rad_s * np.maximum(1.0, w)
            w = w_new
            if np.all(done):
                break
        omega[turning] = w
    current = np.where(turning, (v - ke * omega) / R, v / R)
    return SteadyState(omega.reshape(shape), current.reshape(shape))


def _closed_form_start(
    Cp: float, linear: float | FloatArray, d: FloatArray, k: float, hi: FloatArray
) -> FloatArray:
    """The root itself for k = 1, 2, 3 (closed forms), else the upper bound ``hi`` for Newton to descend from.

    For k = 3, ``ω³ + pω − q = 0`` with p = linear/C_p > 0 has one real root,
    ``ω = 2·sqrt(p/3)·sinh(asinh(1.5·q/p·sqrt(3/p))/3)``, free of the cancellation in Cardano's form.
    Newton then only polishes (one or two steps).
    """
    if Cp == 0 or k == 1:
        return d / (linear + Cp) if k == 1 else hi
    if k == 2:
        return 2.0 * d / (linear + np.sqrt(linear * linear + 4.0 * Cp * d))  # stable quadratic root
    if k == 3:
        p = linear / Cp
        q = d / Cp
        root: FloatArray = 2.0 * np.sqrt(p / 3.0) * np.sinh(np.arcsinh(1.5 * q / p * np.sqrt(3.0 / p)) / 3.0)
        return np.minimum(root, hi)
    return hi
