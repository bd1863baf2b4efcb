"""``compare``: the model against measurements — error statistics, noise floor, where it fails.

Errors are measured − model. The *forward* errors are those of the speed and current predicted from
voltage (and the context, for a model with effects); the *equation* errors are those of each equation
on its own, fed with the measured speed and current: eq. 9's voltage error and eq. 10's current error.
A region (a voltage bin, a time span, a range of a context variable) *fails* when its speed or current
RMS error exceeds the noise floor by more than sampling allows: ``rms > σ·(1.1 + 3/√(2n))`` for n
samples in the region (the RMS of n samples of pure noise scatters by about σ/√(2n)). σ is the noise
floor *of that region* (repeated pairs inside it, see :mod:`.noise`; the global floor when it holds fewer
than 10 pairs), because sensor noise often grows with load.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..model.effects.base import Effect, equation_residuals, solve
from ..model.estimation import accuracy_pct
from ..model.params import MotorParams
from ..model.predict import model_terms
from .data import WorkbenchData, fit_base
from .noise import NoiseFloor, noise_floor, repeat_pairs

__all__ = ["Comparison", "ErrorStats", "Region", "compare"]

FloatArray = NDArray[np.float64]
VOLTAGE_BINS = 10
TIME_SPANS = 10
CONTEXT_BINS = 5
REPORT_REGIONS = 15


@dataclass(frozen=True)
class ErrorStats:
    """Statistics of one error (measured − model)."""

    name: str
    unit: str
    n: int
    bias: float
    rmse: float
    mae: float
    p95_abs: float
    accuracy_pct: float

    @classmethod
    def of(cls, name: str, unit: str, measured: FloatArray, model: FloatArray) -> ErrorStats:
        ok = np.isfinite(measured) & np.isfinite(model)
        e = measured[ok] - model[ok]
        if not len(e):
            return cls(name, unit, 0, math.nan, math.nan, math.nan, math.nan, math.nan)
        return cls(
            name,
            unit,
            len(e),
            float(e.mean()),
            float(np.sqrt(np.mean(e * e))),
            float(np.mean(np.abs(e))),
            float(np.quantile(np.abs(e), 0.95)),
            accuracy_pct(measured[ok], model[ok]),
        )

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class Region:
    """One slice of the data and its errors against the noise floor."""

    kind: str  # "voltage_v", "time_s" or a context variable's name
    lower: float
    upper: float
    n: int
    rmse_omega_rad_s: float
    rmse_current_a: float
    ratio_omega: float
    ratio_current: float
    fails: bool

    def label(self) -> str:
        return f"{self.kind} {self.lower:.4g}..{self.upper:.4g}"

    def to_dict(self) -> dict[str, Any]:
        return {**self.__dict__, "label": self.label()}


@dataclass(frozen=True)
class Comparison:
    """Everything ``compare`` reports, plus the per-sample arrays its plots draw."""

    params: MotorParams
    noise: NoiseFloor
    forward: tuple[ErrorStats, ErrorStats]
    equations: tuple[ErrorStats, ErrorStats]
    regions: tuple[Region, ...]
    samples: dict[str, FloatArray] = field(repr=False, default_factory=dict)

    @property
    def failing(self) -> list[Region]:
        return [r for r in self.regions if r.fails]

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.params.name,
            "effects": [name for name, _ in self.params.effects],
            "noise_floor": self.noise.to_dict(),
            "forward": {s.name: s.to_dict() for s in self.forward},
            "equations": {s.name: s.to_dict() for s in self.equations},
            "at_noise_floor": not self.failing,
            "failing_regions": [r.to_dict() for r in self.failing],
            "regions": [r.to_dict() for r in self.regions],
        }

    def report(self) -> str:
        n = self.noise
        lines = [
            f"model: {self.params.name}"
            + (f" + {', '.join(e for e, _ in self.params.effects)}" if self.params.effects else ""),
            f"noise floor ({n.method}, {n.n_pairs} pairs): speed {n.omega_rad_s:.3g} rad/s, current {n.current_a:.3g} A",
            "",
            f"{'error':34s} {'n':>6s} {'bias':>10s} {'rmse':>10s} {'mae':>10s} {'p95|e|':>10s} {'accuracy':>9s}",
        ]
        for s in (*self.forward, *self.equations):
            lines.append(
                f"{s.name + ' [' + s.unit + ']':34s} {s.n:6d} {s.bias:10.4g} {s.rmse:10.4g} {s.mae:10.4g} "
                f"{s.p95_abs:10.4g} {s.accuracy_pct:8.2f}%"
            )
        fail = self.failing
        lines.append("")
        if not fail:
            lines.append(
                "the forward errors are at the noise floor in every voltage bin, time span and condition"
            )
        else:
            lines.append(
                f"where the error exceeds the noise floor ({len(fail)} of {len(self.regions)} regions):"
            )
            worst = sorted(fail, key=lambda r: -max(r.ratio_omega, r.ratio_current))
            for r in worst[:REPORT_REGIONS]:
                lines.append(
                    f"  {r.label():36s} n={r.n:5d}  speed {r.ratio_omega:5.2f}x  current {r.ratio_current:5.2f}x noise"
                )
            if len(worst) > REPORT_REGIONS:
                lines.append(f"  ... and {len(worst) - REPORT_REGIONS} more (--json lists them all)")
        return "\n".join(lines)


def _edges(x: FloatArray, bins: int, *, equal_width: bool = False) -> FloatArray:
    x = x[np.isfinite(x)]
    if not len(x):
        return np.array([])
    if equal_width:
        return np.linspace(x.min(), x.max(), bins + 1)
    return np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))


def _regions(
    kind: str,
    x: FloatArray,
    rw: FloatArray,
    ri: FloatArray,
    noise: NoiseFloor,
    bins: int,
    equal: bool,
    pairs: tuple[NDArray[np.intp], NDArray[np.intp]],
    measured: tuple[FloatArray, FloatArray],
) -> list[Region]:
    edges = _edges(x, bins, equal_width=equal)
    out: list[Region] = []
    if len(edges) < 2:
        return out
    key = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    key = np.where(np.isfinite(x), key, -1)
    for b in range(len(edges) - 1):
        sel = (key == b) & np.isfinite(rw) & np.isfinite(ri)
        n = int(sel.sum())
        if n < 3:
            continue
        rms_w = float(np.sqrt(np.mean(rw[sel] ** 2)))
        rms_i = float(np.sqrt(np.mean(ri[sel] ** 2)))
        s_w, s_i = noise.omega_rad_s, noise.current_a
        first, second = pairs
        inside = sel[first] & sel[second]
        if noise.method == "repeated" and inside.sum() >= 10:
            dw = measured[0][second[inside]] - measured[0][first[inside]]
            di = measured[1][second[inside]] - measured[1][first[inside]]
            s_w, s_i = float(np.sqrt(np.mean(dw * dw) / 2)), float(np.sqrt(np.mean(di * di) / 2))
        ratio_w = rms_w / s_w if s_w > 0 else math.nan
        ratio_i = rms_i / s_i if s_i > 0 else math.nan
        limit = 1.1 + 3.0 / math.sqrt(2 * n)
        fails = bool((ratio_w > limit) or (ratio_i > limit))
        out.append(
            Region(kind, float(edges[b]), float(edges[b + 1]), n, rms_w, rms_i, ratio_w, ratio_i, fails)
        )
    return out


def compare(
    data: WorkbenchData,
    params: MotorParams | None = None,
    *,
    registry: Mapping[str, Effect] | None = None,
) -> Comparison:
    """Compare ``params`` (default: the base model fitted to ``data``) with the measurements."""
    data = data.usable()
    if params is None:
        params = fit_base(data).params
    terms = model_terms(params, data.voltage_v, data.context, registry)
    model = solve(terms)
    v_res, i_res = equation_residuals(terms, data.omega_rad_s, data.current_a)
    nf = noise_floor(data.time_s, data.motor, data.voltage_v, data.omega_rad_s, data.current_a)
    forward = (
        ErrorStats.of("forward speed", "rad/s", data.omega_rad_s, model.omega_rad_s),
        ErrorStats.of("forward current", "A", data.current_a, model.current_a),
    )
    v_eff = np.broadcast_to(np.asarray(terms.voltage_v, float), v_res.shape)
    equations = (
        ErrorStats.of("eq. 9 voltage", "V", v_eff, v_eff - v_res),
        ErrorStats.of("eq. 10 current", "A", data.current_a, data.current_a - i_res),
    )
    rw = data.omega_rad_s - model.omega_rad_s
    ri = data.current_a - model.current_a
    pairs = repeat_pairs(data.time_s, data.motor, data.voltage_v)
    meas = (data.omega_rad_s, data.current_a)
    regions = _regions("voltage_v", data.voltage_v, rw, ri, nf, VOLTAGE_BINS, True, pairs, meas)
    regions += _regions("time_s", data.time_s, rw, ri, nf, TIME_SPANS, True, pairs, meas)
    for name, x in data.context.items():
        if name == "time_s" or not np.isfinite(x).any() or np.nanstd(x) == 0:
            continue
        regions += _regions(name, x, rw, ri, nf, CONTEXT_BINS, False, pairs, meas)
    samples = {
        "time_s": data.time_s,
        "voltage_v": data.voltage_v,
        "omega_rad_s": data.omega_rad_s,
        "omega_model_rad_s": model.omega_rad_s,
        "current_a": data.current_a,
        "current_model_a": model.current_a,
        "omega_residual_rad_s": rw,
        "current_residual_a": ri,
        "eq9_residual_v": v_res,
        "eq10_residual_a": i_res,
        **{f"context:{k}": v for k, v in data.context.items()},
    }
    return Comparison(params, nf, forward, equations, tuple(regions), samples)
