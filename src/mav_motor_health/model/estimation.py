"""Two-step Levenberg–Marquardt estimation of the motor model (paper section II.B, eqs. 8–10).

Step 1 fits R and k_e to eq. 9 (``V = R·i + k_e·ω``); step 2 fits C_p, B and T_f to eq. 10
(``i = (C_p·ω^k + B·ω + T_f)/k_t`` with ``k_t = k_e`` from step 1), choosing the exponent k among
positive integers by least squares, or fitting it as a real number on request.

Like the paper, which fitted averages over five-minute steady points, the fit works on *operating
points*: the measurements are grouped into bins of the input voltage and each bin's means are one point.
Averaging is what keeps the fit unbiased: a least-squares fit on raw samples whose regressors (current,
speed) carry noise is biased toward zero (errors in variables), and i and ω are nearly collinear.

Accuracy, one definition everywhere in this project::

    accuracy % = 100 · (1 − Σ|ȳ_measured − y_model| / Σ|ȳ_measured|)

over the operating points (bin means), i.e. one minus the weighted mean absolute percentage error of the
steady-state means, as the paper compares averaged measurements with the model in Figs. 1 and 2.

**With the ESC map** (:func:`estimate_with_esc`): a test stand that logs the ESC's command and the *bus*
voltage, not the motor's, fits eq. 9 through the ESC (:mod:`.esc`): the idle offset c₀ by a bounded
scalar search, the side the current is read on (input/battery side ``s = d·i``, or motor side ``s = i``)
by the smaller residual, then R, k_e and c₀ together by the same least-squares wrapper; eq. 10 is fitted
on the motor current (``s/d`` on the input side) against the motor voltage ``d·V_bus``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import FitError
from .equations import current_from_speed, steady_state, voltage_from_current_speed
from .esc import (
    DEFAULT_MIN_DUTY,
    IDLE_OFFSET_RANGE,
    ElectricalTerms,
    EscMap,
    fit_electrical_balance,
    search_idle_offset,
)
from .lsq import LeastSquaresFit, accuracy_pct, fit_least_squares
from .params import PARAMETER_UNITS, MotorParams

__all__ = [
    "EscFit",
    "FitResult",
    "LeastSquaresFit",
    "OperatingPoints",
    "SpeedOnlyFit",
    "accuracy_pct",
    "estimate",
    "estimate_speed_only",
    "estimate_with_esc",
    "operating_points",
]

FloatArray = NDArray[np.float64]

DEFAULT_BIN_WIDTH_V = 0.05
DEFAULT_MIN_SAMPLES = 3
INTEGER_EXPONENTS = (1, 2, 3, 4, 5)
#: the ESC's sides a current reading may be on (see :mod:`.esc`)
ESC_CURRENT_SIDES = ("input", "motor")
#: units of the fitted values that are not motor parameters
_OTHER_UNITS = {"idle_offset": "of the command range"}


@dataclass(frozen=True)
class OperatingPoints:
    """Means of voltage, current and speed per bin of input voltage, with the sample count of each."""

    voltage_v: FloatArray
    current_a: FloatArray
    omega_rad_s: FloatArray
    count: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.voltage_v)


def operating_points(
    voltage_v: ArrayLike,
    current_a: ArrayLike,
    omega_rad_s: ArrayLike,
    *,
    bin_width_v: float | None = DEFAULT_BIN_WIDTH_V,
    min_samples: int = DEFAULT_MIN_SAMPLES,
) -> OperatingPoints:
    """Group samples into bins of input voltage and average each (``bin_width_v=None``: no grouping).

    Samples with any non-finite value are left out; bins with fewer than ``min_samples`` samples too.
    """
    v = np.asarray(voltage_v, dtype=float).ravel()
    i = np.asarray(current_a, dtype=float).ravel()
    w = np.asarray(omega_rad_s, dtype=float).ravel()
    ok = np.isfinite(v) & np.isfinite(i) & np.isfinite(w)
    v, i, w = v[ok], i[ok], w[ok]
    if bin_width_v is None:
        return OperatingPoints(v, i, w, np.ones(len(v), dtype=np.int64))
    if bin_width_v <= 0:
        raise FitError(f"bin_width_v must be > 0, got {bin_width_v}")
    keys = np.round(v / bin_width_v).astype(np.int64)
    uniq, inverse, count = np.unique(keys, return_inverse=True, return_counts=True)
    sums = [np.bincount(inverse, weights=x, minlength=len(uniq)) for x in (v, i, w)]
    keep = count >= min_samples
    means = [s[keep] / count[keep] for s in sums]
    return OperatingPoints(means[0], means[1], means[2], count[keep].astype(np.int64))


@dataclass(frozen=True)
class EscFit:
    """The ESC map a bench fit found: the idle offset and the side the current was read on.

    ``current_side`` is "input" (the battery side: the reading is duty × motor current) or "motor";
    ``residual_v`` the RMS residual of the electrical balance [V] under each side at its own best idle
    offset (the smaller one decides the side, unless it was given: ``side_from`` "data" or "given").
    """

    esc: EscMap
    idle_offset_stderr: float
    current_side: str
    residual_v: dict[str, float]
    side_from: str = "data"

    def to_dict(self) -> dict[str, Any]:
        return {
            "idle_offset": self.esc.idle_offset,
            "idle_offset_stderr": self.idle_offset_stderr,
            "current_side": self.current_side,
            "side_from": self.side_from,
            "residual_v": dict(self.residual_v),
        }


@dataclass(frozen=True)
class FitResult:
    """The two-step estimate: the fitted :class:`MotorParams` and how well each equation fits.

    ``esc`` is the ESC map where the fit went through one (:func:`estimate_with_esc`), else None.
    """

    params: MotorParams
    electrical: LeastSquaresFit
    mechanical: LeastSquaresFit
    exponent_rmse_a: dict[float, float]
    forward_accuracy_pct: dict[str, float]
    points: OperatingPoints = field(repr=False)
    exponent_bic: dict[float, float] = field(default_factory=dict)
    esc: EscFit | None = None

    @property
    def stderr(self) -> dict[str, float]:
        return {**self.electrical.stderr, **self.mechanical.stderr}

    @property
    def rmse(self) -> dict[str, float]:
        return {"voltage_v": self.electrical.rmse, "current_a": self.mechanical.rmse}

    @property
    def success(self) -> bool:
        return self.electrical.success and self.mechanical.success

    def to_dict(self) -> dict[str, Any]:
        p = self.params
        out = {
            "params": {"R_ohm": p.R_ohm, "k_e": p.k_e, "C_p": p.C_p, "B": p.B, "T_f": p.T_f, "k": p.k},
            "stderr": self.stderr,
            "rmse": self.rmse,
            "r_squared": {"voltage_v": self.electrical.r_squared, "current_a": self.mechanical.r_squared},
            "accuracy_pct": {
                "voltage_eq9": self.electrical.accuracy_pct,
                "current_eq10": self.mechanical.accuracy_pct,
                **{f"forward_{k}": v for k, v in self.forward_accuracy_pct.items()},
            },
            "exponent_rmse_a": {str(k): v for k, v in self.exponent_rmse_a.items()},
            "n_points": len(self.points),
            "units": PARAMETER_UNITS,
        }
        if self.esc is not None:
            out["esc"] = self.esc.to_dict()
        return out

    def report(self) -> str:
        """A plain-text table of parameters, standard errors and fit statistics."""
        lines = [f"[[Two-step Levenberg-Marquardt fit]]  {len(self.points)} operating points"]
        if self.esc is not None:
            e = self.esc
            at_bound = min(abs(e.esc.idle_offset - b) for b in IDLE_OFFSET_RANGE) < 1e-6
            lines.append(
                f"  ESC map: idle offset {e.esc.idle_offset:.4f} +/- {e.idle_offset_stderr:.2g} of the command "
                "range"
                + (
                    f" (AT THE BOUND of {IDLE_OFFSET_RANGE[0]:g}..{IDLE_OFFSET_RANGE[1]:g})"
                    if at_bound
                    else ""
                )
                + " (full command = full duty); motor voltage = duty x bus voltage"
            )
            lines.append(
                f"  current read on the {e.current_side} side"
                + (" (battery side: duty x motor current)" if e.current_side == "input" else "")
                + f", {e.side_from}; electrical residual "
                + ", ".join(f"{k} side {v:.3g} V" for k, v in e.residual_v.items())
            )
        units = {**PARAMETER_UNITS, **_OTHER_UNITS}
        lines.extend(fit.report(units) for fit in (self.electrical, self.mechanical))
        ks = ", ".join(
            f"k={k:g}: {v:.4g} A" + (f" (BIC {self.exponent_bic[k]:.1f})" if k in self.exponent_bic else "")
            for k, v in self.exponent_rmse_a.items()
        )
        lines.append(f"  exponent choice (current rmse, BIC): {ks}")
        lines.append(f"  k = 3 unless another exponent lowers the BIC by {K_BIC_MARGIN:g} or more")
        lines.append(
            "  forward accuracy from voltage: "
            + ", ".join(f"{k} {v:.2f} %" for k, v in self.forward_accuracy_pct.items())
        )
        return "\n".join(lines)


def fit_electrical(points: OperatingPoints) -> LeastSquaresFit:
    """Step 1, eq. 9: R and k_e from (V, i, ω)."""
    v, i, w = points.voltage_v, points.current_a, points.omega_rad_s
    design = np.column_stack([i, w])
    x0 = np.linalg.lstsq(design, v, rcond=None)[0].astype(np.float64)
    scale = np.array([max(abs(x0[0]), 1e-3), max(abs(x0[1]), 1e-5)])

    def residual(x: FloatArray) -> FloatArray:
        return x[0] * i + x[1] * w - v  # y_t − y_m, eq. 8

    return fit_least_squares(
        residual, x0, ["R_ohm", "k_e"], scale=scale, target=v, title="electrical (eq. 9)"
    )


def fit_mechanical(points: OperatingPoints, k_t: float, k: float | None) -> LeastSquaresFit:
    """Step 2, eq. 10: C_p, B, T_f (and k when ``k`` is None) from (ω, i) with k_t known."""
    i, w = points.current_a, np.abs(points.omega_rad_s)
    k_start = 3.0 if k is None else float(k)
    design = np.column_stack([w**k_start, w, np.ones_like(w)]) / k_t
    col = np.abs(design).max(axis=0)
    col[col == 0] = 1.0
    z0, *_ = np.linalg.lstsq(design / col, i, rcond=None)
    lin0 = z0 / col
    scale = np.abs(lin0)
    scale[scale == 0] = 1.0 / col[scale == 0]
    scale = np.maximum(scale, 1e-3 / col)  # keeps tiny or zero starting values movable
    # propeller load, viscous damping and friction are torques the motor must supply: none is negative
    nonnegative = np.zeros(3)
    if k is not None:

        def residual(x: FloatArray) -> FloatArray:
            return (x[0] * w**k + x[1] * w + x[2]) / k_t - i

        return fit_least_squares(
            residual,
            lin0,
            ["C_p", "B", "T_f"],
            scale=scale,
            lower=nonnegative,
            target=i,
            title="mechanical (eq. 10)",
        )

    def residual_k(x: FloatArray) -> FloatArray:
        return (x[0] * w ** x[3] + x[1] * w + x[2]) / k_t - i

    return fit_least_squares(
        residual_k,
        np.append(lin0, k_start),
        ["C_p", "B", "T_f", "k"],
        scale=np.append(scale, 1.0),
        lower=np.append(nonnegative, K_RANGE[0]),
        upper=np.append(np.full(3, np.inf), K_RANGE[1]),
        target=i,
        title="mechanical (eq. 10)",
    )


#: another propeller exponent replaces the physical k = 3 only where its fit's BIC is lower by at least this
#: (Kass & Raftery: a difference above 10 is "very strong" evidence); a hair of RMSE is not a reason
K_BIC_MARGIN = 10.0
#: the range a fitted real exponent may take
K_RANGE = (0.5, 6.0)


def choose_exponent(bic: Mapping[float, float], default: float = 3.0) -> float:
    """The propeller exponent: ``default`` unless another candidate's BIC is lower by ``K_BIC_MARGIN``."""
    best = min(bic, key=lambda kk: bic[kk])
    if default not in bic:
        return best
    return best if bic[default] - bic[best] >= K_BIC_MARGIN else default


