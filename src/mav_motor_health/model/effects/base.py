"""The composed steady-state model: the paper's equations with every coefficient free to vary per sample.

An *effect* is a pure function that takes the model's terms (per-sample arrays), its own parameter values
and the measured context variables, and returns changed terms. The model is the base
(:class:`~mav_motor_health.model.params.MotorParams`) plus a list of effects applied in order. The terms
are those of eqs. 2 and 7, generalised::

    V_eff       = R·i + k_e·ω                                  (eq. 2, voltage at the windings)
    k_e·i       = C_p·ω^k + B2·ω² + B·ω + T_f                  (eq. 7 with a thrust-loaded ω² term)
    i_measured  = current_scale·i + current_offset_a           (what the sensor reports)

so the forward solution stays one monotone scalar equation per sample,
``f(ω) = C_p·ω^k + B2·ω² + (B + k_e²/R)·ω + T_f − k_e·V_eff/R = 0``, solved by the project's one solver
(:func:`~mav_motor_health.model.solve.turning_speed`), as :func:`~mav_motor_health.model.equations.
steady_state` solves the model without effects: with no effect applied, :func:`solve` gives its numbers.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import ConfigError
from ..equations import SteadyState
from ..params import MotorParams
from ..solve import turning_speed

__all__ = [
    "Effect",
    "EffectParameter",
    "ModelTerms",
    "base_terms",
    "compose",
    "equation_residuals",
    "solve",
]

FloatArray = NDArray[np.float64]
EffectFunction = Callable[["ModelTerms", Mapping[str, float], Mapping[str, FloatArray]], "ModelTerms"]


@dataclass(frozen=True)
class ModelTerms:
    """Per-sample coefficients of the composed model (arrays or scalars that broadcast together)."""

    voltage_v: Any
    R_ohm: Any
    k_e: Any
    C_p: Any
    k: Any
    B: Any
    T_f: Any
    B2: Any = 0.0
    current_scale: Any = 1.0
    current_offset_a: Any = 0.0

    def replace(self, **changes: Any) -> ModelTerms:
        return replace(self, **changes)

    def arrays(self, n: int) -> dict[str, FloatArray]:
        """Every term as a float array of length ``n``."""
        return {
            f.name: np.broadcast_to(np.asarray(getattr(self, f.name), dtype=float), (n,)).astype(float)
            for f in fields(self)
        }


@dataclass(frozen=True)
class EffectParameter:
    """One parameter of an effect: value range, starting value and the value that switches it off."""

    name: str
    unit: str
    lower: float
    upper: float
    initial: float
    neutral: float = 0.0
    description: str = ""

    def __post_init__(self) -> None:
        if not (self.lower < self.upper):
            raise ConfigError(
                f"bounds [{self.lower}, {self.upper}] are empty", key=self.name, expected="lower < upper"
            )
        for label, value in (("initial", self.initial), ("neutral", self.neutral)):
            if not (self.lower <= value <= self.upper):
                raise ConfigError(
                    f"{label} value {value} lies outside [{self.lower}, {self.upper}]",
                    key=self.name,
                    expected="a value within the bounds",
                )


@dataclass(frozen=True)
class Effect:
    """A physical effect: a pure function of terms, parameters and data, plus what it declares.

    ``needs`` lists the context variables the function reads; ``"a|b"`` means "a, or else b" (the
    function always sees it under the first name). ``optional`` variables are passed when present.
    The physics is written in the function's docstring (:attr:`physics`); ``summary`` defaults to its
    first line.
    """

    name: str
    function: EffectFunction
    parameters: tuple[EffectParameter, ...]
    needs: tuple[str, ...] = ()
    optional: tuple[str, ...] = ()
    summary: str = ""

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ConfigError(f"effect name {self.name!r}", expected="a Python identifier (a TOML key)")
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise ConfigError(f"effect '{self.name}' declares a parameter twice: {names}")
        if not self.summary:
            first = (self.function.__doc__ or self.name).strip().splitlines()[0]
            object.__setattr__(self, "summary", first.rstrip("."))

    @property
    def physics(self) -> str:
        return (self.function.__doc__ or self.summary).strip()

    def defaults(self, which: str = "initial") -> dict[str, float]:
        return {p.name: float(getattr(p, which)) for p in self.parameters}

    def missing(self, available: Sequence[str]) -> list[str]:
        """Needed variables absent from ``available`` (each as written in :attr:`needs`)."""
        have = set(available)
        return [need for need in self.needs if not any(alt in have for alt in need.split("|"))]

    def data(self, context: Mapping[str, ArrayLike]) -> dict[str, FloatArray]:
        """The context this effect reads, under its first-choice names; raises if something is missing."""
        out: dict[str, FloatArray] = {}
        for need in self.needs:
            alternatives = need.split("|")
            found = next((alt for alt in alternatives if alt in context), None)
            if found is None:
                raise ConfigError(
                    f"effect '{self.name}' needs the variable {' or '.join(alternatives)}",
                    expected=f"a telemetry column named {' or '.join(alternatives)}",
                )
            out[alternatives[0]] = np.asarray(context[found], dtype=float)
        for name in self.optional:
            if name in context:
                out[name] = np.asarray(context[name], dtype=float)
        return out

    def apply(
        self, terms: ModelTerms, values: Mapping[str, float], context: Mapping[str, ArrayLike]
    ) -> ModelTerms:
        full = self.defaults("neutral")
        unknown = set(values) - set(full)
        if unknown:
            raise ConfigError(
                f"effect '{self.name}' has no parameter(s) {', '.join(sorted(unknown))}",
                key=f"motor.effects.{self.name}",
                expected=f"only {', '.join(full) or 'no parameters'}",
            )
        full.update({k: float(v) for k, v in values.items()})
        return self.function(terms, full, self.data(context))


def base_terms(params: MotorParams, voltage_v: ArrayLike) -> ModelTerms:
    """The paper's model as terms: every coefficient constant, the current measured as it flows."""
    return ModelTerms(
        voltage_v=np.asarray(voltage_v, dtype=float),
        R_ohm=params.R_ohm,
        k_e=params.k_e,
        C_p=params.C_p,
        k=params.k,
        B=params.B,
        T_f=params.T_f,
    )


