"""A command paired loosely with its sample (:mod:`..pairing`). :class:`PairingGuard` writes each sample's
pairing error, before the bands, which grow with it where identification measured how the vehicle's
deviations do (:mod:`..noise`). :class:`PairingLimits` then, with the profile's absolute bands or a vehicle
file without that measurement: where the error is a sizeable part of the speed band the current is not
used (unless the current departs further than the pairing could move it: below), where it is a sizeable
part of the speed-only band nothing is judged. Applies to a comparison with a
moving low-pass (the balance rule) on a source that says how loosely it pairs (``pairing_s``: one number,
or one per sample — a log table's column, the live agent's samples' —, each sample then weighed with the
95th percentile of the last second's; per sample the guard always runs, so that a stream split anywhere
gives what the whole gives).

**A departure beyond the pairing's reach.** The pairing error is how far the model speed could be off
because the sample's command is up to ``pairing_s`` older or newer than the one the motor saw; along the
model's steady state that moves the model current by at most its slope in the speed times the error. A
judged current further from the model than its band plus that cannot be the pairing's doing, and is kept
where the error alone would set it aside. The case it is for: a propeller breaks, the autopilot answers the
lost thrust by driving that motor's command up, and the pairing error grows with the moving command just
as the motor's current falls far below the model. In the demo (`./dev demo`, the bundled `flight` profile)
the guard set motor 3's current aside for about a quarter of a second there, the motor read ``FAST`` on its
speed alone, and ``F3.1`` was announced 0.42–0.45 s after the damage; with the current kept, 0.14 s
(docs/flight.md, "The pairing guard keeps a current it cannot explain")."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ...model.balance import linearised_slopes
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
        if unpaired.any():  # (most calls set nothing aside: no more work there)
            beyond = self._beyond_the_pairing(frame, error)
            if beyond is not None:
                unpaired = unpaired & ~beyond
        frame.sensor_flags = np.where(
            unpaired, frame.sensor_flags | int(SensorIssue.CURRENT_UNPAIRED), frame.sensor_flags
        ).astype(np.int16)
        frame.steady = frame.steady & ~doubtful
        return carries

    def _beyond_the_pairing(self, frame: Frame, error: NDArray[np.float64]) -> NDArray[np.bool_] | None:
        """Where the judged current departs from the model by more than its band plus the most the
        pairing error could move it (the steady-state current's slope in the speed, ``dI/dω =
        (k·C_p·ω^(k−1) + B)/k_t`` at the model speed, times the error): a departure the pairing cannot
        explain, kept (module doc, "A departure beyond the pairing's reach"); None where the rule wrote no
        judged current."""
        judged, model = frame.current_judged_a, frame.current_model_a
        if judged is None or model is None:
            return None
        g, _ = linearised_slopes(frame.params, frame.omega_model_rad_s)
        slope = g / frame.params.k_t
        departure = np.asarray(judged, dtype=float) - np.asarray(model, dtype=float)
        band = np.where(departure < 0, frame.current_band_below_a, frame.current_band_a)
        with np.errstate(invalid="ignore"):
            return np.abs(departure) > band + slope * error

    def _measured(self, frame: Frame) -> NDArray[np.bool_] | None:
        """Per motor (a column), whether its bands are in units of noise measured with the pairing error
        (and the profile limits the judged samples to the pairing that noise was measured at)."""
        profile, noise = self.profile, frame.noise
        if not (profile.judges_within_noise_conditions and noise is not None):
            return None
        found = np.array([math.isfinite(n.pairing_error_high_rad_s) for n in noise])
        return found.reshape(-1, 1) if found.any() else None