def estimate(
    voltage_v: ArrayLike,
    current_a: ArrayLike,
    omega_rad_s: ArrayLike,
    *,
    k: float | None = None,
    fit_k: bool = False,
    exponents: tuple[int, ...] = INTEGER_EXPONENTS,
    bin_width_v: float | None = DEFAULT_BIN_WIDTH_V,
    min_samples: int = DEFAULT_MIN_SAMPLES,
    name: str = "fitted motor",
) -> FitResult:
    """Estimate the motor model from steady-state measurements (paper section II.B).

    ``voltage_v`` is the voltage applied to the motor (the effective voltage in flight), ``current_a``
    the motor current and ``omega_rad_s`` the mechanical speed. ``k`` fixes the exponent; otherwise it
    is chosen among ``exponents`` by least squares, or fitted as a real number with ``fit_k=True``
    (starting from the best integer).
    """
    points = operating_points(
        voltage_v, current_a, omega_rad_s, bin_width_v=bin_width_v, min_samples=min_samples
    )
    needed = 4 if fit_k else 3
    if len(points) < needed:
        raise FitError(
            f"{len(points)} operating points after grouping by {bin_width_v} V of input voltage; "
            f"the fit needs at least {needed} distinct steady points"
        )
    return _second_step(points, fit_electrical(points), k, fit_k, exponents, name)


