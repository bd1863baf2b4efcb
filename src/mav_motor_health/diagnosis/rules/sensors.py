"""Can the sensors be believed: the plausibility checks (:mod:`..plausibility`) as a pipeline rule."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..plausibility import PlausibilityCarry, PlausibilityRule, check_motor_rows
from .base import Frame, Rule

__all__ = ["SensorCheck"]


@dataclass(frozen=True)
class SensorCheck(Rule):
    """Writes ``sensor_flags``: the checks of the reported current (the ESC's, where the source gives it)
    and speed, with the flags found across motors (the currents' sum) added."""

    name = "plausibility"
    rule: PlausibilityRule

    def new_carry(self) -> PlausibilityCarry:
        return PlausibilityCarry()

    def judge(self, frame: Frame, carries: list[PlausibilityCarry]) -> list[PlausibilityCarry]:
        reported = frame.current_a if frame.sensor_current_a is None else frame.sensor_current_a
        flags, new = check_motor_rows(
            self.rule,
            frame.time_s,
            frame.command,
            np.asarray(reported, dtype=float),
            frame.omega_rad_s,
            carries,
            frame.ragged,
        )
        frame.sensor_flags = flags if frame.extra_flags is None else flags | frame.extra_flags
        return new
