"""The steady-state motor equations as pure, vectorised functions (paper eqs. 2, 7, 9 and 10).

The forward solution eliminates the current between eq. 2 and eq. 7::

    f(ω) = C_p·ω^k + (B + k_e²/R)·ω + T_f − k_e·V/R = 0

For ω ≥ 0 and k ≥ 1, f is increasing and convex, so it has one root when f(0) < 0 (the motor turns)
and none otherwise (friction holds the motor: ω = 0); :func:`~.solve.turning_speed`, the project's one
solver, finds it (the model with effects is solved by the same function).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .params import MotorParams
from .solve import turning_speed

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
        if isinstance(linear, np.ndarray):
            linear = linear[turning]
        omega[turning] = turning_speed(drive[turning], linear, Cp, k, tol_rad_s=tol_rad_s, max_iter=max_iter)
    current = np.where(turning, (v - ke * omega) / R, v / R)
    return SteadyState(omega.reshape(shape), current.reshape(shape))