def _second_step(
    points: OperatingPoints,
    electrical: LeastSquaresFit,
    k: float | None,
    fit_k: bool,
    exponents: tuple[int, ...],
    name: str,
    esc: EscFit | None = None,
) -> FitResult:
    """Step 2 (eq. 10) on the operating points with step 1's k_e, and the forward accuracy of both."""
    R, k_e = electrical.values["R_ohm"], electrical.values["k_e"]
    if not (R > 0 and k_e > 0):
        raise FitError(
            f"step 1 (eq. 9) gave R = {R:.4g} ohm, k_e = {k_e:.4g} V*s/rad: not a motor; "
            "are voltage, current and speed in volts, amperes and rad/s?"
        )
    candidates = (float(k),) if k is not None else tuple(float(x) for x in exponents)
    fits = {kk: fit_mechanical(points, k_e, kk) for kk in candidates}
    exponent_rmse = {kk: f.rmse for kk, f in fits.items()}
    best_k = choose_exponent({kk: f.bic for kk, f in fits.items()})
    mechanical = fit_mechanical(points, k_e, None) if fit_k and k is None else fits[best_k]
    values = mechanical.values
    params = MotorParams(
        R_ohm=R,
        k_e=k_e,
        C_p=values["C_p"],
        B=values["B"],
        T_f=values["T_f"],
        k=values.get("k", best_k),
        name=name,
    )
    forward = steady_state(params, points.voltage_v)
    forward_acc = {
        "omega": accuracy_pct(points.omega_rad_s, forward.omega_rad_s),
        "current": accuracy_pct(points.current_a, forward.current_a),
    }
    return FitResult(
        params=params,
        electrical=electrical,
        mechanical=mechanical,
        exponent_rmse_a=exponent_rmse,
        forward_accuracy_pct=forward_acc,
        points=points,
        exponent_bic={kk: f.bic for kk, f in fits.items()},
        esc=esc,
    )


