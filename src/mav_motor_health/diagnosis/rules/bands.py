"""The bands around the model the tree judges against: the profile's absolute ones, or each motor's own
noise times ``noise_bands`` (:mod:`..noise`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["Bands"]


@dataclass(frozen=True)
class Bands(Rule):
    """Writes ``speed_band_rad_s``, ``current_band_a`` and ``current_band_below_a`` (half-widths)."""

    name = "bands"
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        profile = self.profile
        if profile.noise_bands > 0:
            noise, shape = frame.noise, frame.shape
            if noise is None or len(noise) != shape[0]:
                raise ValueError(
                    f"profile {profile.name!r} needs each motor's noise (noise_bands); none given"
                )
            a = np.zeros(shape) if frame.activity_v is None else frame.activity_v
            e = frame.pairing_error_rad_s
            speed, current = np.empty(shape), np.empty(shape)
            # beyond the conditions σ was measured in, where the profile judges there (noise.py)
            reaching = profile.judges_within_noise_conditions and profile.conditions_reach > 1
            exponent = profile.conditions_growth if reaching else 0.0
            # after an input step, wider by what identification measured there (rules/balance.py)
            after = frame.after_step_factor
            for r, motor_noise in enumerate(noise):
                e_r = None if e is None else e[r]
                speed[r], current[r] = motor_noise.sigmas(a[r], e_r)
                if exponent > 0:
                    grow = motor_noise.growth(
                        frame.omega_model_rad_s[r], profile.range_margin, a[r], e_r, exponent
                    )
                    speed[r] *= grow
                    current[r] *= grow
                if after is not None:
                    widen = np.where(np.isfinite(after[r]), after[r], 1.0)
                    speed[r] *= widen
                    current[r] *= widen
            frame.speed_band_rad_s = profile.noise_bands * speed
            frame.current_band_a = profile.noise_bands * current
            frame.current_band_below_a = frame.current_band_a.copy()
        else:
            frame.speed_band_rad_s, frame.current_band_a, frame.current_band_below_a = profile.bands(
                frame.judged_voltage_v, frame.activity_v
            )
        return carries
