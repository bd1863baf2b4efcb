"""The paper's threshold tree (:mod:`..tree`) as pipeline rules: the tree on every sample, then the slow
look where the tree saw nothing."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..states import MotorState
from ..tree import agreeing_departures, classify_depth
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["SlowLook", "Tree"]


@dataclass(frozen=True)
class Tree(Rule):
    """Writes ``state`` and ``depth``: the tree's verdict on the judged measurement against the bands."""

    name = "tree"
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        frame.state, frame.depth = classify_depth(
            self.profile,
            omega_rad_s=frame.omega_judged_rad_s,
            omega_model_rad_s=frame.omega_model_rad_s,
            current_a=frame.current_judged_a,
            current_model_a=frame.current_model_a,
            voltage_v=frame.judged_voltage_v,
            bus_voltage_v=frame.bus_voltage_v,
            current_trusted=frame.current_trusted(),
            omega_expected_rad_s=frame.omega_expected_rad_s,
            activity_v=frame.activity_v,
            omega_free_rad_s=frame.omega_free_rad_s,
            bands=(frame.speed_band_rad_s, frame.current_band_a, frame.current_band_below_a),
            stall_split_a=self._stall_split(frame),
            stop_cap_rad_s=frame.stop_cap_rad_s,
        )
        return carries

    def _stall_split(self, frame: Frame) -> NDArray[np.float64] | None:
        """The F2.1/F4.2 split of each row where the profile scales it with the motor's typical current
        and the motor's noise has one; None: the profile's split everywhere."""
        profile, noise = self.profile, frame.noise
        if not (profile.stall_split_typical > 0 and noise):
            return None
        typical = np.array([n.current_typical_a for n in noise], dtype=float)
        if not np.isfinite(typical).any():
            return None
        fallback = np.broadcast_to(
            np.asarray(profile.stall_split(frame.bus_voltage_v), dtype=float), frame.shape
        )
        own = profile.stall_split_typical * typical[:, None]
        return np.where(np.isfinite(own), own, fallback)


@dataclass(frozen=True)
class SlowLook(Rule):
    """Where the tree sees nothing, a small lasting departure may still show in the comparison's longer
    averages (the balance rule's slow look): named where speed and current agree on a fault, against the
    bands narrowed to ``fraction``; ``joint_band_sum`` as the tree's (0: 2)."""

    name = "slow_look"
    fraction: float
    joint_band_sum: float = 0.0

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        slow = frame.slow
        if slow is None or not self.fraction > 0:
            return carries
        state = frame.state
        candidates = slow.ready & (state == MotorState.NORMAL) & frame.current_trusted()
        if not np.any(candidates):
            return carries
        slow_state, slow_depth = agreeing_departures(
            slow.delta_omega_rad_s,
            slow.delta_current_a,
            self.fraction * np.asarray(frame.speed_band_rad_s, dtype=float),
            self.fraction
            * np.where(slow.delta_current_a < 0, frame.current_band_below_a, frame.current_band_a),
            self.joint_band_sum or 2.0,
        )
        use = candidates & (slow_state != MotorState.NORMAL)
        state[use] = slow_state[use]
        frame.depth[use] = slow_depth[use]
        return carries