def estimate_with_esc(
    command: ArrayLike,
    bus_voltage_v: ArrayLike,
    current_a: ArrayLike,
    omega_rad_s: ArrayLike,
    *,
    side: str | None = None,
    k: float | None = None,
    fit_k: bool = False,
    exponents: tuple[int, ...] = INTEGER_EXPONENTS,
    bin_width_v: float | None = DEFAULT_BIN_WIDTH_V,
    min_samples: int = DEFAULT_MIN_SAMPLES,
    name: str = "fitted motor",
) -> FitResult:
    """Estimate the motor model through the ESC map, from the ESC's command and bus voltage.

    ``command`` is the ESC command as a fraction of its range (0..1), ``bus_voltage_v`` the ESC's supply
    voltage, ``current_a`` the current as measured (battery or motor side: ``side`` "input" or "motor",
    decided by the smaller electrical residual when None), ``omega_rad_s`` the mechanical speed. The
    samples are grouped into operating points by the nominal voltage command × bus voltage as
    :func:`estimate` groups its input voltage. Step 1 finds the idle offset c₀ by the bounded scalar
    search of :mod:`.esc` for each side, then fits R, k_e and c₀ together (least squares, R, k_e ≥ 0, c₀
    in :data:`~.esc.IDLE_OFFSET_RANGE`); step 2 is :func:`estimate`'s on the motor voltage d·V_bus and the
    motor current (the reading over the duty on the input side, at operating points with a duty of at
    least :data:`~.esc.DEFAULT_MIN_DUTY`). ``forward_accuracy_pct["esc_current"]`` compares the reading as
    measured with the model's (duty × motor current on the input side).
    """
    if side is not None and side not in ESC_CURRENT_SIDES:
        raise FitError(f"side must be one of {', '.join(ESC_CURRENT_SIDES)}, got {side!r}")
    c = np.asarray(command, dtype=float).ravel()
    v = np.asarray(bus_voltage_v, dtype=float).ravel()
    s = np.asarray(current_a, dtype=float).ravel()
    w = np.asarray(omega_rad_s, dtype=float).ravel()
    ok = np.isfinite(c) & np.isfinite(v) & np.isfinite(s) & np.isfinite(w)
    c, v, s, w = np.clip(c[ok], 0.0, 1.0), v[ok], s[ok], w[ok]
    if bin_width_v is None:  # every sample its own operating point, as in operating_points()
        bins, min_samples = np.arange(c.size, dtype=np.int64), 1
    elif bin_width_v <= 0:
        raise FitError(f"bin_width_v must be > 0, got {bin_width_v}")
    else:
        bins = np.round(c * v / bin_width_v).astype(np.int64)
    _, index, count = np.unique(bins, return_inverse=True, return_counts=True)
    kept = count[index] >= min_samples
    count = count[count >= min_samples].astype(np.int64)
    terms = ElectricalTerms.from_samples(c[kept], v[kept], w[kept], s[kept], bins[kept])
    needed = 4 if fit_k else 3
    if count.size < needed:
        raise FitError(
            f"{count.size} operating points after grouping by {bin_width_v} V of command x bus voltage; "
            f"the fit needs at least {needed} distinct steady points"
        )
    searched = {sd: search_idle_offset({1: terms}, sd) for sd in ((side,) if side else ESC_CURRENT_SIDES)}
    chosen = min(searched, key=lambda sd: searched[sd][1])
    electrical = _fit_electrical_with_esc(terms, chosen, searched[chosen][0])
    c0 = electrical.values["idle_offset"]
    duty = terms.duty(c0)
    if chosen == "input":  # the motor current is the reading over the duty: undefined near idle
        motor_current, use = terms.s / duty, duty >= DEFAULT_MIN_DUTY
    else:
        motor_current, use = terms.s, duty > 0.0
    points = OperatingPoints(terms.motor_voltage_v(c0)[use], motor_current[use], terms.w[use], count[use])
    if len(points) < needed:
        raise FitError(
            f"{len(points)} operating points above the ESC's idle offset {c0:.3f} (a duty of at least "
            f"{DEFAULT_MIN_DUTY} on the input side); the fit needs at least {needed}"
        )
    esc = EscFit(
        esc=EscMap(idle_offset=c0),
        idle_offset_stderr=electrical.stderr["idle_offset"],
        current_side=chosen,
        residual_v={sd: r[1] for sd, r in searched.items()},
        side_from="given" if side else "data",
    )
    result = _second_step(points, electrical, k, fit_k, exponents, name, esc)
    model_current = steady_state(result.params, points.voltage_v).current_a
    reading = model_current * duty[use] if chosen == "input" else model_current
    forward = {**result.forward_accuracy_pct, "esc_current": accuracy_pct(terms.s[use], reading)}
    return replace(result, forward_accuracy_pct=forward)


