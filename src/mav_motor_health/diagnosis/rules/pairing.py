"""A command paired loosely with its sample (:mod:`..pairing`). :class:`PairingGuard` writes each sample's
pairing error, before the bands, which grow with it where identification measured how the vehicle's
deviations do (:mod:`..noise`). :class:`PairingLimits` then, with the profile's absolute bands or a vehicle
file without that measurement: where the error is a sizeable part of the speed band the current is not
used, where it is a sizeable part of the speed-only band nothing is judged. Applies to a comparison with a
moving low-pass (the balance rule) on a source that says how loosely it pairs (``pairing_s``: one number,
or one per sample — a log table's column, the live agent's samples' —, each sample then weighed with the
95th percentile of the last second's; per sample the guard always runs, so that a stream split anywhere
gives what the whole gives)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..pairing import PairingCarry, pairing_error_rows
from ..plausibility import SensorIssue
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["PairingGuard", "PairingLimits"]


@dataclass(frozen=True)
class PairingGuard(Rule):
    """Writes ``pairing_error_rad_s`` (before the bands: a vehicle's noise grows with it)."""

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
            # the balance rule's setting: the guard serves that rule alone
            input_excursion_v=frame.excursions(getattr(self.profile.steady, "excursion_pairing_weight", 0.0)),
        )
        frame.pairing_error_rad_s = error
        return carries


@dataclass(frozen=True)
class PairingLimits(Rule):
    """Flags CURRENT_UNPAIRED and takes samples out of ``steady`` where the pairing error is a sizeable
    part of the bands. Not for a motor whose noise the vehicle file measured with the pairing error
    (``pairing_error_high_rad_s``): its bands grow with the error as its healthy flight's deviations did,
    and beyond that flight's loosest pairing nothing is judged (:class:`~.judged.Judged`)."""

    name = "pairing_limits"
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        error = frame.pairing_error_rad_s
        if error is None:
            return carries
        plaus = self.profile.plausibility
        speed_band = np.asarray(frame.speed_band_rad_s, dtype=float)
        unpaired = error > plaus.pairing_current_share * speed_band
        speed_only_band = self.profile.speed_only_band(frame.speed_band_rad_s, frame.omega_model_rad_s)
        doubtful = error > plaus.pairing_speed_share * speed_only_band
        measured = self._measured(frame)
        if measured is not None:
            unpaired, doubtful = unpaired & ~measured, doubtful & ~measured
        frame.sensor_flags = np.where(
            unpaired, frame.sensor_flags | int(SensorIssue.CURRENT_UNPAIRED), frame.sensor_flags
        ).astype(np.int16)
        frame.steady = frame.steady & ~doubtful
        return carries

    def _measured(self, frame: Frame) -> NDArray[np.bool_] | None:
        """Per motor (a column), whether its bands are in units of noise measured with the pairing error
        (and the profile limits the judged samples to the pairing that noise was measured at)."""
        profile, noise = self.profile, frame.noise
        if not (profile.judges_within_noise_conditions and noise is not None):
            return None
        found = np.array([math.isfinite(n.pairing_error_high_rad_s) for n in noise])
        return found.reshape(-1, 1) if found.any() else None
