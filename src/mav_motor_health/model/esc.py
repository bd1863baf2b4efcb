"""The ESC: its command → duty map, and the ideal PWM stage between the bus and the motor.

ESC telemetry reports the ESC's *input* (DC bus) voltage and current, not the motor's. With the ESC
switching the bus at duty d (the normalised motor command, 0..1):

* effective motor voltage  V_m = d · V_bus
* motor current            i_m = i_esc / d      (power balance of a lossless stage: V_bus·i_esc = V_m·i_m)

Assumptions and limits, which docs/flight.md discusses: the command maps linearly to duty (true of
BLHeli/AM32 with calibrated endpoints and of DShot; not of ESCs with a throttle curve or active braking
set up differently); switching and conduction losses are neglected (a few per cent, absorbed by the fitted
R); below ``min_duty`` the division amplifies the current sensor's offset and noise without bound, so
the motor current is left undefined (NaN) there; and an ESC reports its input current *averaged*, the
mean of duty × current, so where the command zigzags between control steps the quotient with the
sample's duty reads high (duty and current rise together). The flight rule therefore never divides: it
weights the model by the duty (:mod:`.balance`); the quotient serves display, the stall current and the
testbed rules.

**The command → duty map and the electrical balance with it**, shared by flight identification
(:mod:`.identify`) and the bench fit (:func:`.estimation.estimate_with_esc`): :class:`EscMap` turns the
command ``c`` (0..1) into ``d = clip((c − c₀)/(1 − c₀), 0, 1)``, ``c₀`` the ESC's idle offset (full
command is full duty: a full-scale error only scales k_e and R and cannot be told from them). With the
current read on the ESC's *input* (battery) side, ``s = d·i``, eq. 9 becomes
``⟨d·(d·V_bus − k_e·ω)⟩ = R·⟨s⟩``; read on the *motor* side, ``s = i``, ``⟨d·V_bus − k_e·ω⟩ = R·⟨s⟩``.
``⟨·⟩`` are bin means (:class:`ElectricalTerms`), every product formed per sample before averaging. For a
given c₀ the balance is linear in (k_e, R) (:func:`fit_electrical_balance`, bounded ≥ 0); c₀ minimises
the pooled residual in a bounded scalar search (:func:`search_idle_offset`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .lsq import fit_linear

__all__ = [
    "DEFAULT_MIN_DUTY",
    "IDLE_OFFSET_RANGE",
    "ElectricalTerms",
    "EscMap",
    "fit_electrical_balance",
    "motor_current_a",
    "motor_voltage_v",
    "search_idle_offset",
]

FloatArray = NDArray[np.float64]

DEFAULT_MIN_DUTY = 0.05
#: the idle offsets c₀ the search considers (of the command range)
IDLE_OFFSET_RANGE = (-0.05, 0.3)
#: bins below this mean duty carry no weight in the electrical balance (they say nothing)
BALANCE_MIN_DUTY = 0.02


def motor_voltage_v(duty: ArrayLike, bus_voltage_v: ArrayLike) -> NDArray[np.float64]:
    """Effective motor voltage [V] = duty × bus voltage (duty clipped to 0..1)."""
    return np.clip(np.asarray(duty, dtype=float), 0.0, 1.0) * np.asarray(bus_voltage_v, dtype=float)


def motor_current_a(
    esc_current_a: ArrayLike, duty: ArrayLike, min_duty: float = DEFAULT_MIN_DUTY
) -> NDArray[np.float64]:
    """Motor current [A] = ESC input current / duty; NaN where the duty is below ``min_duty``."""
    d = np.clip(np.asarray(duty, dtype=float), 0.0, 1.0)
    i = np.asarray(esc_current_a, dtype=float)
    safe = np.where(d >= min_duty, d, np.nan)
    return i / safe


@dataclass(frozen=True)
class EscMap:
    """The ESC's command → duty map: duty = clip((command − idle_offset)/(1 − idle_offset), 0, 1)."""

    idle_offset: float = 0.0

    def duty(self, command: FloatArray) -> FloatArray:
        c0 = self.idle_offset
        return np.clip((np.asarray(command, dtype=float) - c0) / (1.0 - c0), 0.0, 1.0)


def _bin_means(bins: NDArray[np.int64], columns: Mapping[str, FloatArray]) -> dict[str, FloatArray]:
    _, index, counts = np.unique(bins, return_inverse=True, return_counts=True)
    return {name: np.bincount(index, weights=values) / counts for name, values in columns.items()}