def _fit_electrical_with_esc(terms: ElectricalTerms, side: str, c0_start: float) -> LeastSquaresFit:
    """R, k_e and the idle offset c₀ of eq. 9 through the ESC (:mod:`.esc`), started from the scalar
    search's c₀ and the linear fit at it; the residual in volts (each bin divided by its mean duty)."""
    coef, _, _ = fit_electrical_balance(terms, c0_start, side)
    y_start, _, _ = terms.weighted_rows(c0_start, side)

    def residual(x: FloatArray) -> FloatArray:
        y, a, _ = terms.weighted_rows(float(x[2]), side)
        return x[1] * a[:, 0] + x[0] * a[:, 1] - y  # y_t − y_m, eq. 8, in volts

    x0 = np.array([coef[1], coef[0], c0_start])
    scale = np.array([max(abs(x0[0]), 1e-3), max(abs(x0[1]), 1e-5), 0.05])
    return fit_least_squares(
        residual,
        x0,
        ["R_ohm", "k_e", "idle_offset"],
        scale=scale,
        lower=np.array([0.0, 0.0, IDLE_OFFSET_RANGE[0]]),
        upper=np.array([np.inf, np.inf, IDLE_OFFSET_RANGE[1]]),
        target=y_start,
        title=f"electrical through the ESC (eq. 9, {side}-side current)",
    )


