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

import numpy as np
from numpy.typing import NDArray

from ..diagnosis.pipeline import MotorBatch, StreamingDiagnoser
from ..diagnosis.plausibility import CurrentSumCheck, SensorIssue
from ..diagnosis.profile import ThresholdProfile
from ..diagnosis.states import MotorState
from ..diagnosis.vehicle_check import VehicleFit
from ..model.identify import CurrentReading, EscMap
from ..model.params import MotorParams
from ..model.vehicle import calibrate_columns
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
        esc: EscMap | None = None,
        current: CurrentReading | None = None,
    ) -> None:
        self.diagnoser = StreamingDiagnoser(params, profile, range(1, motors + 1))
        # the vehicle's ESC map and current sensing (identification), applied as replay applies them
        self.esc, self.current = esc, current
        # the ESC currents' sum against the battery monitor, across motors, as replay checks it
        self.current_sum = CurrentSumCheck(profile.plausibility, range(1, motors + 1))
        self.stale_s = stale_s
        self.status = {n: MotorStatus(n) for n in range(1, motors + 1)}
        self.samples = 0
        #: the vehicle check's latest verdict (diagnosis.vehicle_check.VehicleFit)
        self.vehicle_fit = VehicleFit.CHECKING if self.diagnoser.vehicle.applies else VehicleFit.FITS

    def feed(self, sample: MotorSample) -> tuple[dict[str, Any], StateChange | None]:
        """Diagnose one sample; returns its result row and the state change it caused, if any."""
        rows, changes = self.feed_many([sample])
        return rows[0], (changes[0] if changes else None)

    def feed_many(self, samples: list[MotorSample]) -> tuple[list[dict[str, Any]], list[StateChange]]:
        """Diagnose samples (each motor's in time order) in one core call for all motors: same results as
        one by one (the core carries each motor's state), a fraction of the overhead. Returns rows and
        changes."""
        by_motor: dict[int, list[MotorSample]] = {}
        sum_flags: dict[int, list[int]] = {}
        for sample in samples:
            if sample.motor not in self.status:
                raise KeyError(f"motor {sample.motor} is not one of 1..{len(self.status)}")
        esc_current: Any = [s.esc_current_a for s in samples]
        if self.esc is not None:  # the sum check adds true currents, as replay's calibrated table does
            esc_current = calibrate_columns(
                {
                    name: np.array([getattr(s, name) for s in samples], dtype=float)
                    for name in ("throttle", "bus_voltage_v", "esc_current_a")
                },
                self.esc,
                self.current,
            )["esc_current_a"]
        mismatch = self.current_sum.update(
            [s.time_s for s in samples],
            [s.motor for s in samples],
            esc_current,
            [s.battery_current_a for s in samples],
        )
        for sample, bad in zip(samples, mismatch.tolist()):
            by_motor.setdefault(sample.motor, []).append(sample)
            sum_flags.setdefault(sample.motor, []).append(int(SensorIssue.CURRENT_SUM) if bad else 0)
        batches: dict[int, MotorBatch] = {}
        for motor, group in by_motor.items():
            arrays = {
                name: np.array([getattr(s, name) for s in group], dtype=float)
                for name in (
                    "time_s",
                    "voltage_v",
                    "omega_rad_s",
                    "current_a",
                    "bus_voltage_v",
                    "throttle",
                    "esc_current_a",
                    "esc_temp_c",
                )
            }
            arrays = calibrate_columns(arrays, self.esc, self.current)
            batches[motor] = MotorBatch(
                arrays["time_s"],
                arrays["voltage_v"],
                arrays["omega_rad_s"],
                arrays["current_a"],
                arrays["bus_voltage_v"],
                command=arrays["throttle"],
                sensor_current_a=arrays["esc_current_a"],
                extra_flags=np.array(sum_flags[motor], dtype=np.int16),
                context=arrays,  # what a model with fitted effects may read (temperatures, throttle...)
            )
        # every motor's samples in one core call (the same results as motor by motor)
        results: dict[int, dict[str, NDArray]] = self.diagnoser.update_motors(batches)
        # the vehicle check across motors, in arrival order, as replay runs it over the whole log
        position = {motor: 0 for motor in by_motor}
        index = []
        for sample in samples:
            index.append(position[sample.motor])
            position[sample.motor] += 1
        verdict, announced = self.diagnoser.judge_vehicle(
            np.array([s.time_s for s in samples]),
            np.array([s.motor for s in samples]),
            np.array([s.omega_rad_s for s in samples], dtype=float),
            np.array([results[s.motor]["omega_model_rad_s"][k] for s, k in zip(samples, index)]),
            np.array([results[s.motor]["announced"][k] for s, k in zip(samples, index)]),
        )
        for (sample, k), fit, state in zip(zip(samples, index), verdict.tolist(), announced.tolist()):
            results[sample.motor]["announced"][k] = state
            results[sample.motor].setdefault("vehicle_fit", np.zeros(position[sample.motor], dtype=np.int8))[
                k
            ] = fit
        if verdict.size:
            self.vehicle_fit = int(verdict[-1])
        rows: list[dict[str, Any]] = []
        changes: list[StateChange] = []
        for motor, group in by_motor.items():
            status = self.status[motor]
            cols = {name: values.tolist() for name, values in results[motor].items()}  # Python values
            for k, sample in enumerate(group):
                row: dict[str, Any] = {
                    "time_s": sample.time_s,
                    "motor": motor,
                    "omega_rad_s": sample.omega_rad_s,
                    "current_a": sample.current_a,
                    "voltage_v": sample.voltage_v,
                    "bus_voltage_v": sample.bus_voltage_v,
                    "throttle": sample.throttle,
                    "esc_current_a": sample.esc_current_a,
                    **{name: values[k] for name, values in cols.items()},
                }
                rows.append(row)
                status.row = row
                status.last_sample_s = sample.time_s
                if row["announced"] != status.state:
                    change = self._publish(status, MotorState(row["announced"]), sample.time_s, row)
                    if change is not None:
                        changes.append(change)
            self.samples += len(group)
        changes.sort(key=lambda c: c.time_s)
        return rows, changes

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