def compose(
    params: MotorParams,
    voltage_v: ArrayLike,
    context: Mapping[str, ArrayLike],
    effects: Sequence[tuple[Effect, Mapping[str, float]]],
) -> ModelTerms:
    """Base terms with each effect applied in turn."""
    terms = base_terms(params, voltage_v)
    for effect, values in effects:
        terms = effect.apply(terms, values, context)
    return terms


def solve(terms: ModelTerms, *, tol_rad_s: float = 1e-9, max_iter: int = 100) -> SteadyState:
    """Forward solution of the composed model: speed and *measured* current for every sample.

    As :func:`~mav_motor_health.model.equations.steady_state`: negative voltages clip to zero, a motor
    whose drive cannot beat T_f stands still and draws ``V/R``, NaN inputs give NaN.
    """
    v_in = np.asarray(terms.voltage_v, dtype=float)
    shape = v_in.shape
    n = v_in.size
    t = terms.replace(voltage_v=v_in.ravel()).arrays(n)
    v = np.clip(t["voltage_v"], 0.0, None)
    R, ke, Cp, k, B2 = t["R_ohm"], t["k_e"], np.clip(t["C_p"], 0, None), t["k"], np.clip(t["B2"], 0, None)
    linear = np.maximum(t["B"] + ke * ke / R, 1e-9 * ke * ke / R)
    drive = ke * v / R - t["T_f"]
    bad = ~np.isfinite(drive + linear + Cp + k + B2)
    turning = (drive > 0) & ~bad
    omega = np.zeros(n)
    if np.any(turning):
        law = (_one_value(x[turning]) for x in (Cp, k, B2))
        omega[turning] = turning_speed(
            drive[turning], linear[turning], *law, tol_rad_s=tol_rad_s, max_iter=max_iter
        )
    current = np.where(turning, (v - ke * omega) / R, v / R)
    measured = t["current_scale"] * current + t["current_offset_a"]
    omega[bad] = np.nan
    measured[bad] = np.nan
    return SteadyState(omega.reshape(shape), measured.reshape(shape))


def _one_value(values: FloatArray) -> float | FloatArray:
    """``values`` as one number where every sample has the same (the load law of the model without
    effects on it: the solver's closed form applies), else as they are."""
    return float(values[0]) if values.size and bool((values == values[0]).all()) else values


def equation_residuals(
    terms: ModelTerms, omega_rad_s: ArrayLike, current_a: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Each equation on its own, from measured speed and current (measured − model).

    Returns the voltage residual of eq. 9 [V] (``V_eff − R·i − k_e·ω`` with the sensor's scale and
    offset removed from i) and the current residual of eq. 10 [A] (measured current − the current the
    torque balance needs at the measured speed, as the sensor would report it).
    """
    w = np.abs(np.asarray(omega_rad_s, dtype=float))
    i_meas = np.asarray(current_a, dtype=float)
    t = terms.arrays(w.size)
    i_motor = (i_meas - t["current_offset_a"]) / t["current_scale"]
    v_res = t["voltage_v"] - t["R_ohm"] * i_motor - t["k_e"] * w
    torque = np.clip(t["C_p"], 0, None) * w ** t["k"] + t["B2"] * w * w + t["B"] * w + t["T_f"]
    i_res = i_meas - (t["current_scale"] * torque / t["k_e"] + t["current_offset_a"])
    return v_res, i_res
