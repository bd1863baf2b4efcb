"""``explain``: which physical effect is missing from the model, learned from the residual.

(a) The measured variables are ranked by how strongly the forward residual (speed and current, each in
units of its noise floor) depends on them beyond voltage (:mod:`.dependence`). (b) Each candidate effect
is added to the model, the model is refitted on a training part of the data and scored on held-out
data: the samples are split into 8 blocks in time and every second block is held out, so the test
covers the whole session without sharing neighbouring samples with the training part. The score is the
held-out error ``E = √(mean((r_ω/σ_ω)² + (r_i/σ_i)²)/2)`` — 1 at the noise floor. Candidates are ranked
by E (significant ones first); candidates within 1 % of the best are refitted on the whole training
part (not a subsample) before the final ranking. An effect counts as an explanation only
when it lowers E by more than 1 % *and* improves the training BIC by more than 10; otherwise the report
says plainly that nothing explains the residual beyond noise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import FitError
from ..model.effects.base import Effect
from ..model.effects.fit import EffectsFit, fit_effects, forward_errors
from ..model.effects.user import available_effects, resolve
from ..model.params import MotorParams
from .data import WorkbenchData, fit_base
from .dependence import VariableScore, rank_variables
from .noise import NoiseFloor, noise_floor

__all__ = ["EffectTrial", "Explanation", "explain"]

MIN_IMPROVEMENT = 0.01
TIE_FRACTION = 0.01
TIE_SAMPLES = 2000
MIN_DELTA_BIC = 10.0
BLOCKS = 8
MIN_SAMPLES = 10


@dataclass(frozen=True)
class EffectTrial:
    """One candidate effect: held-out errors before and after adding it, and its fitted parameters."""

    name: str
    heldout_before: float
    heldout_after: float
    rmse_before: dict[str, float]
    rmse_after: dict[str, float]
    delta_bic: float
    parameters: dict[str, float]
    significant: bool
    summary: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "error_before": {"heldout_noise_units": self.heldout_before, **self.rmse_before},
            "error_after": {"heldout_noise_units": self.heldout_after, **self.rmse_after},
            "delta_bic": self.delta_bic,
            "parameters": self.parameters,
            "significant": self.significant,
            "summary": self.summary,
        }


@dataclass(frozen=True)
class Explanation:
    """What explains the model's residual: effects (best first) and variables (strongest first)."""

    params: MotorParams
    noise: NoiseFloor
    heldout_base: float
    effects: tuple[EffectTrial, ...]
    variables: tuple[VariableScore, ...]
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def best(self) -> EffectTrial | None:
        return self.effects[0] if self.effects and self.effects[0].significant else None

    @property
    def significant_variables(self) -> list[VariableScore]:
        return [v for v in self.variables if v.significant]

    def verdict(self) -> str:
        best = self.best
        strong = self.significant_variables
        if best is not None:
            text = (
                f"missing effect: {best.name} ({best.summary}); held-out error "
                f"{best.heldout_before:.2f} -> {best.heldout_after:.2f} noise units"
            )
            if best.heldout_after > 1.1:
                text += "; still above the noise floor, more is missing"
            return text
        if strong:
            names = ", ".join(v.name for v in strong[:3])
            return (
                f"no library effect explains the residual, but it depends on {names}: "
                "write an effect that uses it (docs/workbench.md, --effects-file)"
            )
        if self.heldout_base <= 1.1:
            return "nothing explains the residual beyond noise: the model is at the noise floor"
        return (
            f"the residual is {self.heldout_base:.2f}x the noise floor, but neither a library effect nor a "
            "measured variable explains it beyond noise"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "effects": [e.to_dict() for e in self.effects],
            "variables": [v.to_dict() for v in self.variables],
            "verdict": self.verdict(),
            "explained": self.best is not None,
            "noise_floor": self.noise.to_dict(),
            "heldout_base_noise_units": self.heldout_base,
            "skipped_effects": self.skipped,
        }

    def report(self) -> str:
        n = self.noise
        lines = [
            f"noise floor ({n.method}): speed {n.omega_rad_s:.3g} rad/s, current {n.current_a:.3g} A",
            f"held-out error of the model as given: {self.heldout_base:.3f} noise units (1 = noise floor)",
            "",
            "effects (best first)                held-out E   after   dBIC   speed rmse   current rmse",
        ]
        for e in self.effects:
            mark = "*" if e.significant else " "
            lines.append(
                f" {mark} {e.name:32s} {e.heldout_before:8.3f} {e.heldout_after:8.3f} {e.delta_bic:7.1f} "
                f"{e.rmse_after['omega_rad_s']:9.3g} rad/s {e.rmse_after['current_a']:9.3g} A   "
                + ", ".join(f"{k}={v:.4g}" for k, v in e.parameters.items())
            )
        for name, why in self.skipped.items():
            lines.append(f"   {name:32s} not tried: {why}")
        lines += ["", "variables the residual depends on beyond voltage (distance correlation)"]
        for v in self.variables:
            lines.append(
                f" {'*' if v.significant else ' '} {v.name:24s} {v.score:.3f}  (threshold {v.threshold:.3f})"
            )
        lines += ["", "* = significant", f"verdict: {self.verdict()}"]
        return "\n".join(lines)


def _scaled_error(rw: NDArray, ri: NDArray, noise: tuple[float, float]) -> float:
    ok = np.isfinite(rw) & np.isfinite(ri)
    return float(np.sqrt(np.mean((rw[ok] / noise[0]) ** 2 + (ri[ok] / noise[1]) ** 2) / 2))


