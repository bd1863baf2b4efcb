"""MAVLink messages to motor samples: the one reading, for the .tlog reader and the live agent alike.

The .tlog reader hands :class:`MessageReader` a whole log's messages in one call; the live agent hands
it each batch of messages its link delivers. Either way the input is *columns of messages*
(:class:`Messages` per message name: times, places in the stream, field arrays) and the output a
:class:`MotorReading` of table-shaped columns: one row per ESC telemetry message and ESC slot, the motor
commands and the battery. The reader carries what earlier messages said (the parameters in force, each
ESC slot's last packet count, what the stream has shown it carries), so a stream read in batches gives
the rows it gives read whole. Scaling and mappings are :mod:`.mavlink_esc`'s. The rules:

* ``ESC_TELEMETRY_1_TO_4``/``5_TO_8``/``9_TO_12``: slot ``j`` of each message is an ESC. A slot whose
  count, speed, voltage and current are all 0 has had no packet yet; a slot that has never had one gives
  no rows. ArduPilot repeats an ESC's last values until a new packet comes: once a slot's packet
  ``count`` has been seen to move, a message whose count did not move is a repeat (an ESC whose count
  never moves is read every time). Both are stale rows: speed and current NaN, ``fresh`` False.
* ``ESC_STATUS`` (PX4): speed [1/min], voltage [V], current [A] of ESCs ``index..index+3``, read only
  while the stream carries no ESC_TELEMETRY slot that reports.
* The motor of ESC slot ``j`` is that of servo output ``j+1`` (``SERVOn_FUNCTION``; default: output n is
  motor n); a slot that drives no motor gives no rows.
* ``SERVO_OUTPUT_RAW`` of port 0 holds outputs 1–16 (9–16 as MAVLink 2 extensions); once the stream has
  carried a port 1 message (MAVLink 1 autopilots), outputs 9–16 are port 1's ``servo1..8``. A motor's
  command is the lowest output that drives it, as throttle 0..1 over ``MOT_PWM_MIN/MAX``.
* Battery: ``BATTERY_STATUS`` of battery 0 (voltage: the sum of the cells, ``UINT16_MAX`` marking a cell
  that is not there), else ``SYS_STATUS`` as long as the stream has carried no BATTERY_STATUS of battery
  0. A voltage of 0 or ``UINT16_MAX`` and a negative current (−1: not measured) are no reading (NaN).
* ``PARAM_VALUE`` changes the mapping and the PWM range from its place in the stream on.

"The stream has carried X" counts the call being read: a .tlog, read in one call, decides from the whole
log. Pairing each ESC row with its motor's command and the battery comes after the reading, by one rule
and one class (:class:`.assemble.HeldValues`: the last value at or before the row's *time*, none older
than 1 s for commands, 5 s for the battery): the .tlog reader hands the whole reading to
:func:`.assemble.motor_table` (every log format's pairing), the live agent each batch's to
:class:`SamplePairing`, which carries the last values between batches; both derive the motor's voltage
and current with :func:`.mavlink_esc.motor_inputs`. Tests hold the .tlog table and the live rows of the
same messages equal, however the messages are batched.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import mavlink_esc
from .assemble import (
    COMMAND_MAX_AGE_S,
    CONTEXT_MAX_AGE_S,
    MAX_ESC_SLOTS,
    CommandExcursions,
    HeldValues,
    MessageIntervals,
    Series,
    bus_voltage_or_battery,
    excursion_v,
    pairing_uncertainty,
)

__all__ = [
    "MAX_MOTORS",
    "READ_FIELDS",
    "READ_MESSAGES",
    "MessageReader",
    "Messages",
    "MotorReading",
    "SamplePairing",
    "columns_from_messages",
    "columns_of",
]

#: The message fields the reading uses, per message name.
READ_FIELDS: dict[str, tuple[str, ...]] = {
    **{
        name: ("temperature", "voltage", "current", "rpm", "count")
        for name in mavlink_esc.ESC_TELEMETRY_MESSAGES
    },
    "ESC_STATUS": ("index", "rpm", "voltage", "current"),
    "SERVO_OUTPUT_RAW": ("port", *(f"servo{n}_raw" for n in range(1, 17))),  # 9-16: MAVLink 2 only
    "SYS_STATUS": ("voltage_battery", "current_battery"),
    "BATTERY_STATUS": ("id", "voltages", "current_battery"),
    "PARAM_VALUE": ("param_id", "param_value"),
}
#: The messages the reading uses.
READ_MESSAGES = tuple(READ_FIELDS)
#: Motor numbers a reading can give (an ESC slot or a servo output without SERVOn_FUNCTION is its motor).
MAX_MOTORS = MAX_ESC_SLOTS
_OUTPUTS = 16
_UINT16_MAX = 0xFFFF
_MAPPING_PARAMS = ("SERVO", "MOT_PWM", "RC3_")  # parameters that change the ESC→motor map or the PWM range
_SLOT_ROWS = np.arange(4)[:, None]  # the four slots of an ESC_TELEMETRY message, as rows
_SERVO_FIELDS = READ_FIELDS["SERVO_OUTPUT_RAW"][1:]


def _empty(*shape: int, dtype: Any = float) -> NDArray[Any]:
    array = np.zeros(shape or (0,), dtype=dtype)
    array.flags.writeable = False  # shared
    return array


_NONE = _empty()
_NO_POSITIONS = _empty(dtype=np.int64)
_NO_COMMANDS = _empty(0, 0)


@dataclass(frozen=True)
class Messages:
    """The messages of one name as columns: ``fields[f]`` is field ``f`` of each message (a row each).

    ``fields`` is a numpy structured array (the .tlog reader's) or a mapping of field name to array.
    ``position`` orders messages of different names: the place in the stream (a file offset, an arrival
    counter), increasing in the order the messages came.
    """

    time_s: NDArray[np.float64]
    position: NDArray[np.int64]
    fields: Any
    #: several fields at once as the columns of one 2-D array, keyed by their names (optional: saves
    #: gathering them field by field)
    blocks: Mapping[tuple[str, ...], NDArray[Any]] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.time_s)

    def __getitem__(self, name: str) -> NDArray[Any]:
        return np.asarray(self.fields[name])

    def block(self, names: Sequence[str]) -> NDArray[Any]:
        """The fields ``names`` as the columns of one array (a row per message)."""
        for stored, array in self.blocks.items():
            if set(names) <= set(stored):
                return array[:, [stored.index(name) for name in names]]
        return np.stack([self[name] for name in names], axis=1)


@dataclass(frozen=True)
class MotorReading:
    """What a batch of messages says about the motors, as columns.

    ESC rows (one per message and reporting ESC slot; message by message for each message name, slot by
    slot): ``time_s``, ``position`` (the message's place in the stream), ``motor``, ``omega_rad_s`` and
    ``esc_current_a`` (NaN on stale rows), ``bus_voltage_v`` (the ESC's own reading; 0 where it measures
    none), ``esc_temp_c`` (NaN: not reported), ``fresh``. Commands, a row per SERVO_OUTPUT_RAW:
    ``command_time_s``, ``command_position``, ``throttle`` (a column per motor of ``command_motors``; NaN
    where the message carries no command for the motor). Battery, a row per message read:
    ``battery_time_s``, ``battery_position``, ``battery_voltage_v``, ``battery_current_a`` (NaN: no reading).
    """

    time_s: NDArray[np.float64]
    position: NDArray[np.int64]
    motor: NDArray[np.int64]
    omega_rad_s: NDArray[np.float64]
    esc_current_a: NDArray[np.float64]
    bus_voltage_v: NDArray[np.float64]
    esc_temp_c: NDArray[np.float64]
    fresh: NDArray[np.bool_]
    command_time_s: NDArray[np.float64]
    command_position: NDArray[np.int64]
    command_motors: NDArray[np.int64]
    throttle: NDArray[np.float64]
    battery_time_s: NDArray[np.float64]
    battery_position: NDArray[np.int64]
    battery_voltage_v: NDArray[np.float64]
    battery_current_a: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.time_s)

    def fresh_rows(self) -> MotorReading:
        """The reading with its measurements only (stale ESC rows left out; commands and battery kept)."""
        keep = self.fresh
        if keep.all():
            return self
        return replace(
            self,
            time_s=self.time_s[keep],
            position=self.position[keep],
            motor=self.motor[keep],
            omega_rad_s=self.omega_rad_s[keep],
            esc_current_a=self.esc_current_a[keep],
            bus_voltage_v=self.bus_voltage_v[keep],
            esc_temp_c=self.esc_temp_c[keep],
            fresh=keep[keep],
        )

    def commands(self) -> dict[int, Series]:
        """Each motor's command series (time, throttle), for :func:`.assemble.motor_table`."""
        out: dict[int, Series] = {}
        has = np.isfinite(self.throttle)
        for col, motor in enumerate(self.command_motors.tolist()):
            sel = has[:, col]
            if sel.any():
                out[motor] = (self.command_time_s[sel], self.throttle[sel, col])
        return out


class _Mapping:
    """The parameters' say: the motor of each ESC slot, the output of each motor, the PWM range."""

    def __init__(self, params: Mapping[str, float]) -> None:
        #: per slot (0-based): motor number, 0 for none (and for slot MAX_ESC_SLOTS: out of range)
        self.motor_of_slot = np.array(
            [mavlink_esc.motor_for_output(slot + 1, params) or 0 for slot in range(MAX_ESC_SLOTS)] + [0],
            dtype=np.int64,
        )
        #: per motor − 1: the 0-based servo output commanding it, −1 for none
        self.output_of_motor = np.full(MAX_MOTORS, -1, dtype=np.int64)
        for output in range(_OUTPUTS, 0, -1):  # the lowest output driving a motor gives its command
            motor = mavlink_esc.motor_for_output(output, params)
            if motor is not None and 1 <= motor <= MAX_MOTORS:
                self.output_of_motor[motor - 1] = output - 1
        self.pwm_low_us, self.pwm_high_us = mavlink_esc.pwm_range(params)
        self.motors = np.flatnonzero(self.output_of_motor >= 0)  # motor − 1 of each commanded motor
        self.motor_outputs = self.output_of_motor[self.motors]  # and its output

    def same_as(self, other: _Mapping) -> bool:
        return (
            np.array_equal(self.motor_of_slot, other.motor_of_slot)
            and np.array_equal(self.output_of_motor, other.output_of_motor)
            and (self.pwm_low_us, self.pwm_high_us) == (other.pwm_low_us, other.pwm_high_us)
        )


class MessageReader:
    """Columns of MAVLink messages → :class:`MotorReading`, carrying the stream's state between calls.

    ``params`` are the parameters in force before the first message (the .tlog reader passes each
    parameter's first logged value; the live agent starts without); ``motors`` keeps rows of these motor
    numbers only (None: all). ``repeats`` counts the ESC rows found to be repeats.
    """

    def __init__(
        self, params: Mapping[str, float] | None = None, motors: Iterable[int] | None = None
    ) -> None:
        self.params: dict[str, float] = {k: float(v) for k, v in (params or {}).items()}
        # which motor numbers to keep (0: a slot that drives no motor)
        self._wanted = np.zeros(MAX_MOTORS + 1, dtype=bool)
        if motors is None:
            self._wanted[1:] = True
        else:
            self._wanted[[m for m in motors if 1 <= m <= MAX_MOTORS]] = True
        self.repeats = 0
        # what the stream has carried so far
        self.esc_reported = False  # an ESC_TELEMETRY slot with a packet
        self.port1_seen = False  # SERVO_OUTPUT_RAW of port 1 (outputs 9-16, MAVLink 1)
        self.battery_status_seen = False  # BATTERY_STATUS of battery 0
        # per ESC_TELEMETRY slot: whether it has reported, its last packet count (-1: none), whether the
        # count has been seen to move
        self._reported = np.zeros(MAX_ESC_SLOTS, dtype=bool)
        self._last_count = np.full(MAX_ESC_SLOTS, -1, dtype=np.int64)
        self._count_moved = np.zeros(MAX_ESC_SLOTS, dtype=bool)
        self._mapping = _Mapping(self.params)

    def read(self, batch: Mapping[str, Messages]) -> MotorReading:
        """Read the next messages of the stream (each name's rows in stream order)."""
        starts, mappings = self._parameters(batch.get("PARAM_VALUE"))

        def segment(position: NDArray[np.int64]) -> NDArray[np.int64]:
            """Which of ``mappings`` is in force at each position."""
            return np.searchsorted(starts, position, side="right")

        parts: list[tuple[NDArray[Any], ...]] = []
        for name in mavlink_esc.ESC_TELEMETRY_MESSAGES:
            if name in batch and (part := self._esc_telemetry(name, batch[name])) is not None:
                parts.append(part)
        status = batch.get("ESC_STATUS")
        if status is not None and len(status) and not self.esc_reported:
            parts.append(_esc_status(status))
        if len(parts) == 1:
            time_s, position, slot, omega, current, bus, temp, fresh, repeat = parts[0]
        elif parts:
            time_s, position, slot, omega, current, bus, temp, fresh, repeat = (
                np.concatenate(cols) for cols in zip(*parts)
            )
        else:
            time_s = omega = current = bus = temp = _NONE
            position = slot = _NO_POSITIONS
            fresh = repeat = _empty(dtype=bool)
        # the motor of each row's slot (slot MAX_ESC_SLOTS: out of range, no motor)
        if len(mappings) == 1:
            motor = mappings[0].motor_of_slot[slot]
        else:
            motor = np.stack([m.motor_of_slot for m in mappings])[segment(position), slot]
        keep = self._wanted[motor]
        if not keep.all():
            time_s, position, motor, omega = time_s[keep], position[keep], motor[keep], omega[keep]
            current, bus, temp, fresh, repeat = (
                current[keep],
                bus[keep],
                temp[keep],
                fresh[keep],
                repeat[keep],
            )
        self.repeats += int(np.count_nonzero(repeat))
        servo = batch.get("SERVO_OUTPUT_RAW")
        command_time_s, command_position = _NONE, _NO_POSITIONS
        if servo is not None and len(servo):
            command_time_s, command_position = servo.time_s, servo.position
        command_motors, throttle = self._commands(servo, mappings, segment)
        return MotorReading(
            time_s,
            position,
            motor,
            omega,
            current,
            bus,
            temp,
            fresh,
            command_time_s,
            command_position,
            command_motors,
            throttle,
            *self._battery(batch),
        )

    def _parameters(self, pv: Messages | None) -> tuple[NDArray[np.int64], list[_Mapping]]:
        """Apply PARAM_VALUE messages in order: the positions where the mapping changes, and the mapping
        in force before, between and after them."""
        mappings = [self._mapping]
        starts: list[int] = []
        if pv is None or not len(pv):
            return _NO_POSITIONS, mappings
        for name, value, position in zip(
            pv["param_id"].tolist(), pv["param_value"].tolist(), pv.position.tolist()
        ):
            if isinstance(name, bytes):
                name = name.split(b"\0", 1)[0].decode("ascii", "replace")
            name, value = str(name).rstrip("\x00"), float(value)
            before = self.params.get(name)
            self.params[name] = value
            if name.startswith(_MAPPING_PARAMS) and not (before == value or _both_nan(before, value)):
                mapping = _Mapping(self.params)
                if not mapping.same_as(mappings[-1]):
                    starts.append(int(position))
                    mappings.append(mapping)
        self._mapping = mappings[-1]
        return np.array(starts, dtype=np.int64), mappings

    def _esc_telemetry(self, name: str, rec: Messages) -> tuple[NDArray[Any], ...] | None:
        """One ESC_TELEMETRY message name's rows: slot by slot, each slot's messages in order."""
        n = len(rec)
        if n == 0:
            return None
        first = mavlink_esc.ESC_TELEMETRY_MESSAGES[name]
        slots = slice(first, first + 4)
        # slot by slot (4 × n): the log is read ESC by ESC
        count, rpm = rec["count"].T, rec["rpm"].T
        voltage, current = rec["voltage"].T, rec["current"].T
        seen = (count | rpm | voltage | current) != 0  # all 0: no packet yet
        reporting = self._reported[slots]
        reporting |= seen.any(axis=1)  # (a view: the reader's state)
        if not reporting.any():
            return None
        self.esc_reported = True
        # Repeats: each packet's count against the slot's previous packet's (column 0: the one carried from
        # the calls before, -1 for none); once the count has been seen to move, a count that did not move
        # is ArduPilot repeating the last values.
        carried = self._last_count[slots]
        counts = np.concatenate((carried[:, None], count), axis=1)
        packets = np.concatenate(((carried >= 0)[:, None], seen), axis=1)
        if packets.all():  # a packet in every message (and one before): each packet's previous is the last
            has_previous = seen
            moved = has_previous & (count != counts[:, :-1])
            last_packet = np.full(len(carried), n)
        else:
            last = np.maximum.accumulate(np.where(packets, np.arange(n + 1), -1), axis=1)
            previous = last[:, :-1]
            has_previous = seen & (previous >= 0)
            moved = has_previous & (count != counts[_SLOT_ROWS, previous])
            last_packet = last[:, -1]
        moved_yet = _since_first(np.concatenate((self._count_moved[slots, None], moved), axis=1))
        repeat = has_previous & ~moved & moved_yet[:, :-1]
        carried[:] = counts[_SLOT_ROWS[:, 0], np.maximum(last_packet, 0)]  # none yet: column 0 is -1
        self._count_moved[slots] = moved_yet[:, -1]
        fresh = seen & ~repeat
        temperature = rec["temperature"].T
        if reporting.all():
            cols = _SLOT_ROWS[:, 0]
        else:  # a slot that has never reported gives no rows
            cols = np.flatnonzero(reporting)
            temperature, voltage, current, rpm = temperature[cols], voltage[cols], current[cols], rpm[cols]
            fresh, repeat = fresh[cols], repeat[cols]
        si = mavlink_esc.esc_fields_to_si(temperature.ravel(), voltage.ravel(), current.ravel(), rpm.ravel())
        fresh, repeat = fresh.ravel(), repeat.ravel()
        return (
            np.concatenate([rec.time_s] * len(cols)),
            np.concatenate([rec.position] * len(cols)),
            np.repeat(first + cols, n),
            np.where(fresh, si["omega_rad_s"], np.nan),
            np.where(fresh, si["esc_current_a"], np.nan),
            si["bus_voltage_v"],
            si["esc_temp_c"],
            fresh,
            repeat,
        )

    def _commands(
        self,
        rec: Messages | None,
        mappings: Sequence[_Mapping],
        segment: Callable[[NDArray[np.int64]], NDArray[np.int64]],
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """The motors commanded, and each SERVO_OUTPUT_RAW message's throttle of each (NaN: none)."""
        if rec is None or not len(rec):
            return _NO_POSITIONS, _NO_COMMANDS
        port = rec["port"]
        self.port1_seen = self.port1_seen or bool((port == 1).any())
        outputs = np.unique(np.concatenate([m.motor_outputs for m in mappings]))  # 0-based, the needed ones
        pwm = rec.block([_SERVO_FIELDS[o] for o in outputs.tolist()]).astype(float)
        main = port == 0
        if self.port1_seen:  # outputs 9-16 come as port 1's servo1..8
            upper = outputs >= 8
            pwm = np.where(main[:, None] & ~upper, pwm, np.nan)
            if upper.any():
                port1 = rec.block([_SERVO_FIELDS[o - 8] for o in outputs[upper].tolist()])
                pwm[:, upper] = np.where((port == 1)[:, None], port1, np.nan)
        elif not main.all():
            pwm = np.where(main[:, None], pwm, np.nan)
        motors = np.unique(np.concatenate([m.motors for m in mappings]))  # motor − 1
        if len(mappings) == 1:
            (mapping,) = mappings
            throttle = mavlink_esc.throttle_from_pwm(
                pwm[:, np.searchsorted(outputs, mapping.motor_outputs)],
                mapping.pwm_low_us,
                mapping.pwm_high_us,
            )
            return motors + 1, throttle
        throttle = np.full((len(rec), len(motors)), np.nan)
        seg = segment(rec.position)
        for k, mapping in enumerate(mappings):
            rows = np.flatnonzero(seg == k)
            cols = np.searchsorted(motors, mapping.motors)
            throttle[np.ix_(rows, cols)] = mavlink_esc.throttle_from_pwm(
                pwm[np.ix_(rows, np.searchsorted(outputs, mapping.motor_outputs))],
                mapping.pwm_low_us,
                mapping.pwm_high_us,
            )
        return motors + 1, throttle

    def _battery(self, batch: Mapping[str, Messages]) -> tuple[NDArray[Any], ...]:
        """Time, position, voltage and current of each battery message read."""
        status = batch.get("BATTERY_STATUS")
        if status is not None and len(status):
            mine = status["id"] == 0
            self.battery_status_seen = self.battery_status_seen or bool(mine.any())
            if mine.any():
                cells = status["voltages"][mine].astype(float)
                cells[cells == _UINT16_MAX] = np.nan  # no such cell
                present = np.isfinite(cells).any(axis=1)
                millivolts = np.where(present, np.nansum(cells, axis=1), np.nan)
                return (
                    status.time_s[mine],
                    status.position[mine],
                    _volts(millivolts),
                    _amps(status["current_battery"][mine]),
                )
        sys_status = batch.get("SYS_STATUS")
        if sys_status is not None and len(sys_status) and not self.battery_status_seen:
            return (
                sys_status.time_s,
                sys_status.position,
                _volts(sys_status["voltage_battery"].astype(float)),
                _amps(sys_status["current_battery"]),
            )
        return _NONE, _NO_POSITIONS, _NONE, _NONE


def _both_nan(a: float | None, b: float) -> bool:
    return a is not None and math.isnan(a) and math.isnan(b)


def _volts(millivolts: NDArray[np.float64]) -> NDArray[np.float64]:
    """Battery voltage [V] from mV; 0 and UINT16_MAX are no reading."""
    mv = np.asarray(millivolts, dtype=float).copy()
    mv[(mv == _UINT16_MAX) | (mv == 0)] = np.nan
    return mv / 1000.0


def _amps(centiamps: NDArray[Any]) -> NDArray[np.float64]:
    """Battery current [A] from cA; negative (−1: not measured) is no reading."""
    ca = np.asarray(centiamps, dtype=float).copy()
    ca[ca < 0] = np.nan
    return ca / 100.0


def _since_first(flags: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``np.logical_or.accumulate(flags, axis=1)``: each row true from its first true on (one search per
    row instead of a running OR)."""
    width = flags.shape[1]
    first = np.where(flags.any(axis=1), flags.argmax(axis=1), width)
    return np.arange(width)[None, :] >= first[:, None]


def _esc_status(rec: Messages) -> tuple[NDArray[Any], ...]:
    """PX4's ESC_STATUS rows, slot by slot: SI units already, no packet count (every row is fresh)."""
    n = len(rec)
    slot = (rec["index"].astype(np.int64)[:, None] + np.arange(4)).T.ravel()
    slot[(slot < 0) | (slot >= MAX_ESC_SLOTS)] = MAX_ESC_SLOTS  # a damaged index: no motor
    return (
        np.tile(rec.time_s, 4),
        np.tile(rec.position, 4),
        slot,
        rec["rpm"].reshape(n, 4).T.ravel().astype(float) * mavlink_esc.RPM_TO_RAD_S,
        rec["current"].reshape(n, 4).T.ravel().astype(float),
        rec["voltage"].reshape(n, 4).T.ravel().astype(float),
        np.full(4 * n, np.nan),
        np.ones(4 * n, dtype=bool),
        np.zeros(4 * n, dtype=bool),
    )


class SamplePairing:
    """The live agent's pairing, :func:`.assemble.motor_table`'s rule on readings fed one after another:
    each ESC row gets its motor's command and the battery by previous-value hold by time
    (:class:`.assemble.HeldValues`, carried across calls): the last value at or before the row's time,
    none older than ``COMMAND_MAX_AGE_S`` for commands, ``CONTEXT_MAX_AGE_S`` for the battery (a message
    saying "not measured" is the latest word: no value). A message that carries no command for a motor
    leaves that motor's last command in force, as the .tlog reader's command series skip it. Where the ESC
    measures no voltage the battery's stands in; ``voltage_v``/``current_a`` come from
    :func:`.mavlink_esc.motor_inputs`, as in the table. Each sample's ``pairing_s`` is the table's
    (:func:`.assemble.pairing_uncertainty`): its command's age or, if more, the interval of its motor's
    ESC messages over the last second (:class:`.assemble.MessageIntervals`, carried across calls: a message
    carries each ESC's last packet, which came after the message before). Rows come out message by message, each
    message's in motor order, with their ``position``.
    """

    def __init__(self) -> None:
        self.commands = HeldValues(MAX_MOTORS, COMMAND_MAX_AGE_S)  # motor m: signal m - 1
        self.battery = HeldValues(2, CONTEXT_MAX_AGE_S)  # voltage [V], current [A]
        self.messages = MessageIntervals(MAX_MOTORS)  # motor m: signal m - 1
        self.excursions = CommandExcursions(MAX_MOTORS)  # motor m: signal m - 1

    def pair(self, reading: MotorReading) -> dict[str, NDArray[Any]]:
        """The table columns of the reading's fresh ESC rows (and their ``position``). Pass the whole
        reading, stale rows included: they count for the interval of a motor's messages (as in
        the .tlog table, which keeps them), and are left out here."""
        interval = self.messages.since_previous(reading.time_s, reading.motor - 1)
        if not reading.fresh.all():
            interval = interval[reading.fresh]
            reading = reading.fresh_rows()
        position, motor, time_s = reading.position, reading.motor, reading.time_s
        throttle = reading.throttle
        if len(reading.command_position):  # a column per motor number (motor m: column m - 1)
            throttle = np.full((len(reading.command_position), MAX_MOTORS), np.nan)
            throttle[:, reading.command_motors - 1] = reading.throttle
        command, command_age = self.commands.hold(
            reading.command_time_s, throttle, time_s, motor - 1, present=np.isfinite(throttle)
        )
        # how far each motor's commands went beyond the two held ones since its sample before; a motor
        # with commands but no sample in this part carries them to its next sample
        commanded = throttle.ndim == 2 and throttle.shape[0] > 0
        excursion = self.excursions.beyond_held(
            np.asarray(reading.command_time_s, dtype=float)[: len(throttle)] if commanded else np.zeros(0),
            throttle if commanded else np.zeros((0, MAX_MOTORS)),
            motor - 1,
            time_s,
        )
        battery, _ = self.battery.hold(
            reading.battery_time_s,
            np.stack((reading.battery_voltage_v, reading.battery_current_a), axis=-1),
            time_s,
        )
        battery_v, battery_a = battery[:, 0], battery[:, 1]
        bus = bus_voltage_or_battery(reading.bus_voltage_v, battery_v)
        voltage, current = mavlink_esc.motor_inputs(command, bus, reading.esc_current_a)
        columns: dict[str, NDArray[Any]] = {
            "time_s": time_s,
            "motor": motor,
            "omega_rad_s": reading.omega_rad_s,
            "current_a": current,
            "voltage_v": voltage,
            "bus_voltage_v": bus,
            "throttle": command,
            "esc_current_a": reading.esc_current_a,
            "esc_temp_c": reading.esc_temp_c,
            "battery_voltage_v": battery_v,
            "battery_current_a": battery_a,
            "pairing_s": pairing_uncertainty(command_age, interval),
            "command_age_s": command_age,
            "input_excursion_v": excursion_v(excursion, bus),
            "position": position,
        }
        if len(position) > 1:
            order = np.lexsort((motor, position))
            if (order != np.arange(len(position))).any():
                columns = {name: values[order] for name, values in columns.items()}
        return columns


def columns_of(kind: str, time_s: Sequence[float], position: Sequence[int], msgs: Sequence[Any]) -> Messages:
    """Columns of pymavlink messages of one kind (``kind`` in :data:`READ_FIELDS`), with their times
    and stream positions."""
    n = len(msgs)
    fields: dict[str, NDArray[Any]]
    blocks: dict[tuple[str, ...], NDArray[Any]] = {}
    if kind in mavlink_esc.ESC_TELEMETRY_MESSAGES:
        table = np.array(
            [[*m.temperature, *m.voltage, *m.current, *m.rpm, *m.count] for m in msgs], dtype=np.int64
        ).reshape(n, 20)
        fields = {name: table[:, 4 * k : 4 * k + 4] for k, name in enumerate(READ_FIELDS[kind])}
    elif kind == "ESC_STATUS":
        table = np.array([[m.index, *m.rpm, *m.voltage, *m.current] for m in msgs], dtype=float).reshape(
            n, 13
        )
        fields = {
            "index": table[:, 0],
            "rpm": table[:, 1:5],
            "voltage": table[:, 5:9],
            "current": table[:, 9:13],
        }
    elif kind == "BATTERY_STATUS":
        table = np.array([[m.id, *m.voltages, m.current_battery] for m in msgs], dtype=np.int64).reshape(
            n, 12
        )
        fields = {"id": table[:, 0], "voltages": table[:, 1:11], "current_battery": table[:, 11]}
    elif kind == "PARAM_VALUE":
        fields = {
            "param_id": np.array([str(m.param_id).rstrip("\x00") for m in msgs], dtype=object),
            "param_value": np.array([float(m.param_value) for m in msgs]),
        }
    else:  # SERVO_OUTPUT_RAW, SYS_STATUS: scalar fields
        names = READ_FIELDS[kind]
        get = operator.attrgetter(*names)
        table = np.array([get(m) for m in msgs], dtype=np.int64).reshape(n, len(names))
        fields = {name: table[:, k] for k, name in enumerate(names)}
        if kind == "SERVO_OUTPUT_RAW":
            blocks[_SERVO_FIELDS] = table[:, 1:]
    return Messages(np.array(time_s, dtype=float), np.array(position, dtype=np.int64), fields, blocks)


def columns_from_messages(
    received: Sequence[tuple[float, Any]], first_position: int = 0
) -> dict[str, Messages]:
    """Columns of pymavlink messages: ``received`` holds (time_s, message) in the order they came; their
    positions count from ``first_position``. Messages the reading does not use are left out."""
    grouped: dict[str, tuple[list[float], list[int], list[Any]]] = {}
    for k, (time_s, msg) in enumerate(received):
        kind = msg.get_type()
        if kind in READ_FIELDS:
            times, positions, msgs = grouped.setdefault(kind, ([], [], []))
            times.append(time_s)
            positions.append(first_position + k)
            msgs.append(msg)
    return {kind: columns_of(kind, *group) for kind, group in grouped.items()}
