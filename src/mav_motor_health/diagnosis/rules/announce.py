"""From verdicts to announcements: the sequential test on the fault directions (:mod:`..detection`),
and persistence (:mod:`..persistence`) on the rest (stalls, sensor faults) or on everything."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..._arrays import one_of
from ..detection import (
    DIRECTIONS,
    SequentialCarry,
    direction_evidence,
    equation_evidence,
    held_states,
    named_evidence,
    sequential_alarms_rows,
    with_slow_evidence,
)
from ..persistence import PersistenceCarry, announce
from ..states import Code, MotorState
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["Persistence", "Sequential"]

#: states the sequential test does not judge (persistence announces them)
_NOT_DIRECTIONS = (
    MotorState.F2_1,
    MotorState.F4_2,
    MotorState.STALLED,
    MotorState.SENSOR_FAULT,
    MotorState.NO_DATA,
)


@dataclass(frozen=True)
class Sequential(Rule):
    """A CUSUM per fault direction on the deviations in σ of the motor's noise (``[detection]``): writes
    ``alarms`` and ``detection_level``, and leaves the directions to it (``announced_elsewhere``); with
    ``hold_sigmas``, ``state`` and ``depth`` again where a NORMAL sample departs the announced way by
    that many σ (:mod:`..detection`, "Once announced")."""

    name = "sequential"
    profile: ThresholdProfile

    def new_carry(self) -> SequentialCarry:
        return SequentialCarry()

    def judge(self, frame: Frame, carries: list[SequentialCarry]) -> list[SequentialCarry]:
        profile = self.profile
        if frame.low_pass_s is None:
            raise ValueError(f"profile {profile.name!r}: the sequential test needs a low-passed comparison")
        sigmas = profile.noise_bands
        speed_band = np.asarray(frame.speed_band_rad_s, dtype=float)
        # without a trusted current, the speed is judged against the tree's speed-only band
        alone_band = profile.speed_only_band(speed_band, frame.omega_model_rad_s)
        deviation = frame.omega_judged_rad_s - frame.omega_model_rad_s
        with np.errstate(divide="ignore", invalid="ignore"):
            current_sigma_a = frame.current_band_a / sigmas
            evidence = direction_evidence(
                deviation / (speed_band / sigmas),
                (frame.current_judged_a - frame.current_model_a) / current_sigma_a,
                frame.current_trusted(),
                sigmas,
                z_omega_alone=deviation / (alone_band / sigmas),
            )
        if frame.z_torque is not None:
            # friction and a lighter propeller in the torque balance, where it is judged (rules/equations.py);
            # not a lighter propeller where the sample's own current reads above its band, and each only
            # where the speed departs its way or not at all (friction no faster, a lighter propeller no slower)
            with np.errstate(divide="ignore", invalid="ignore"):
                z_current_read = (frame.current_a - frame.current_model_a) / current_sigma_a
            evidence = equation_evidence(
                frame.z_torque, frame.current_trusted(), evidence, z_current_read, sigmas, deviation
            )
        # the tree names the fault, the test says when it has lasted: a direction gains only on samples
        # the tree (and the rules after it) named that way; elsewhere its evidence counts at most the
        # reference (no gain, and no more loss than the sample's own departure gives)
        read = evidence
        evidence = named_evidence(evidence, frame.state, profile.detection.reference_sigmas)
        # where the slow look named the sample, its own departure too, for the fewer observations it gives
        evidence = with_slow_evidence(
            evidence,
            frame.state,
            frame.slow_evidence,
            profile.detection.reference_sigmas,
            float(getattr(profile.steady, "slow_factor", 0.0)),
        )
        # judged: the steady samples the tree named a motor state on (not a stall, a bad sensor, no data)
        judged = frame.steady & ~one_of(frame.state, _NOT_DIRECTIONS)
        alarms, level, new = sequential_alarms_rows(
            profile.detection,
            frame.time_s,
            evidence,
            2.0 * frame.low_pass_s,
            judged,
            frame.counts,
            carries,
            profile.persistence.max_gap_s,
            frame.design_tau_s,
        )
        frame.alarms, frame.detection_level = alarms, level
        frame.announced_elsewhere = tuple(int(d) for d in DIRECTIONS)
        hold = profile.detection.hold_sigmas
        if hold > 0:
            # once announced, a sample departing that way by the hold's σ reads as the fault (detection.py,
            # "Once announced"); after the test, which these states do not feed
            held, toward = held_states(frame.state, alarms, read, judged, hold)
            if held.any():
                frame.state = np.where(held, alarms, frame.state).astype(frame.state.dtype)
                frame.depth = np.where(held, toward / profile.noise_bands, frame.depth)
        return new


@dataclass(frozen=True)
class Persistence(Rule):
    """Writes ``announced``: a state announced once it has held (the profile's ``[persistence]``), the
    states another rule announces left out; that rule's alarms where persistence announces nothing (a
    stall, a bad sensor come before a direction)."""

    name = "persistence"
    profile: ThresholdProfile

    def new_carry(self) -> PersistenceCarry:
        return PersistenceCarry()

    def judge(self, frame: Frame, carries: list[PersistenceCarry]) -> list[PersistenceCarry]:
        rule = self.profile.persistence
        t, state, activity = frame.time_s, frame.state, frame.activity_v
        rate = np.minimum(frame.depth, rule.max_depth) if rule.max_depth > 1 else None
        hold_s, hold_per_activity_s = rule.hold_s(), rule.hold_per_activity_s()
        persisted = state
        if frame.announced_elsewhere:
            persisted = np.where(one_of(state, frame.announced_elsewhere), Code.NORMAL, state)
            persisted = persisted.astype(state.dtype)
        announced = np.zeros(t.shape, dtype=np.int8)
        new = list(carries)
        for r, count in enumerate(frame.counts):
            announced[r, :count], new[r] = announce(
                hold_s,
                t[r, :count],
                persisted[r, :count],
                frame.eligible[r, :count],
                carries[r],
                rule.max_gap_s,
                hold_per_activity_s=hold_per_activity_s,
                activity=None if activity is None else activity[r, :count],
                rate=None if rate is None else rate[r, :count],
            )
        if frame.alarms is not None:
            announced = np.where(announced == Code.NORMAL, frame.alarms, announced).astype(np.int8)
        frame.announced = announced
        return new
