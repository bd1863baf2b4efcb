"""``fit --with``: add effects one at a time and watch the error fall, step by step."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ..model.effects.base import Effect
from ..model.effects.fit import EffectsFit, fit_effects, forward_errors
from ..model.effects.user import available_effects, resolve
from ..model.estimation import FitResult
from .data import WorkbenchData, fit_base
from .noise import NoiseFloor, noise_floor

__all__ = ["EffectSteps", "Step", "fit_with_effects"]


@dataclass(frozen=True)
class Step:
    """The model after one more effect: its forward errors on all the data."""

    label: str
    effects: tuple[str, ...]
    rmse_omega_rad_s: float
    rmse_current_a: float
    bic: float
    fit: EffectsFit | None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "label": self.label,
            "effects": list(self.effects),
            "rmse": {"omega_rad_s": self.rmse_omega_rad_s, "current_a": self.rmse_current_a},
            "bic": self.bic,
        }
        if self.fit is not None:
            out["effect_params"] = {n: dict(v) for n, v in self.fit.params.effects}
            out["stderr"] = self.fit.stderr
        return out


@dataclass(frozen=True)
class EffectSteps:
    """The base two-step estimate, then one refit per added effect (cumulative)."""

    base: FitResult
    noise: NoiseFloor
    steps: tuple[Step, ...]

    @property
    def final(self) -> EffectsFit | None:
        return self.steps[-1].fit

    def to_dict(self) -> dict[str, Any]:
        return {"noise_floor": self.noise.to_dict(), "steps": [s.to_dict() for s in self.steps]}

    def report(self) -> str:
        n = self.noise
        lines = [
            f"noise floor ({n.method}): speed {n.omega_rad_s:.3g} rad/s, current {n.current_a:.3g} A",
            f"{'step':44s} {'speed rmse':>12s} {'x noise':>8s} {'current rmse':>13s} {'x noise':>8s} {'BIC':>10s}",
        ]
        for s in self.steps:
            lines.append(
                f"{s.label:44s} {s.rmse_omega_rad_s:9.4g} rad/s {s.rmse_omega_rad_s / n.omega_rad_s:7.2f}x "
                f"{s.rmse_current_a:11.4g} A {s.rmse_current_a / n.current_a:7.2f}x {s.bic:10.1f}"
            )
        if self.final is not None:
            lines += ["", self.final.report()]
        return "\n".join(lines)


def fit_with_effects(
    data: WorkbenchData,
    effect_names: Sequence[str],
    *,
    registry: Mapping[str, Effect] | None = None,
    base: FitResult | None = None,
    max_samples: int = 1500,
) -> EffectSteps:
    """Fit the base model, then add ``effect_names`` one by one, refitting everything at each step."""
    data = data.usable()
    registry = registry if registry is not None else available_effects()
    effects: list[Effect] = resolve(effect_names, registry)
    base = base or fit_base(data)
    nf = noise_floor(data.time_s, data.motor, data.voltage_v, data.omega_rad_s, data.current_a)
    sigma = None
    if math.isfinite(nf.omega_rad_s) and nf.omega_rad_s > 0 and nf.current_a > 0:
        sigma = (nf.omega_rad_s, nf.current_a)
    rw, ri = forward_errors(base.params, [], data.voltage_v, data.omega_rad_s, data.current_a, data.context)
    steps = [Step("base model (two-step LM)", (), _rms(rw), _rms(ri), math.nan, None)]
    start = base.params
    for j in range(len(effects) + 1):
        chosen = effects[:j]
        fit = fit_effects(
            start,
            chosen,
            data.voltage_v,
            data.omega_rad_s,
            data.current_a,
            data.context,
            sigma=sigma,
            max_samples=max_samples,
        )
        ew, ei = forward_errors(
            fit.params, chosen, data.voltage_v, data.omega_rad_s, data.current_a, data.context
        )
        label = "base refitted on forward errors" if j == 0 else f"+ {effects[j - 1].name}"
        steps.append(Step(label, tuple(e.name for e in chosen), _rms(ew), _rms(ei), fit.bic, fit))
        start = fit.params
    return EffectSteps(base, nf, tuple(steps))


def _rms(x: Any) -> float:
    import numpy as np

    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if len(x) else math.nan
