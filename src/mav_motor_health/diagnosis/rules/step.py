"""The step rule (the paper's testbed): measurements against the steady-state model, after input steps.

A change of input voltage larger than ``step_v`` between two samples is a step, and samples are not steady
for ``settle_s`` after it (:mod:`..steady`). With ``residual_tau_s`` > 0 the tree judges the model plus the
low-passed residual (measured minus model) instead of the measurement itself.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ...errors import ConfigError
from ...model.dynamics import ResponseCarry, first_order_responses
from ...model.equations import SteadyState, steady_state
from ...model.params import MotorParams
from ...model.predict import predict_steady
from ..steady import SteadyCarry, steady_mask_rows
from .base import CompareRule, Frame

__all__ = ["StepCarry", "StepRule", "check_settling", "lowpass_residuals", "steady_model"]


@dataclass(frozen=True)
class StepCarry:
    """What the step and dynamic rules remember about one motor."""

    steady: SteadyCarry = field(default_factory=SteadyCarry)
    speed_residual: ResponseCarry = field(default_factory=ResponseCarry)
    current_residual: ResponseCarry = field(default_factory=ResponseCarry)
    #: the dynamic rule's first-order response of the model speed
    response: ResponseCarry = field(default_factory=ResponseCarry)


@dataclass(frozen=True)
class StepRule(CompareRule):
    """Steady where the input has not stepped by more than ``step_v`` [V] for ``settle_s`` [s]; the
    residuals low-passed with ``residual_tau_s`` [s] (0: not)."""

    kind = "step"

    step_v: float = 0.2
    settle_s: float = 0.3
    residual_tau_s: float = 0.0

    def validate(self) -> None:
        check_settling(self.step_v, self.settle_s)
        if not self.residual_tau_s >= 0:
            raise ConfigError(
                f"{self.residual_tau_s!r}", key="steady.residual_tau_s", expected="a time constant >= 0 s"
            )

    def new_carry(self) -> StepCarry:
        return StepCarry()

    def judge(self, frame: Frame, carries: list[StepCarry]) -> list[StepCarry]:
        model = steady_model(frame.params, frame.voltage_v, frame.context, frame.counts)
        steady, settled = steady_mask_rows(
            self, frame.time_s, frame.voltage_v, [c.steady for c in carries], frame.counts
        )
        self._compared(frame, model, model.omega_rad_s, model.current_a, steady)
        return self._carried(frame, carries, settled, [c.response for c in carries])

    def _compared(
        self,
        frame: Frame,
        model: SteadyState,
        omega_model_rad_s: NDArray[np.float64],
        current_model_a: NDArray[np.float64],
        steady: NDArray[np.bool_],
    ) -> None:
        """Write the comparison of a model prediction into the frame (the step and dynamic rules')."""
        frame.omega_model_rad_s, frame.current_model_a = omega_model_rad_s, current_model_a
        frame.steady = steady
        frame.judged_voltage_v = frame.voltage_v
        frame.omega_expected_rad_s = np.minimum(omega_model_rad_s, model.omega_rad_s)
        frame.omega_free_rad_s = frame.voltage_v / frame.params.k_e  # no fault turns it faster (tree rule 2)

    def _carried(
        self,
        frame: Frame,
        carries: list[StepCarry],
        settled: list[SteadyCarry],
        responses: list[ResponseCarry],
    ) -> list[StepCarry]:
        """The judged measurements (low-passed residuals) into the frame; the rows' new carries."""
        frame.omega_judged_rad_s, frame.current_judged_a, residuals = lowpass_residuals(
            self.residual_tau_s,
            frame,
            [c.speed_residual for c in carries] + [c.current_residual for c in carries],
        )
        rows = frame.shape[0]
        return [StepCarry(settled[r], residuals[r], residuals[rows + r], responses[r]) for r in range(rows)]


def check_settling(step_v: float, settle_s: float) -> None:
    """Refuse a step that is no step, or a negative wait after it (the step and balance rules')."""
    if not (step_v > 0 and settle_s >= 0):
        raise ConfigError(
            "step_v must be > 0 and settle_s >= 0", key="steady", expected="step_v > 0 V, settle_s >= 0 s"
        )


def steady_model(
    params: MotorParams,
    voltage_v: NDArray[np.float64],
    context: Mapping[str, NDArray[np.float64]] | None,
    counts: list[int],
) -> SteadyState:
    """The steady state at each sample: the base model for all rows at once, a model with fitted effects
    row by row (its context is per motor)."""
    if not params.effects:
        return steady_state(params, voltage_v)
    omega, current = np.full(voltage_v.shape, np.nan), np.full(voltage_v.shape, np.nan)
    for r, count in enumerate(counts):
        row_context = None if context is None else {k: np.asarray(x)[r, :count] for k, x in context.items()}
        model = predict_steady(params, voltage_v[r, :count], row_context)
        omega[r, :count], current[r, :count] = model.omega_rad_s, model.current_a
    return SteadyState(omega, current)


def lowpass_residuals(
    tau_s: float, frame: Frame, carries: list[ResponseCarry]
) -> tuple[NDArray[np.float64], NDArray[np.float64], list[ResponseCarry]]:
    """The measurements as the tree judges them: the model plus the low-passed residual (no low-pass
    with ``tau_s`` = 0); ``carries`` and the new ones: speed residuals, then currents."""
    omega_seen, current_seen = frame.omega_rad_s, frame.current_a
    if not tau_s > 0:
        return omega_seen, current_seen, carries
    # Commands are sampled, the motor sees every control cycle in between: the residual carries the
    # aliased control noise. Low-passing the residual (not the measurement) keeps a fault's lasting
    # offset and averages that noise, as the paper's moving average did for the current.
    rows = frame.shape[0]
    omega_pred, current_pred = frame.omega_model_rad_s, frame.current_model_a
    residuals, carries = first_order_responses(
        frame.time_s,
        np.concatenate([omega_seen - omega_pred, current_seen - current_pred]),
        tau_s,
        carries,
        frame.counts * 2,
    )
    omega_seen = np.where(np.isfinite(omega_seen), omega_pred + residuals[:rows], np.nan)
    current_seen = np.where(np.isfinite(current_seen), current_pred + residuals[rows:], np.nan)
    return omega_seen, current_seen, carries
