"""The dynamic rule (flight, a motor with a known inertia J): the steady-state prediction passed through
the motor's own first-order response (:mod:`...model.dynamics`).

Measurements are compared with that response, and a sample counts as quasi-steady where the response has
caught up with the steady state to within ``lag_fraction`` of the speed and current bands and the input
has not stepped (the step rule's ``step_v`` and ``settle_s``). A model without J is judged by the step
rule.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from ...model.dynamics import first_order_responses, time_constant_s
from ...model.equations import current_from_speed
from ..steady import steady_mask_rows
from .base import Frame
from .step import StepCarry, StepRule, steady_model

__all__ = ["DynamicRule"]


@dataclass(frozen=True)
class DynamicRule(StepRule):
    """The step rule's settings, and ``lag_fraction``: the share of the bands within which the response
    must have caught up with the steady state."""

    kind = "dynamic"

    lag_fraction: float = 0.5

    def validate(self) -> None:
        super().validate()
        if not self.lag_fraction > 0:
            raise ConfigError(f"{self.lag_fraction!r}", key="steady.lag_fraction", expected="a fraction > 0")

    def judge(self, frame: Frame, carries: list[StepCarry]) -> list[StepCarry]:
        params = frame.params
        if params.J_kg_m2 is None:
            return super().judge(frame, carries)
        t, v = frame.time_s, frame.voltage_v
        model = steady_model(params, v, frame.context, frame.counts)
        tau = time_constant_s(params, model.omega_rad_s)
        omega_pred, responses = first_order_responses(
            t, model.omega_rad_s, tau, [c.response for c in carries], frame.counts
        )
        turning = omega_pred > 0
        # Current from the torque balance (eq. 7 plus the inertia's share, J·dω/dt with dω/dt of the
        # first-order response), not from eq. 2: eq. 2 would turn every sampled command jitter into
        # current jitter divided by R (6 A per volt on the paper's motor).
        accel = (model.omega_rad_s - omega_pred) / tau
        current_pred = np.where(
            turning,
            current_from_speed(params, omega_pred) + params.J_kg_m2 * accel / params.k_t,
            model.current_a,
        )
        # The input is known only at the samples: a sample is quasi-steady where the response has
        # caught up with the steady state and the input has not stepped since the last samples (a
        # command that jumps between samples hides what the motor saw in between).
        held, settled = steady_mask_rows(self, t, v, [c.steady for c in carries], frame.counts)
        lag, profile = self.lag_fraction, frame.profile
        steady = (
            held
            & (np.abs(omega_pred - model.omega_rad_s) <= lag * profile.speed_band_rad_s)
            & (np.abs(current_pred - model.current_a) <= lag * profile.current_halfwidth_a(v))
        )
        self._compared(frame, model, omega_pred, current_pred, steady)
        return self._carried(frame, carries, settled, responses)
