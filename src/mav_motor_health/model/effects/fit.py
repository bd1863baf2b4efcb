"""Fitting the model with effects: the two-step estimate first, then one joint output-error refinement.

The foundation's two-step Levenberg–Marquardt (:func:`~mav_motor_health.model.estimation.estimate`)
gives the base parameters. With effects, eqs. 9 and 10 no longer separate (the effects change R, k_e,
C_p... per sample), so the base parameters and the effects' parameters are refined together by bounded
least squares (scipy's trust-region reflective method) on the *forward* errors: the speed and current
the composed model predicts from voltage and context, minus the measurements, each divided by its
noise level. Inputs (voltage, context) are taken as exact, so this output-error fit is not biased the
way a fit on noisy regressors is, and it minimises the very error ``compare`` reports.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import ConfigError, FitError
from ..lsq import LeastSquaresFit, fit_least_squares
from ..params import MotorParams
from .base import Effect, compose, solve

__all__ = ["BASE_PARAMETERS", "EffectsFit", "fit_effects", "forward_errors"]

FloatArray = NDArray[np.float64]
BASE_PARAMETERS = ("R_ohm", "k_e", "C_p", "B", "T_f")
SCREEN_NFEV = 8


@dataclass(frozen=True)
class EffectsFit:
    """A fitted composed model: parameters (base + effects), the joint fit's statistics
    (:class:`~..lsq.LeastSquaresFit`, on the forward errors in units of each output's noise) and the
    forward errors in the outputs' own units."""

    params: MotorParams
    effects: tuple[str, ...]
    fit: LeastSquaresFit = field(repr=False)
    rmse_omega_rad_s: float
    rmse_current_a: float
    n_samples: int
    units: dict[str, str] = field(default_factory=dict)

    @property
    def stderr(self) -> dict[str, float]:
        return self.fit.stderr

    @property
    def n_parameters(self) -> int:
        return self.fit.n_parameters

    @property
    def aic(self) -> float:
        return self.fit.aic

    @property
    def bic(self) -> float:
        return self.fit.bic

    @property
    def success(self) -> bool:
        return self.fit.success

    @property
    def message(self) -> str:
        return self.fit.message

    def to_dict(self) -> dict[str, Any]:
        p = self.params
        return {
            "effects": list(self.effects),
            "params": {k: getattr(p, k) for k in (*BASE_PARAMETERS, "k")},
            "effect_params": {name: dict(values) for name, values in p.effects},
            "stderr": self.stderr,
            "rmse": {"omega_rad_s": self.rmse_omega_rad_s, "current_a": self.rmse_current_a},
            "n_samples": self.n_samples,
            "n_parameters": self.n_parameters,
            "aic": self.aic,
            "bic": self.bic,
            "success": self.success,
        }

    def report(self) -> str:
        p = self.params
        lines = [
            f"[[Output-error fit with effects: {', '.join(self.effects) or 'none'}]]  "
            f"{self.n_samples} samples, {self.n_parameters} parameters",
            f"  forward rmse: speed {self.rmse_omega_rad_s:.4g} rad/s, current {self.rmse_current_a:.4g} A; "
            f"AIC {self.aic:.1f}, BIC {self.bic:.1f}" + ("" if self.success else f"  ({self.message})"),
        ]
        for key in BASE_PARAMETERS:
            lines.append(f"    {key:24s} = {getattr(p, key): .5g} +/- {self.stderr.get(key, math.nan):.3g}")
        for name, values in p.effects:
            for pname, value in values:
                full = f"{name}.{pname}"
                unit = self.units.get(full, "")
                lines.append(
                    f"    {full:24s} = {value: .5g} +/- {self.stderr.get(full, math.nan):.3g}  [{unit}]"
                )
        return "\n".join(lines)


def forward_errors(
    params: MotorParams,
    effects: Sequence[Effect],
    voltage_v: ArrayLike,
    omega_rad_s: ArrayLike,
    current_a: ArrayLike,
    context: Mapping[str, ArrayLike],
) -> tuple[FloatArray, FloatArray]:
    """Measured − predicted speed and current for ``params`` whose effects are ``effects`` (in order)."""
    values = dict(params.effects)
    terms = compose(params, voltage_v, context, [(e, dict(values.get(e.name, ()))) for e in effects])
    model = solve(terms)
    return np.asarray(omega_rad_s, float) - model.omega_rad_s, np.asarray(current_a, float) - model.current_a


def _take(x: ArrayLike, idx: NDArray[np.intp]) -> FloatArray:
    return np.asarray(x, dtype=float)[idx]


def fit_effects(
    start: MotorParams,
    effects: Sequence[Effect],
    voltage_v: ArrayLike,
    omega_rad_s: ArrayLike,
    current_a: ArrayLike,
    context: Mapping[str, ArrayLike],
    *,
    sigma: tuple[float, float] | None = None,
    max_samples: int = 1500,
    vary_k: bool = False,
    k_choices: Sequence[float] | None = None,
) -> EffectsFit:
    """Refine ``start`` (base + effects) on forward errors; returns the motor with fitted ``effects``.

    ``sigma`` = (speed, current) noise levels that weight the two errors (default: the spread of the
    starting model's errors). Effects already in ``start.effects`` start from their values there, others
    from their declared initial values. Samples with a missing input are left out; at most
    ``max_samples`` evenly spread samples are used.

    The propeller exponent k stays fixed (``vary_k`` fits it as a real number), but as in the two-step
    estimate it is chosen among integers: ``k_choices`` (default: the start's k and its integer
    neighbours within 1..5, since a hidden effect can tip the two-step choice) are each fitted and the
    lowest cost wins.
    """
    if k_choices is None:
        k0 = float(start.k)
        k_choices = [k0] + ([k0 - 1, k0 + 1] if k0.is_integer() and not vary_k else [])
        k_choices = [k for k in k_choices if 1 <= k <= 5]
    # Another exponent starts with the same load at a typical speed (C_p·ω_ref^k unchanged); each
    # exponent gets a short screening fit, and only the best one is refined to convergence.
    w = np.abs(np.asarray(omega_rad_s, dtype=float))
    w_ref = float(np.sqrt(np.nanmean(w * w))) if np.isfinite(w).any() else 1.0

    def run(begin: MotorParams, max_nfev: int) -> EffectsFit:
        return _fit_one(
            begin,
            effects,
            voltage_v,
            omega_rad_s,
            current_a,
            context,
            sigma=sigma,
            max_samples=max_samples,
            vary_k=vary_k,
            max_nfev=max_nfev,
        )

    if len(k_choices) == 1:
        return run(start.replace(k=float(k_choices[0])), 200)
    screened = [
        run(start.replace(k=float(k), C_p=start.C_p * w_ref ** (start.k - float(k))), SCREEN_NFEV)
        for k in k_choices
    ]
    best = min(screened, key=lambda f: f.aic)
    refined = run(best.params.replace(name=start.name), 200)
    return min((best, refined), key=lambda f: f.aic)


def _fit_one(
    start: MotorParams,
    effects: Sequence[Effect],
    voltage_v: ArrayLike,
    omega_rad_s: ArrayLike,
    current_a: ArrayLike,
    context: Mapping[str, ArrayLike],
    *,
    sigma: tuple[float, float] | None,
    max_samples: int,
    vary_k: bool,
    max_nfev: int = 200,
) -> EffectsFit:
    v_all = np.asarray(voltage_v, dtype=float)
    w_all = np.asarray(omega_rad_s, dtype=float)
    i_all = np.asarray(current_a, dtype=float)
    ctx_all: dict[str, FloatArray] = {}
    for e in effects:
        ctx_all.update(e.data(context))
    ok = np.isfinite(v_all) & np.isfinite(w_all) & np.isfinite(i_all)
    needs_throttle = any("throttle" in e.needs or "throttle" in e.optional for e in effects)
    for arr in ctx_all.values():
        ok &= np.isfinite(arr)
    if needs_throttle and "throttle" in context:
        ctx_all.setdefault("throttle", np.asarray(context["throttle"], float))
    idx = np.flatnonzero(ok)
    if len(idx) < 6:
        raise FitError(f"{len(idx)} usable samples (finite voltage, speed, current and context); need >= 6")
    if len(idx) > max_samples:
        idx = idx[np.linspace(0, len(idx) - 1, max_samples).round().astype(int)]
    v, w, i = v_all[idx], w_all[idx], i_all[idx]
    ctx = {k: a[idx] for k, a in ctx_all.items()}

    for e in effects:
        for name in e.optional:
            if name in context and name not in ctx:
                ctx[name] = np.asarray(context[name], float)[idx]

    names = list(BASE_PARAMETERS) + (["k"] if vary_k else [])
    x0 = [float(getattr(start, n)) for n in names]
    w_max = float(np.nanmax(np.abs(w))) or 1.0
    torque = start.k_e * max(float(np.nanmax(np.abs(i))), 1e-3)
    scale = [start.R_ohm, start.k_e, torque / w_max**start.k, torque / w_max, torque] + (
        [1.0] if vary_k else []
    )
    lower = [start.R_ohm / 20, start.k_e / 5, 0.0, -np.inf, -np.inf] + ([0.5] if vary_k else [])
    upper = [start.R_ohm * 20, start.k_e * 5, np.inf, np.inf, np.inf] + ([6.0] if vary_k else [])
    existing = dict(start.effects)
    units: dict[str, str] = {}
    for e in effects:
        given = dict(existing.get(e.name, ()))
        for par in e.parameters:
            names.append(f"{e.name}.{par.name}")
            x0.append(float(np.clip(given.get(par.name, par.initial), par.lower, par.upper)))
            span = par.upper - par.lower
            scale.append(
                max(abs(par.initial), span * 1e-3) if math.isfinite(span) else max(abs(par.initial), 1.0)
            )
            lower.append(par.lower)
            upper.append(par.upper)
            units[f"{e.name}.{par.name}"] = par.unit

    def unpack(x: FloatArray) -> tuple[MotorParams, list[tuple[Effect, dict[str, float]]]]:
        base = dict(zip(names[: len(BASE_PARAMETERS) + vary_k], x))
        values = []
        pos = len(BASE_PARAMETERS) + int(vary_k)
        for e in effects:
            vals = {par.name: float(x[pos + j]) for j, par in enumerate(e.parameters)}
            pos += len(e.parameters)
            values.append((e, vals))
        params = (
            start.replace(
                R_ohm=float(base["R_ohm"]),
                k_e=float(base["k_e"]),
                C_p=max(float(base["C_p"]), 0.0),
                B=float(base["B"]),
                T_f=float(base["T_f"]),
                k=float(base.get("k", start.k)),
                effects=(),
            )
            if _valid(base, start)
            else start
        )
        return params, values

    def predict(x: FloatArray) -> tuple[FloatArray, FloatArray]:
        params, values = unpack(x)
        model = solve(compose(params, v, ctx, values))
        return model.omega_rad_s, model.current_a

    if sigma is None:
        w0, i0 = predict(np.asarray(x0))
        sigma = (_rms(w - w0) or 1.0, _rms(i - i0) or 1.0)
    s_w, s_i = (max(float(s), 1e-9) for s in sigma)

    def residual(x: FloatArray) -> FloatArray:
        pw, pi = predict(x)
        r = np.concatenate([(w - pw) / s_w, (i - pi) / s_i])
        return np.where(np.isfinite(r), r, 1e3)

    fit = fit_least_squares(
        residual,
        x0,
        names,
        scale=scale,
        lower=lower,
        upper=upper,
        title=f"output-error fit with effects: {', '.join(e.name for e in effects) or 'none'}",
        max_nfev=max_nfev,
    )
    x = fit.x
    params, values = unpack(x)
    try:
        fitted = MotorParams(
            R_ohm=params.R_ohm,
            k_e=params.k_e,
            C_p=params.C_p,
            B=params.B,
            T_f=params.T_f,
            k=params.k,
            name=start.name,
            effects=tuple((e.name, tuple((k, float(val)) for k, val in vals.items())) for e, vals in values),
        )
    except ConfigError as exc:
        raise FitError(
            f"the fit with effects {[e.name for e in effects]} left the valid range: {exc}"
        ) from exc
    pw, pi = predict(x)
    return EffectsFit(
        params=fitted,
        effects=tuple(e.name for e in effects),
        fit=fit,
        rmse_omega_rad_s=_rms(w - pw),
        rmse_current_a=_rms(i - pi),
        n_samples=len(idx),
        units=units,
    )


def _valid(base: Mapping[str, float], start: MotorParams) -> bool:
    R, ke, B = base["R_ohm"], base["k_e"], base["B"]
    return bool(R > 0 and ke > 0 and B + ke * ke / R > 0 and all(math.isfinite(x) for x in base.values()))


def _rms(x: FloatArray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if len(x) else math.nan
