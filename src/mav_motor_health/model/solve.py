"""The project's one steady-state solver: the speed at which a turning motor's torque balances its load.

Eliminating the current between eq. 2 and eq. 7 leaves one scalar equation per sample,

    f(ω) = P·ω^k + Q·ω² + L·ω − D = 0,    L = B + k_e²/R,  D = k_e·V/R − T_f

(P the propeller load C_p, Q a thrust-loaded ω² term that only effects add, D the drive, positive when
the motor turns). For ω ≥ 0 and k ≥ 1, f is increasing and convex, so it has one root when D > 0.
:func:`turning_speed` finds it for every sample at once; the paper's model
(:func:`~.equations.steady_state`, parameters as numbers) and the model with effects
(:func:`~.effects.base.solve`, every coefficient per sample) are two ways in: the base model is the model
with no effects, solved by the same code.

Where the load law is one number for every sample (P, k scalars and no Q), the root has a closed form for
k = 1, 2, 3, which one Newton step polishes; otherwise Newton's method starts at an upper bound of the
root (the linear part's root, the power part's, the quadratic part's) and descends on it, a bisection guard
keeping it in the bracket for any k.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["turning_speed"]

FloatArray = NDArray[np.float64]


def turning_speed(
    drive: FloatArray,
    linear: Any,
    power: Any,
    exponent: Any,
    quadratic: Any = 0.0,
    *,
    tol_rad_s: float = 1e-9,
    max_iter: int = 100,
) -> FloatArray:
    """The root ω > 0 of ``power·ω^exponent + quadratic·ω² + linear·ω = drive`` for each ``drive`` > 0.

    ``linear`` > 0; ``power``, ``quadratic`` ≥ 0; ``linear``, ``power``, ``exponent`` and ``quadratic``
    are numbers or arrays like ``drive`` (one value per sample). Converged where a Newton step moves ω by
    at most ``tol_rad_s`` × max(1, ω)."""
    d = drive
    one_law = np.ndim(power) == 0 and np.ndim(exponent) == 0 and np.ndim(quadratic) == 0 and quadratic == 0
    hi = d / linear  # root of the linear part: an upper bound since the others are ≥ 0
    if one_law:
        if power > 0:
            hi = np.minimum(hi, (d / power) ** (1.0 / exponent))  # root of the power part: another bound
        w = _closed_form_start(power, linear, d, exponent, hi)
        if power > 0 and exponent in (2, 3):
            # The closed form is the root up to rounding: one Newton step polishes it.
            f = power * w**exponent + linear * w - d
            return np.clip(w - f / (power * exponent * w ** (exponent - 1.0) + linear), 0.0, hi)
    else:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            cp = power > 0
            hi = np.where(cp, np.minimum(hi, (d / np.where(cp, power, 1.0)) ** (1.0 / exponent)), hi)
            q = quadratic > 0
            hi = np.where(q, np.minimum(hi, np.sqrt(d / np.where(q, quadratic, 1.0))), hi)
        w = hi.copy()
    lo = np.zeros_like(hi)
    for _ in range(max_iter):
        f = power * w**exponent + linear * w - d
        fprime = power * exponent * np.power(w, exponent - 1.0, where=w > 0, out=np.zeros_like(w)) + linear
        if not one_law:
            f = f + quadratic * w * w
            fprime = fprime + 2.0 * quadratic * w
        # Keep the bracket [lo, hi] around the root, then take a Newton step inside it.
        above = f > 0
        hi = np.where(above, w, hi)
        lo = np.where(above, lo, w)
        w_new = w - f / fprime
        outside = ~((w_new >= lo) & (w_new <= hi))
        w_new = np.where(outside, 0.5 * (lo + hi), w_new)
        done = np.abs(w_new - w) <= tol_rad_s * np.maximum(1.0, w)
        w = w_new
        if np.all(done):
            break
    return w


def _closed_form_start(Cp: float, linear: Any, d: FloatArray, k: float, hi: FloatArray) -> FloatArray:
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
