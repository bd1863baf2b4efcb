"""Per-motor health for the live agent: the diagnosis core fed one sample at a time, plus silence.

:class:`HealthMonitor` feeds every :class:`~.samples.MotorSample` to the same
:class:`~mav_motor_health.diagnosis.pipeline.StreamingDiagnoser` (so to ``diagnose_motor``) that replay
uses in batch, and reports a :class:`StateChange` whenever the *published* state of a motor changes. The
published state is the core's announced state, except ``NO_DATA`` while a motor has sent nothing for
``stale_s`` (the core cannot announce silence: a missing sample never reaches it). No I/O, no clock:
callers pass times on the link's clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..diagnosis.pipeline import StreamingDiagnoser
from ..diagnosis.profile import ThresholdProfile
from ..diagnosis.states import MotorState
from ..model.params import MotorParams
from .samples import MotorSample

__all__ = ["HealthMonitor", "MotorStatus", "StateChange"]


@dataclass(frozen=True)
class StateChange:
    """A motor's published state changed at ``time_s``; ``evidence`` is the sample that decided it."""

    motor: int
    time_s: float
    state: MotorState
    previous: MotorState
    evidence: dict[str, float]


@dataclass
class MotorStatus:
    """What the agent knows about one motor now."""

    motor: int
    state: MotorState = MotorState.NO_DATA  # published (announced, or NO_DATA when silent)
    since_s: float = math.nan  # link time the published state began
    last_sample_s: float = -math.inf
    row: dict[str, Any] = field(default_factory=dict)  # the last diagnosed row

    @property
    def fresh(self) -> bool:
        return self.state != MotorState.NO_DATA


class HealthMonitor:
    """Live diagnosis of ``motors`` motors; ``feed`` per sample, ``check_silence`` now and then."""

    def __init__(
        self,
        params: MotorParams | dict[int, MotorParams],
        profile: ThresholdProfile,
        motors: int = 6,
        stale_s: float = 1.0,
    ) -> None:
        self.diagnoser = StreamingDiagnoser(params, profile)
        self.stale_s = stale_s
        self.status = {n: MotorStatus(n) for n in range(1, motors + 1)}
        self.samples = 0

    def feed(self, sample: MotorSample) -> tuple[dict[str, Any], StateChange | None]:
        """Diagnose one sample; returns its result row and the state change it caused, if any."""
        status = self.status.get(sample.motor)
        if status is None:
            raise KeyError(f"motor {sample.motor} is not one of 1..{len(self.status)}")
        row = self.diagnoser.update(
            sample.motor,
            sample.time_s,
            sample.voltage_v,
            sample.omega_rad_s,
            sample.current_a,
            None if math.isnan(sample.bus_voltage_v) else sample.bus_voltage_v,
        )
        row["bus_voltage_v"] = sample.bus_voltage_v
        row["throttle"] = sample.throttle
        self.samples += 1
        status.row = row
        status.last_sample_s = sample.time_s
        announced = MotorState(int(row["announced"]))  # type: ignore[call-overload]
        return row, self._publish(status, announced, sample.time_s, row)

    def check_silence(self, now_s: float) -> list[StateChange]:
        """Motors silent for longer than ``stale_s`` become ``NO_DATA``; returns those changes."""
        changes = []
        for status in self.status.values():
            if status.state != MotorState.NO_DATA and now_s - status.last_sample_s > self.stale_s:
                change = self._publish(status, MotorState.NO_DATA, now_s, status.row)
                if change is not None:
                    changes.append(change)
        return changes

    def _publish(
        self, status: MotorStatus, state: MotorState, time_s: float, row: dict[str, Any]
    ) -> StateChange | None:
        if state == status.state:
            return None
        change = StateChange(
            motor=status.motor,
            time_s=time_s,
            state=state,
            previous=status.state,
            evidence={
                k: float(row[k])
                for k in ("omega_rad_s", "omega_model_rad_s", "current_a", "current_model_a", "voltage_v")
                if k in row
            },
        )
        status.state = state
        status.since_s = time_s
        return change

    def states(self) -> dict[int, MotorState]:
        return {n: s.state for n, s in self.status.items()}