@dataclass(frozen=True)
class ElectricalTerms:
    """Bin means of the products the electrical balance needs, for any idle offset c₀."""

    c: FloatArray
    c2v: FloatArray
    cv: FloatArray
    v: FloatArray
    cw: FloatArray
    w: FloatArray
    s: FloatArray

    @classmethod
    def from_samples(
        cls,
        command: FloatArray,
        bus_voltage_v: FloatArray,
        omega_rad_s: FloatArray,
        current_a: FloatArray,
        bins: NDArray[np.int64],
    ) -> ElectricalTerms:
        """Means per bin (in the order of the sorted bin keys) of the samples with a current reading."""
        have = np.isfinite(current_a)
        c, v, w, s = command[have], bus_voltage_v[have], omega_rad_s[have], current_a[have]
        means = _bin_means(
            bins[have], {"c": c, "c2v": c * c * v, "cv": c * v, "v": v, "cw": c * w, "w": w, "s": s}
        )
        return cls(**means)

    def duty(self, c0: float) -> FloatArray:
        """Each bin's mean duty ⟨d⟩ under the idle offset c₀ (unclipped)."""
        return (self.c - c0) / (1.0 - c0)

    def motor_voltage_v(self, c0: float) -> FloatArray:
        """Each bin's mean motor voltage ⟨d·V_bus⟩ under the idle offset c₀ (unclipped)."""
        return (self.cv - c0 * self.v) / (1.0 - c0)

    def rows(self, c0: float, side: str) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(y, x_ke, x_r, mean duty) with y = k_e·x_ke + (R/g)·x_r for the reading's side."""
        scale = 1.0 - c0
        duty = self.duty(c0)
        dv = self.motor_voltage_v(c0)  # ⟨d·V⟩
        if side == "input":
            y = (self.c2v - 2 * c0 * self.cv + c0 * c0 * self.v) / scale**2  # ⟨d²·V⟩
            x_ke = (self.cw - c0 * self.w) / scale  # ⟨d·ω⟩
            return y, x_ke, self.s, duty
        return dv, self.w, self.s, np.ones_like(duty)

    def weighted_rows(self, c0: float, side: str) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(y, A, weight): the balance ``y = A·(k_e, R/g)`` in volts, each bin divided by its mean duty
        (bins at near-zero duty say nothing: weight 0)."""
        y, x_ke, x_r, duty = self.rows(c0, side)
        weight = np.where(duty > BALANCE_MIN_DUTY, 1.0 / np.maximum(duty, BALANCE_MIN_DUTY), 0.0)
        return y * weight, np.column_stack([x_ke, x_r]) * weight[:, None], weight


def fit_electrical_balance(
    terms: ElectricalTerms, c0: float, side: str
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(k_e, R/g) ≥ 0 for one motor, their standard errors, and the residual in volts (per bin, divided
    by the mean duty; NaN where the bin's duty says nothing)."""
    y, a, weight = terms.weighted_rows(c0, side)
    fit = fit_linear(a, y, ("k_e", "R_ohm"), title=f"electrical balance ({side}-side current)")
    return fit.x, fit.x_stderr, np.where(weight > 0, -fit.residual, np.nan)


def search_idle_offset(terms: Mapping[int, ElectricalTerms], side: str) -> tuple[float, float, float]:
    """The idle offset c₀ that minimises the pooled residual, that residual's RMS [V], and c₀'s standard
    error (from the cost's curvature: var = 2·σ²/(n·cost''); infinite at the range's edge)."""
    count = [0]

    def cost(c0: float) -> float:
        total, n = 0.0, 0
        for t in terms.values():
            _, _, resid = fit_electrical_balance(t, c0, side)
            good = np.isfinite(resid)
            total += float(np.sum(resid[good] ** 2))
            n += int(good.sum())
        count[0] = n
        return total / max(n, 1)

    grid = np.linspace(*IDLE_OFFSET_RANGE, 36)
    costs = [cost(c) for c in grid]
    best = int(np.argmin(costs))
    lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)]
    # scipy.optimize where a fit needs it: its import takes about 0.12 s here, which replay and the
    # agent would pay at every start (issue 18; tests/test_cli_arguments.py)
    from scipy.optimize import minimize_scalar

    found = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-5})
    c0 = float(found.x) if found.fun <= costs[best] else float(grid[best])
    at = cost(c0)
    h = 0.005
    curvature = (cost(c0 + h) - 2 * at + cost(c0 - h)) / h**2
    n = max(count[0], 1)
    stderr = math.sqrt(2 * at / (n * curvature)) if curvature > 0 else math.inf
    on_edge = c0 <= grid[0] + 1e-3 or c0 >= grid[-1] - 1e-3
    return c0, math.sqrt(at), math.inf if on_edge else stderr
