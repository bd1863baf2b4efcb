"""MAVLink messages to motor samples for the live agent: the .tlog reader's reading, fed small batches.

:class:`SampleAssembler` keeps the messages that came since the last call (the agent: one batch of its
link) and hands them, as columns, to :class:`~mav_motor_health.telemetry.mavlink_messages.MessageReader`
— the reading replay gives a whole .tlog — then pairs each ESC row with its motor's command and the
battery by replay's rule (:class:`~mav_motor_health.telemetry.mavlink_messages.SamplePairing`: the last
value at or before the sample's time, none older than 1 s for commands, 5 s for the battery, carried
from batch to batch). What comes out is the telemetry table's columns for the fresh samples: a repeated
or empty ESC slot is no sample (a silent ESC yields none, and the monitor declares it ``NO_DATA``); a
sample whose command is stale has no throttle, motor voltage or motor current (NaN), as in replay's
table. Each sample's ``pairing_s`` (how far apart it and its command may be, which the balance rule
weighs) is replay's column, worked out from the messages so far (telemetry/assemble.py). No I/O here:
messages are anything with pymavlink's attributes and ``get_type()``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..telemetry.mavlink_esc import ESC_TELEMETRY_MESSAGES
from ..telemetry.mavlink_messages import READ_FIELDS, MessageReader, SamplePairing, columns_of

__all__ = ["MotorSample", "SampleAssembler"]

_ESC_MESSAGES = frozenset([*ESC_TELEMETRY_MESSAGES, "ESC_STATUS"])


@dataclass(frozen=True)
class MotorSample:
    """One motor sample in the telemetry table's columns (NaN where unknown)."""

    motor: int
    time_s: float
    omega_rad_s: float
    current_a: float
    voltage_v: float
    bus_voltage_v: float
    throttle: float
    esc_current_a: float
    esc_temp_c: float
    #: the battery monitor's latest current [A] (NaN: none reported)
    battery_current_a: float = math.nan
    #: how far apart the sample and its command may be [s] (telemetry/assemble.py, replay's column of the
    #: same name: its command's age or the interval of the motor's ESC messages, the larger); 0: the
    #: command of the sample's own instant, as the simulator pairs them
    pairing_s: float = 0.0
    #: how far the motor's command went beyond the two held commands since its sample before [V]
    #: (telemetry/assemble.py, replay's column of the same name); 0: not at all, or not known
    input_excursion_v: float = 0.0
    #: the age of the command the sample is paired with [s] (telemetry/assemble.py, replay's column of the
    #: same name); NaN: not known (its pairing then stands in, diagnosis/stall.py)
    command_age_s: float = math.nan

    def row(self) -> dict[str, float]:
        """The sample as a table row (column name → value)."""
        return {
            "time_s": self.time_s,
            "motor": self.motor,
            "omega_rad_s": self.omega_rad_s,
            "current_a": self.current_a,
            "voltage_v": self.voltage_v,
            "bus_voltage_v": self.bus_voltage_v,
            "throttle": self.throttle,
            "esc_current_a": self.esc_current_a,
            "esc_temp_c": self.esc_temp_c,
            "battery_current_a": self.battery_current_a,
            "pairing_s": self.pairing_s,
            "input_excursion_v": self.input_excursion_v,
            "command_age_s": self.command_age_s,
        }


class SampleAssembler:
    """Messages → motor samples of motors 1..``motors``: ``add`` each message, ``take`` the samples.

    ``params`` are parameters known before the first message (the agent reads the autopilot's as they
    come, in ``PARAM_VALUE``).
    """

    def __init__(self, motors: int = 6, params: Mapping[str, float] | None = None) -> None:
        self.reader = MessageReader(params, motors=range(1, motors + 1))
        self.pairing = SamplePairing()
        # the messages waiting, per kind: times, stream positions, messages
        self._waiting: dict[str, tuple[list[float], list[int], list[Any]]] = {}
        self._count = 0  # messages kept so far: the stream position of the next one
        self.waiting = 0  #: messages kept since the last take

    @property
    def params(self) -> dict[str, float]:
        return self.reader.params

    @property
    def repeats(self) -> int:
        """ESC slots skipped because their packet count did not advance."""
        return self.reader.repeats

    def add(self, msg: Any, time_s: float) -> bool:
        """Keep a message for the next :meth:`take` (those the reading does not use are dropped); True if
        it is ESC telemetry (samples to come)."""
        kind = msg.get_type()
        if kind not in READ_FIELDS:
            return False
        waiting = self._waiting.get(kind)
        if waiting is None:
            waiting = self._waiting[kind] = ([], [], [])
        waiting[0].append(time_s)
        waiting[1].append(self._count)
        waiting[2].append(msg)
        self._count += 1
        self.waiting += 1
        return kind in _ESC_MESSAGES

    def take(self) -> dict[str, NDArray[Any]]:
        """The fresh samples of the messages kept since the last call, as table columns: message by message
        (each message's motors in order), with each one's ``position`` in the stream."""
        waiting, self._waiting, self.waiting = self._waiting, {}, 0
        batch = {kind: columns_of(kind, *group) for kind, group in waiting.items()}
        return self.pairing.pair(self.reader.read(batch))  # stale rows count for the pairing, then go

    def feed(self, msg: Any, time_s: float) -> list[MotorSample]:
        """Take one message; returns the motor samples it completes (only ESC telemetry makes any)."""
        self.add(msg, time_s)
        return samples_of(self.take())


#: a sample's columns, in :class:`MotorSample`'s order
SAMPLE_COLUMNS = tuple(f.name for f in fields(MotorSample))


def samples_of(columns: Mapping[str, NDArray[Any]]) -> list[MotorSample]:
    """Table columns as :class:`MotorSample` objects, row by row."""
    values = [np.asarray(columns[name]).tolist() for name in SAMPLE_COLUMNS]
    return [MotorSample(*row) for row in zip(*values)]
