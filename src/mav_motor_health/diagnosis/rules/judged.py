"""Which samples the announcements may count: never a motor fault from a bad sensor, nothing beyond the
speeds the model was checked at (a stall still), nothing at idle."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..plausibility import SensorIssue
from ..states import MotorState
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["TRANSIENT_OK", "Judged"]

#: States a stalled motor shows whatever its input: announced from transient samples too.
TRANSIENT_OK = (MotorState.F2_1, MotorState.F4_2, MotorState.STALLED)
_SPEED_BROKEN = SensorIssue.SPEED_STUCK | SensorIssue.SPEED_RANGE


@dataclass(frozen=True)
class Judged(Rule):
    """Writes ``eligible`` and narrows ``steady``: a broken speed sensor makes SENSOR_FAULT; with
    ``range_margin`` and the motors' noise, samples beyond the identified speeds are not steady; below
    ``min_command`` nothing is."""

    name = "judged"
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        profile, state, noise = self.profile, frame.state, frame.noise
        state[(frame.sensor_flags & _SPEED_BROKEN) != 0] = MotorState.SENSOR_FAULT
        steady = frame.steady
        if profile.judges_within_noise_conditions and noise is not None:
            # beyond the speeds identification checked the model at, in busier air than its flight's or
            # paired more loosely (the noise there is an extrapolation): not judged (a stall still is)
            omega, activity, pairing = frame.omega_model_rad_s, frame.activity_v, frame.pairing_error_rad_s
            known = np.stack(
                [
                    n.known(
                        omega[r],
                        profile.range_margin,
                        None if activity is None else activity[r],
                        None if pairing is None else pairing[r],
                    )
                    for r, n in enumerate(noise)
                ]
            )
            steady = steady & (known | np.isin(state, TRANSIENT_OK))
        eligible = (steady | np.isin(state, TRANSIENT_OK)) & (state != MotorState.NO_DATA)
        if frame.command is not None and profile.min_command > 0:
            idle = np.asarray(frame.command, dtype=float) < profile.min_command  # idle and spin-up
            eligible &= ~idle
            steady = steady & ~idle
        frame.depth[state == MotorState.SENSOR_FAULT] = 1.0
        frame.steady, frame.eligible = steady, eligible
        return carries
