"""A command paired loosely with its sample (:mod:`..pairing`): where the voltage error it could cause is a
sizeable part of the speed band the current is not used, where it is a sizeable part of the speed-only band
nothing is judged. Applies to a comparison with a moving low-pass (the balance rule) on a source that says
how loosely it pairs (``pairing_s``: one number, or one per sample — a log table's column, the live
agent's samples' —, each sample then weighed with the 95th percentile of the last second's; per sample
the guard always runs, so that a stream split anywhere gives what the whole gives)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..pairing import PairingCarry, pairing_error_rows
from ..plausibility import SensorIssue
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["PairingGuard"]


@dataclass(frozen=True)
class PairingGuard(Rule):
    """Writes ``pairing_error_rad_s``; flags CURRENT_UNPAIRED and takes samples out of ``steady``."""

    name = "pairing"
    profile: ThresholdProfile

    def new_carry(self) -> PairingCarry:
        return PairingCarry()

    def judge(self, frame: Frame, carries: list[PairingCarry]) -> list[PairingCarry]:
        pairing = frame.pairing_s
        if frame.low_pass_s is None or pairing is None or (np.ndim(pairing) == 0 and not pairing):
            return carries
        error, carries = pairing_error_rows(
            frame.params,
            frame.time_s,
            frame.voltage_v,
            frame.omega_model_rad_s,
            pairing,
            frame.low_pass_s,
            carries,
            frame.ragged,
        )
        plaus = self.profile.plausibility
        speed_band = np.asarray(frame.speed_band_rad_s, dtype=float)
        frame.sensor_flags = np.where(
            error > plaus.pairing_current_share * speed_band,
            frame.sensor_flags | SensorIssue.CURRENT_UNPAIRED,
            frame.sensor_flags,
        ).astype(np.int16)
        speed_only_band = self.profile.speed_only_band(frame.speed_band_rad_s, frame.omega_model_rad_s)
        frame.steady = frame.steady & ~(error > plaus.pairing_speed_share * speed_only_band)
        frame.pairing_error_rad_s = error
        return carries
