"""The bands around the model the tree judges against: the profile's absolute ones, or each motor's own
noise times ``noise_bands`` (:mod:`..noise`)."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["Bands"]


@dataclass(frozen=True)
class Bands(Rule):
    """Writes ``speed_band_rad_s``, ``current_band_a`` and ``current_band_below_a`` (half-widths), and with
    the profile's ``equation_bands`` the torque balance's, ``torque_band_nm``."""

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
            # the torque balance's band, where the profile judges in it: NaN for a motor without its noise
            # (no usable current: nothing to judge; said once where a motor with a current has none)
            torque = np.full(shape, np.nan) if profile.equation_bands > 0 else None
            if torque is not None and any(
                not n.has_torque_noise and math.isfinite(n.current_a) for n in noise
            ):
                _warn_without_torque_noise(profile.name)
            # beyond the conditions σ was measured in, where the profile judges there (noise.py)
            reaching = profile.judges_within_noise_conditions and profile.conditions_reach > 1
            exponent = profile.conditions_growth if reaching else 0.0
            # after an input step, wider by what identification measured there (rules/balance.py)
            after = frame.after_step_factor
            for r, motor_noise in enumerate(noise):
                e_r = None if e is None else e[r]
                speed[r], current[r] = motor_noise.sigmas(a[r], e_r)
                widen: NDArray[np.float64] | float = 1.0  # grown beyond the conditions, after a step
                if exponent > 0:
                    widen = motor_noise.growth(
                        frame.omega_model_rad_s[r], profile.range_margin, a[r], e_r, exponent
                    )
                if after is not None:
                    widen = widen * np.where(np.isfinite(after[r]), after[r], 1.0)
                speed[r] *= widen
                current[r] *= widen
                judged_torque = motor_noise.torque_judged
                if torque is not None and judged_torque is not None:
                    torque[r] = judged_torque.sigmas(a[r], e_r) * widen
            frame.speed_band_rad_s = profile.noise_bands * speed
            frame.current_band_a = profile.noise_bands * current
            frame.current_band_below_a = frame.current_band_a.copy()
            if torque is not None:
                frame.torque_band_nm = profile.equation_bands * torque
        else:
            frame.speed_band_rad_s, frame.current_band_a, frame.current_band_below_a = profile.bands(
                frame.judged_voltage_v, frame.activity_v
            )
        return carries


def _warn_without_torque_noise(profile_name: str) -> None:
    """Say once (Python's warnings show each place once) that a vehicle file without the torque's noise
    is judged from the deviations alone, and how to get it."""
    warnings.warn(
        f"profile {profile_name!r} judges friction and a lighter propeller in the torque balance "
        "(equation_bands), and the vehicle's noise has no noise.N.torque_residual_nm (a file written "
        "before it was measured): they are judged from the speed and current deviations instead; "
        "`mav-motor-health fit FLIGHT_LOG --out vehicle.toml` measures it",
        UserWarning,
        stacklevel=2,
    )
