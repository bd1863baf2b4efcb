"""Per-motor health for the live agent: the diagnosis core fed one sample at a time, plus silence.

:class:`HealthMonitor` feeds the samples (table columns from :class:`~.samples.SampleAssembler`) to the same
:class:`~mav_motor_health.diagnosis.pipeline.StreamingDiagnoser` (so to ``diagnose_motor``) that replay
uses in batch, and reports a :class:`StateChange` whenever the *published* state of a motor changes. The
published state is the core's announced state (each sample weighed with its own ``pairing_s``, as replay
weighs its table's column), except ``NO_DATA`` while a motor has sent nothing for
``stale_s`` (the core cannot announce silence: a missing sample never reaches it). No I/O, no clock:
callers pass times on the link's clock.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..diagnosis.noise import BandNoise
from ..diagnosis.pipeline import BATCH_COLUMNS, RESIDUAL_COLUMNS, MotorBatch, StreamingDiagnoser
from ..diagnosis.plausibility import CurrentSumCheck, SensorIssue
from ..diagnosis.profile import ThresholdProfile
from ..diagnosis.states import MotorState
from ..diagnosis.vehicle_check import VehicleFit
from ..model.identify import CurrentReading, EscMap
from ..model.params import MotorParams
from ..model.vehicle import calibrate_columns, esc_sum_checked
from .samples import SAMPLE_COLUMNS as _SAMPLE_COLUMNS
from .samples import MotorSample

__all__ = ["HealthMonitor", "MotorStatus", "StateChange"]

#: Those the core sees (its batch, and the context a model with fitted effects may read).
_CORE_COLUMNS = (
    "time_s",
    "voltage_v",
    "omega_rad_s",
    "current_a",
    "bus_voltage_v",
    "throttle",
    "esc_current_a",
    "esc_temp_c",
)
#: The core's inputs (:class:`~..diagnosis.pipeline.MotorBatch`'s names) and the columns they are.
_CORE_INPUTS = BATCH_COLUMNS
#: Columns a source may leave out (the core then takes the sample as paired with the command of its own
#: instant, which did not move between samples)
_OPTIONAL = ("pairing_s", "input_excursion_v", "command_age_s")
#: Those a result row repeats from the sample (before the core's columns).
_ROW_COLUMNS = (
    "time_s",
    "omega_rad_s",
    "current_a",
    "voltage_v",
    "bus_voltage_v",
    "throttle",
    "esc_current_a",
)


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
        noise: Mapping[int, BandNoise] | None = None,
    ) -> None:
        self.diagnoser = StreamingDiagnoser(params, profile, range(1, motors + 1), noise)
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
        """:meth:`feed_columns` for samples as objects (in time order)."""
        return self.feed_columns(
            {name: np.array([getattr(s, name) for s in samples]) for name in _SAMPLE_COLUMNS}
        )

    def feed_columns(
        self, columns: Mapping[str, ArrayLike], rows: bool = True
    ) -> tuple[list[dict[str, Any]], list[StateChange]]:
        """Diagnose samples given as table columns (``time_s``, ``motor``, ... as
        :class:`~.samples.SampleAssembler` gives them; rows in time order) in one core call for all
        motors: same results as one by one (the core carries each motor's state), a fraction of the
        overhead. Returns rows and changes; with ``rows`` False no rows (each motor's last one is still
        its :attr:`MotorStatus.row`, and each change's evidence its sample's): a dict per sample costs
        more than a few samples' share of the core call."""
        motor = np.asarray(columns["motor"], dtype=np.int64)
        if motor.size == 0:
            return [], []
        cols = {
            name: np.asarray(columns[name], dtype=float)
            for name in _SAMPLE_COLUMNS
            if name != "motor" and (name in columns or name not in _OPTIONAL)
        }
        # each sample's pairing with its command, which the balance rule weighs (None: of its own instant)
        pairing = cols.get("pairing_s")
        # ... and each one's command's age (a stall against it, diagnosis/stall.py): both as the source gave
        raw = {"pairing_s": pairing, "command_age_s": cols.get("command_age_s")}
        motors = list(dict.fromkeys(motor.tolist()))  # in the order they first come
        for number in motors:
            if number not in self.status:
                raise KeyError(f"motor {number} is not one of 1..{len(self.status)}")
        esc_current = cols["esc_current_a"]
        if self.esc is not None:  # the sum check adds true currents, as replay's calibrated table does
            esc_current = calibrate_columns(
                {name: cols[name] for name in ("throttle", "bus_voltage_v", "esc_current_a")},
                self.esc,
                self.current,
            )["esc_current_a"]
        if self.esc is not None and not esc_sum_checked(self.current):
            # this vehicle's ESCs and battery monitor are not related (identification): nothing to check
            sum_flags = np.zeros(motor.size, dtype=np.int16)
        else:
            mismatch = self.current_sum.update(cols["time_s"], motor, esc_current, cols["battery_current_a"])
            sum_flags = np.where(mismatch, int(SensorIssue.CURRENT_SUM), 0).astype(np.int16)
        # each sample's place in the core's rows: its motor's row (the motors in the order they first
        # come) and its place among that motor's samples (they come in time order)
        slot_of = {number: r for r, number in enumerate(motors)}
        slot = np.array([slot_of[number] for number in motor.tolist()], dtype=np.intp)
        counts = np.bincount(slot, minlength=len(motors))
        by_motor = np.argsort(slot, kind="stable")
        ends = np.cumsum(counts)
        place = np.empty(motor.size, dtype=np.intp)
        place[by_motor] = np.arange(motor.size) - np.repeat(ends - counts, counts)
        groups = {number: by_motor[end - count : end] for number, count, end in zip(motors, counts, ends)}
        given = [name for name in (*_CORE_COLUMNS, "input_excursion_v") if name in cols]
        calibrated = calibrate_columns({name: cols[name] for name in given}, self.esc, self.current)
        if self.diagnoser.together(motors):
            # every motor's samples laid out as the core's rows at once (one scatter per column), one core
            # call, the results gathered back in the samples' order: the same as a batch per motor
            # (update_motors), without building one
            width = int(counts.max())

            def laid_out(values: NDArray[Any] | None, pad: float = np.nan) -> NDArray[Any] | None:
                if values is None:
                    return None
                out = np.full((len(motors), width), pad, dtype=values.dtype)
                out[slot, place] = values
                return out

            inputs = {
                name: laid_out(raw[column] if column in raw else calibrated.get(column))
                for name, column in _CORE_INPUTS.items()
            }
            inputs["extra_flags"] = laid_out(sum_flags, 0)
            laid = self.diagnoser.update_rows(motors, inputs, counts.tolist())
            results = {name: values[slot, place] for name, values in laid.items()}
        else:
            batches: dict[int, MotorBatch] = {}
            for number, index in groups.items():
                arrays = {name: calibrated[name][index] for name in _CORE_COLUMNS}
                batches[number] = MotorBatch(
                    arrays["time_s"],
                    arrays["voltage_v"],
                    arrays["omega_rad_s"],
                    arrays["current_a"],
                    arrays["bus_voltage_v"],
                    command=arrays["throttle"],
                    sensor_current_a=arrays["esc_current_a"],
                    extra_flags=sum_flags[index],
                    pairing_s=None if pairing is None else pairing[index],
                    command_age_s=None if raw["command_age_s"] is None else raw["command_age_s"][index],
                    input_excursion_v=(
                        calibrated["input_excursion_v"][index] if "input_excursion_v" in calibrated else None
                    ),
                    context=arrays,  # what a model with fitted effects may read (temperatures, throttle...)
                )
            # every motor's samples in one core call where they share a model (the same results as motor
            # by motor)
            by_number = self.diagnoser.update_motors(batches)
            results = {}
            for name, first in by_number[motors[0]].items():
                results[name] = np.empty(motor.size, dtype=first.dtype)
                for number, index in groups.items():
                    results[name][index] = by_number[number][name]
        # the vehicle check across motors, in the rows' order, as replay runs it over the whole log
        verdict, announced = self.diagnoser.judge_vehicle(
            cols["time_s"], motor, cols["omega_rad_s"], results["omega_model_rad_s"], results["announced"]
        )
        results["announced"] = announced.astype(results["announced"].dtype, copy=False)
        results["vehicle_fit"] = verdict.astype(np.int8, copy=False)
        if verdict.size:
            self.vehicle_fit = int(verdict[-1])
        # rows as Python values: the sample's columns, then the core's (a column's list each, a row's
        # dict zipped from them)
        names = ("time_s", "motor", *_ROW_COLUMNS[1:], *results)
        values = [cols["time_s"].tolist(), motor.tolist()]
        values += [cols[name].tolist() for name in _ROW_COLUMNS[1:]]
        values += [column.tolist() for column in results.values()]
        every = [dict(zip(names, row)) for row in zip(*values)] if rows else None

        def row_at(i: int) -> dict[str, Any]:
            return dict(zip(names, [column[i] for column in values]))

        all_rows: list[dict[str, Any]] = []
        changes: list[StateChange] = []
        states = values[names.index("announced")]
        times = values[0]
        for number, index in groups.items():
            status = self.status[number]
            at = index.tolist()
            made = [every[i] for i in at] if every is not None else None
            all_rows += made or []
            for k, i in enumerate(at):
                if states[i] != status.state:
                    row = made[k] if made is not None else row_at(i)
                    change = self._publish(status, MotorState(states[i]), times[i], row)
                    if change is not None:
                        changes.append(change)
            status.row = made[-1] if made is not None else row_at(at[-1])
            status.last_sample_s = times[at[-1]]
            self.samples += index.size
        changes.sort(key=lambda c: c.time_s)
        return all_rows, changes

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
                for k in (
                    "omega_rad_s",
                    "omega_model_rad_s",
                    "current_a",
                    "current_model_a",
                    "voltage_v",
                    *RESIDUAL_COLUMNS,
                )
                if k in row
            },
        )
        status.state = state
        status.since_s = time_s
        return change

    def states(self) -> dict[int, MotorState]:
        return {n: s.state for n, s in self.status.items()}