# Re-exported for callers that evaluate the fitted equations on their own points.
predict_voltage = voltage_from_current_speed
predict_current = current_from_speed


@dataclass(frozen=True)
class SpeedOnlyFit:
    """A model calibrated on speed alone: the parameters and how well they reproduce the speed."""

    params: MotorParams
    fit: LeastSquaresFit
    points: OperatingPoints = field(repr=False)


def estimate_speed_only(
    voltage_v: ArrayLike,
    omega_rad_s: ArrayLike,
    base: MotorParams,
    *,
    bin_width_v: float | None = DEFAULT_BIN_WIDTH_V,
    min_samples: int = DEFAULT_MIN_SAMPLES,
    wide_span_v: float = 2.0,
    name: str = "speed-only calibration",
) -> SpeedOnlyFit:
    """Calibrate the forward speed ω(V) where no current can be trusted (RPM-only ESCs, a stuck sensor).

    Speed alone identifies only combinations of the parameters (multiply eq. 7 by R:
    ``R·C_p·ω^k + (R·B + k_e²)·ω + R·T_f = k_e·V``), so R, B and k are kept from ``base`` and k_e, C_p
    and T_f are fitted by Levenberg–Marquardt on the operating points' mean speeds (k_e and T_f when the
    input spans less than ``wide_span_v``, as in a hover; k_e alone below a tenth of that). The current the
    result predicts is only as good as ``base``'s R: diagnose with it in speed-only mode.
    """
    v_all = np.asarray(voltage_v, dtype=float).ravel()
    w_all = np.asarray(omega_rad_s, dtype=float).ravel()
    ok = np.isfinite(v_all) & np.isfinite(w_all)
    points = operating_points(
        v_all[ok], np.zeros(ok.sum()), w_all[ok], bin_width_v=bin_width_v, min_samples=min_samples
    )
    if len(points) == 0:
        raise FitError("no operating point (a voltage bin with enough samples) to calibrate the speed on")
    v, w = points.voltage_v, points.omega_rad_s
    # A narrow span of input supports few parameters: a hover gives the local line of ω(V) (k_e and the
    # start voltage through T_f), a single point the speed per volt alone; a wide span also the propeller
    # load that bends the curve.
    span = float(np.ptp(v))
    if span >= wide_span_v and len(points) >= 4:
        names = ["k_e", "C_p", "T_f"]
    elif span >= 0.1 * wide_span_v and len(points) >= 3:
        names = ["k_e", "T_f"]  # slope and start voltage: the local line through the operating points
    else:
        names = ["k_e"]

    def model(x: FloatArray) -> MotorParams:
        values = dict(zip(names, x))
        return base.replace(
            k_e=abs(values["k_e"]),
            C_p=abs(values.get("C_p", base.C_p)),
            T_f=values.get("T_f", base.T_f),
            name=name,
        )

    def residual(x: FloatArray) -> FloatArray:
        return steady_state(model(x), v).omega_rad_s - w

    start = {"k_e": base.k_e, "C_p": max(base.C_p, 1e-14), "T_f": base.T_f}
    typical = {"k_e": base.k_e, "C_p": max(base.C_p, 1e-12), "T_f": max(abs(base.T_f), 1e-3)}
    x0 = np.array([start[n] for n in names])
    fit = fit_least_squares(
        residual, x0, names, scale=np.array([typical[n] for n in names]), target=w, title="forward speed ω(V)"
    )
    params = model(np.array([fit.values[n] for n in names]))
    return SpeedOnlyFit(params=params, fit=fit, points=points)
