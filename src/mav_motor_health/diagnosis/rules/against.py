"""The speed judged against its siblings' linear prediction (the profile's ``speed_against_siblings``,
:mod:`..prediction`): where the deviation less the siblings' part has the narrower measured noise."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ..._arrays import broadcast_to
from ..noise import after_step_factor
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["AgainstSiblings"]


@dataclass(frozen=True)
class AgainstSiblings(Rule):
    """Where a sample has its siblings' prediction (``speed_siblings_rad_s``, the vehicle stage) and the
    motor's noise has that of its deviation less it (``speed_vs_siblings``), and that σ(a, e) is below
    ``speed_against_siblings`` times the deviation's own (each widened by what identification measured of
    it at the sample's time after a step; not where the wait's bin was not measured for the difference):
    takes the siblings' part off ``omega_judged_rad_s`` and narrows ``speed_band_rad_s`` by the ratio of
    the two (what widened the band beyond the conditions widens it alike), and ``sigma_speed_rad_s`` with
    it (so the band holds as many σ as before: the slow look reads that number). Elsewhere, as the motor
    alone.
    After the bands, before the tree: the tree, the sequential test and its hold read the speed so
    judged."""

    name = "against_siblings"
    reads_siblings: ClassVar[bool] = True
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        explained, noise = frame.speed_siblings_rad_s, frame.noise
        if explained is None or noise is None:
            return carries
        rows = frame.noise_as_rows()
        if not np.isfinite(rows.against_table[:, 0]).any():
            return carries
        a = np.zeros(frame.shape) if frame.activity_v is None else frame.activity_v
        e = frame.pairing_error_rad_s
        if frame.sigma_speed_rad_s is None or frame.sigma_current_a is None:
            frame.sigma_speed_rad_s, frame.sigma_current_a = rows.sigmas(a, e)
        identified = frame.sigma_speed_rad_s
        own = identified
        sigma = broadcast_to(rows.against_sigmas(a, e), frame.shape)
        if frame.since_step_s is not None:
            # after a step each is wider by its own measured widening (the deviation's is in the band)
            settle_s = float(getattr(self.profile.steady, "settle_s", 0.0))
            sigma = sigma * after_step_factor(rows.against_after_step_table, frame.since_step_s, settle_s)
            if frame.after_step_factor is not None:
                own = own * frame.after_step_factor
        with np.errstate(invalid="ignore", divide="ignore"):
            use = np.isfinite(explained) & (sigma < self.profile.speed_against_siblings * own)
            ratio = np.where(use, sigma / own, 1.0)
        frame.omega_judged_rad_s = np.where(
            use, frame.omega_judged_rad_s - explained, frame.omega_judged_rad_s
        )
        frame.speed_band_rad_s = broadcast_to(frame.speed_band_rad_s, frame.shape) * ratio
        # the σ the band holds its number of: the slow look reads the fast band in it (rules/tree.py)
        frame.sigma_speed_rad_s = identified * ratio
        return carries