def _rms(x: NDArray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if len(x) else math.nan


def explain(
    data: WorkbenchData,
    params: MotorParams | None = None,
    *,
    effects: Mapping[str, Effect] | None = None,
    seed: int = 0,
    max_samples: int = 400,
) -> Explanation:
    """Rank the variables and the candidate effects that explain the residual of ``params`` on ``data``.

    Without ``params`` the base model is first fitted to ``data`` (two-step estimate). ``effects``
    defaults to the built-in and installed effects; those already in ``params`` stay in every candidate.
    """
    data = data.usable()
    if len(data) < MIN_SAMPLES:
        raise FitError(
            f"{data.source or 'the data'}: {len(data)} usable samples; explain needs at least {MIN_SAMPLES} "
            "(half of them are held out to score each effect). `compare` works on fewer."
        )
    registry = dict(effects) if effects is not None else available_effects()
    if params is None:
        params = fit_base(data).params
    existing = resolve([name for name, _ in params.effects], {**available_effects(), **registry})
    nf = noise_floor(data.time_s, data.motor, data.voltage_v, data.omega_rad_s, data.current_a)
    rw, ri = forward_errors(params, existing, data.voltage_v, data.omega_rad_s, data.current_a, data.context)
    sigma = (
        nf.omega_rad_s if math.isfinite(nf.omega_rad_s) and nf.omega_rad_s > 0 else _rms(rw) or 1.0,
        nf.current_a if math.isfinite(nf.current_a) and nf.current_a > 0 else _rms(ri) or 1.0,
    )
    variables = rank_variables(
        np.column_stack([rw / sigma[0], ri / sigma[1]]), data.voltage_v, data.context, seed=seed
    )

    order = np.argsort(data.time_s, kind="stable")
    block = np.empty(len(data), dtype=int)
    block[order] = np.arange(len(data)) * min(BLOCKS, max(len(data) // 3, 2)) // len(data)
    train, test = np.flatnonzero(block % 2 == 0), np.flatnonzero(block % 2 == 1)
    tr, te = data.select(train), data.select(test)

    def fit_on(d: WorkbenchData, effs: Sequence[Effect]) -> EffectsFit:
        return fit_effects(
            params,
            effs,
            d.voltage_v,
            d.omega_rad_s,
            d.current_a,
            d.context,
            sigma=sigma,
            max_samples=max_samples,
        )

    def heldout(fit: EffectsFit, effs: Sequence[Effect]) -> tuple[float, dict[str, float]]:
        ew, ei = forward_errors(fit.params, effs, te.voltage_v, te.omega_rad_s, te.current_a, te.context)
        return _scaled_error(ew, ei, sigma), {"omega_rad_s": _rms(ew), "current_a": _rms(ei)}

    heldout_given = _scaled_error(
        *forward_errors(params, existing, te.voltage_v, te.omega_rad_s, te.current_a, te.context), sigma
    )
    baseline = fit_on(tr, existing)
    e_before, rmse_before = heldout(baseline, existing)
    trials: list[EffectTrial] = []
    skipped: dict[str, str] = {}
    have = [name for name, _ in params.effects]
    for name, effect in registry.items():
        if name in have:
            continue
        missing = effect.missing(list(data.context))
        if missing:
            skipped[name] = f"needs {', '.join(missing)}"
            continue
        effs = [*existing, effect]
        try:
            fit = fit_on(tr, effs)
        except FitError as exc:
            skipped[name] = str(exc)
            continue
        e_after, rmse_after = heldout(fit, effs)
        delta_bic = fit.bic - baseline.bic
        significant = (e_before - e_after) > MIN_IMPROVEMENT * e_before and delta_bic < -MIN_DELTA_BIC
        trials.append(
            EffectTrial(
                name=name,
                heldout_before=e_before,
                heldout_after=e_after,
                rmse_before=rmse_before,
                rmse_after=rmse_after,
                delta_bic=delta_bic,
                parameters=dict(fit.params.effects[-1][1]),
                significant=significant,
                summary=effect.summary,
            )
        )
    # Near-ties at the top (often effects that change the load curve alike) are refitted on the whole
    # training part, not a subsample, and scored again: more data is the only honest tie-breaker.
    trials.sort(key=lambda t: t.heldout_after)
    if len(trials) > 1:
        tied = [
            t
            for t in trials
            if t.heldout_after <= trials[0].heldout_after * (1 + TIE_FRACTION)
            and t.heldout_before - t.heldout_after > MIN_IMPROVEMENT * t.heldout_before
        ]
        if len(tied) > 1:
            for t in tied:
                effs = [*existing, registry[t.name]]
                fit = fit_effects(
                    params,
                    effs,
                    tr.voltage_v,
                    tr.omega_rad_s,
                    tr.current_a,
                    tr.context,
                    sigma=sigma,
                    max_samples=TIE_SAMPLES,
                )
                e_after, rmse_after = heldout(fit, effs)
                trials[trials.index(t)] = replace(
                    t,
                    heldout_after=e_after,
                    rmse_after=rmse_after,
                    parameters=dict(fit.params.effects[-1][1]),
                )
    # A significant effect ranks above an insignificant one with a lower error (stable sorts).
    trials.sort(key=lambda t: t.heldout_after)
    trials.sort(key=lambda t: not t.significant)
    return Explanation(
        params=params,
        noise=nf,
        heldout_base=heldout_given,
        effects=tuple(trials),
        variables=tuple(variables),
        skipped=skipped,
    )
