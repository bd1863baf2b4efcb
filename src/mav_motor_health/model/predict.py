"""The model's prediction with its fitted effects: what diagnosis, compare and explain evaluate."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

from .effects.base import Effect, ModelTerms, compose, solve
from .effects.library import BUILTIN_EFFECTS
from .effects.user import available_effects, resolve
from .equations import SteadyState, steady_state
from .params import MotorParams

__all__ = ["model_terms", "predict_steady"]


def model_terms(
    params: MotorParams,
    voltage_v: ArrayLike,
    context: Mapping[str, ArrayLike] | None = None,
    registry: Mapping[str, Effect] | None = None,
) -> ModelTerms:
    """The composed model's terms for ``params`` and its ``effects`` (resolved in ``registry``)."""
    names = [name for name, _ in params.effects]
    if registry is None:
        # Built-ins need no search of the installed packages (the live agent calls this per sample).
        registry = BUILTIN_EFFECTS if all(n in BUILTIN_EFFECTS for n in names) else available_effects()
    effects = resolve(names, registry)
    return compose(
        params,
        voltage_v,
        context or {},
        [(e, dict(values)) for e, (_, values) in zip(effects, params.effects)],
    )


def predict_steady(
    params: MotorParams,
    voltage_v: ArrayLike,
    context: Mapping[str, ArrayLike] | None = None,
    *,
    registry: Mapping[str, Effect] | None = None,
) -> SteadyState:
    """Steady speed and (measured) current from voltage and context, with the motor's effects.

    Without effects this is exactly :func:`~mav_motor_health.model.equations.steady_state`.
    """
    if not params.effects:
        return steady_state(params, voltage_v)
    v = np.asarray(voltage_v, dtype=float)
    return solve(model_terms(params, v, context, registry))
