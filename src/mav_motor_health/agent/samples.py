"""MAVLink messages to motor samples: the live side of the telemetry table, one row at a time.

:class:`SampleAssembler` remembers what the messages before said (the last motor commands, the
battery voltage and current, the autopilot's parameters) and turns each ESC telemetry message into one
:class:`MotorSample` per motor it carries, in the table's columns and units. All scaling, the ESC→motor
mapping, the PWM range and what the motor sees are :mod:`mav_motor_health.telemetry.mavlink_esc`'s.
ArduPilot keeps repeating an ESC's last values when its telemetry stops; once an ESC's packet ``count``
has been seen to advance, a slot whose count did not advance is skipped, so a silent ESC yields no samples
(and the monitor declares it ``NO_DATA``); an all-zero slot is an ESC that never reported. No I/O here: messages are anything with pymavlink's attributes
and ``get_type()``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..telemetry import mavlink_esc

__all__ = ["MotorSample", "SampleAssembler"]

#: SERVO_OUTPUT_RAW holds outputs 1–16 (9–16 as MAVLink 2 extensions).
_SERVO_FIELDS = tuple(f"servo{n}_raw" for n in range(1, 17))


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
        }


class SampleAssembler:
    """Stateful message → samples converter for ``motors`` motors (1..motors)."""

    def __init__(self, motors: int = 6, params: Mapping[str, float] | None = None) -> None:
        self.motors = motors
        self.params: dict[str, float] = dict(params or {})
        self.pwm_us: dict[int, float] = {}  # servo output (1-based) → last pulse width
        self.battery_v = math.nan
        self.battery_a = math.nan
        self._count: dict[int, int] = {}  # motor → last ESC packet count
        self._count_moves: set[int] = set()  # motors whose ESC count has been seen to advance
        self.repeats = 0  # ESC slots skipped because their packet count did not advance
        self._update_mapping()

    def set_param(self, name: str, value: float) -> None:
        self.params[name] = float(value)
        if name.startswith(("SERVO", "MOT_PWM", "RC3_")):
            self._update_mapping()

    def _update_mapping(self) -> None:
        self.pwm_low, self.pwm_high = mavlink_esc.pwm_range(self.params)
        functions = self.params if self._has_functions() else None
        # PWM for a motor comes from the output that drives it
        self.output_of_motor: dict[int, int] = {}
        for output in range(16, 0, -1):
            motor = mavlink_esc.motor_for_output(output, functions)
            if motor is not None:
                self.output_of_motor[motor] = output
        # the motor of each ESC_TELEMETRY slot (one message per four outputs), worked out once per change
        self._slot_motors = {
            first: [mavlink_esc.motor_for_output(first + j + 1, functions) for j in range(4)]
            for first in set(mavlink_esc.ESC_TELEMETRY_MESSAGES.values())
        }

    def _has_functions(self) -> bool:
        return any(k.startswith("SERVO") and k.endswith("_FUNCTION") for k in self.params)

    def feed(self, msg: Any, time_s: float) -> list[MotorSample]:
        """Take one message; returns the motor samples it completes (only ESC telemetry makes any)."""
        kind = msg.get_type()
        if kind in mavlink_esc.ESC_TELEMETRY_MESSAGES:
            first = mavlink_esc.ESC_TELEMETRY_MESSAGES[kind]
            return self._esc(
                time_s,
                self._slot_motors[first],
                [float(x) for x in msg.rpm],
                [float(x) for x in msg.voltage],
                [float(x) for x in msg.current],
                [float(x) for x in msg.temperature],
                [int(x) for x in msg.count],
            )
        if kind == "ESC_STATUS":  # PX4: floats in SI already; ESC slot j is motor j + 1
            first = int(msg.index)
            return self._esc(
                time_s,
                [first + j + 1 for j in range(4)],
                [float(x) for x in msg.rpm],
                [float(x) * 100.0 for x in msg.voltage],
                [float(x) * 100.0 for x in msg.current],
                [math.nan] * 4,
                None,
            )
        if kind == "SERVO_OUTPUT_RAW":
            if int(getattr(msg, "port", 0)) == 0:
                for n, name in enumerate(_SERVO_FIELDS, start=1):
                    value = getattr(msg, name, None)
                    if value is not None:
                        self.pwm_us[n] = float(value)
        elif kind == "SYS_STATUS":
            if msg.voltage_battery not in (0, 0xFFFF):
                self.battery_v = msg.voltage_battery / 1000.0
            if msg.current_battery != -1:  # cA; −1: not measured
                self.battery_a = msg.current_battery / 100.0
        elif kind == "BATTERY_STATUS":
            if int(msg.id) == 0:
                cells = [v for v in msg.voltages if v not in (0xFFFF,)]
                if cells:
                    self.battery_v = sum(cells) / 1000.0
                if msg.current_battery != -1:
                    self.battery_a = msg.current_battery / 100.0
        elif kind == "PARAM_VALUE":
            name = msg.param_id.rstrip("\x00") if isinstance(msg.param_id, str) else msg.param_id
            self.set_param(str(name), float(msg.param_value))
        return []

    def throttle(self, motor: int) -> float:
        output = self.output_of_motor.get(motor)
        pwm = self.pwm_us.get(output) if output is not None else None
        if pwm is None:
            return math.nan
        return float(mavlink_esc.throttle_from_pwm(pwm, self.pwm_low, self.pwm_high))

    def _repeated(self, motor: int, count: int) -> bool:
        """ArduPilot repeats an ESC's last values until a new packet arrives: ``count`` tells (once it moves)."""
        previous = self._count.get(motor)
        self._count[motor] = count
        if previous is None:
            return False
        if count != previous:
            self._count_moves.add(motor)
            return False
        if motor in self._count_moves:
            self.repeats += 1
            return True
        return False

    def _esc(
        self,
        time_s: float,
        motors: list[int | None],
        rpm: list[float],
        voltage_cv: list[float],
        current_ca: list[float],
        temps: list[float],
        counts: list[int] | None,
    ) -> list[MotorSample]:
        slots = [
            j
            for j, motor in enumerate(motors)
            if motor is not None
            and 1 <= motor <= self.motors
            and not (counts is not None and counts[j] == 0 and not (rpm[j] or voltage_cv[j] or current_ca[j]))
            and not (counts is not None and self._repeated(motor, counts[j]))
        ]
        if not slots:
            return []
        # one vectorised call per message for its ESCs (the shared conversions, not a copy of them)
        si = mavlink_esc.esc_fields_to_si(
            [temps[j] for j in slots],
            [voltage_cv[j] for j in slots],
            [current_ca[j] for j in slots],
            [rpm[j] for j in slots],
        )
        # an ESC that does not measure its input voltage: use the battery monitor's
        bus = np.where(si["bus_voltage_v"] > 0, si["bus_voltage_v"], self.battery_v)
        # the commands of the slots' motors in one call (NaN: no command seen for its output yet)
        pwm = [self._pwm_of(motors[j]) for j in slots]  # type: ignore[arg-type]
        throttle = mavlink_esc.throttle_from_pwm(pwm, self.pwm_low, self.pwm_high)
        voltage, current = mavlink_esc.motor_inputs(throttle, bus, si["esc_current_a"])
        return [
            MotorSample(
                motor=int(motors[j]),
                time_s=time_s,
                omega_rad_s=omega,
                current_a=motor_a,
                voltage_v=volts,
                bus_voltage_v=bus_v,
                throttle=command,
                esc_current_a=esc_a,
                esc_temp_c=temp,
                battery_current_a=self.battery_a,
            )
            for j, omega, motor_a, volts, bus_v, command, esc_a, temp in zip(
                slots,
                si["omega_rad_s"].tolist(),
                current.tolist(),
                voltage.tolist(),
                bus.tolist(),
                throttle.tolist(),
                si["esc_current_a"].tolist(),
                si["esc_temp_c"].tolist(),
            )
        ]

    def _pwm_of(self, motor: int) -> float:
        output = self.output_of_motor.get(motor)
        pwm = self.pwm_us.get(output) if output is not None else None
        return math.nan if pwm is None else pwm
