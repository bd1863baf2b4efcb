"""Each motor's healthy offset from the identified model (:mod:`..noise`): the model the bands are
centred on is the identified one plus the offset identification measured for that motor."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .base import Frame, Rule

__all__ = ["HealthyOffsets"]


@dataclass(frozen=True)
class HealthyOffsets(Rule):
    """Shifts ``omega_model_rad_s`` and ``current_model_a`` of each row by its motor's offsets, where the
    frame has the motors' noise."""

    name = "offsets"

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        if frame.noise is None:
            return carries
        speed = np.array([n.speed_offset_rad_s for n in frame.noise], dtype=float)[:, None]
        current = np.array([n.current_offset_a for n in frame.noise], dtype=float)[:, None]
        if np.any(speed != 0) or np.any(current != 0):
            frame.omega_model_rad_s = frame.omega_model_rad_s + speed
            frame.current_model_a = frame.current_model_a + current
        return carries
