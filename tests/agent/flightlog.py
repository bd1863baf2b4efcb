"""A synthetic hexacopter flight written as a real .tlog, and the same samples as a telemetry table.

Six motors at 50 Hz follow the paper's steady-state model with seeded noise and input steps; faults
come and go. The .tlog holds what ArduPilot streams (SERVO_OUTPUT_RAW, ESC_TELEMETRY_1_TO_4/5_TO_8,
SYS_STATUS with the battery monitor's current, PARAM_VALUE) with MAVLink's integer quantisation; :func:`table_from_fields` turns the same integers into
the telemetry table with the shared ``mavlink_esc`` functions, as a log reader does.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from mav_motor_health.model.params import MotorParams
from mav_motor_health.sim.steady import faulty_steady_state
from mav_motor_health.telemetry import mavlink_esc
from mav_motor_health.telemetry.table import TelemetryTable

#: The .tlog starts with HEARTBEAT and parameters this long before the first sample.
FIRST_RECORD_LEAD_US = 500_000
#: Output → motor as SERVOn_FUNCTION says (outputs 1 and 2 swapped: the mapping must be honoured).
FUNCTIONS = {1: 34, 2: 33, 3: 35, 4: 36, 5: 37, 6: 38, 7: 0, 8: 0}


@dataclass(frozen=True)
class Fault:
    motor: int
    fault: str
    start_s: float
    end_s: float = math.inf
    severity: float = 1.0


DEFAULT_FAULTS = (
    Fault(2, "F3.1", 6.0),
    Fault(4, "F1.1", 8.0, 11.0),
    Fault(5, "F2.1", 13.0, 15.0),
    Fault(6, "F4.1", 4.0, 5.0, severity=2.0),
)


@dataclass
class FlightFields:
    """Raw MAVLink integers per tick (rows) and output (columns 0..7)."""

    stamp_us: np.ndarray
    pwm: np.ndarray
    rpm: np.ndarray
    voltage_cv: np.ndarray
    current_ca: np.ndarray
    temperature: np.ndarray
    count: np.ndarray
    battery_ca: np.ndarray  # the battery monitor's current per tick [cA]


#: from this time on the battery monitor reads 3 × the ESC currents' sum (a mis-scaled sensor)
BATTERY_MISSCALED_FROM_S = 13.0


def make_fields(
    params: MotorParams,
    seed: int = 11,
    duration_s: float = 18.0,
    rate_hz: float = 50.0,
    faults=DEFAULT_FAULTS,
) -> FlightFields:
    rng = np.random.default_rng(seed)
    ticks = int(duration_s * rate_hz)
    stamp_us = 1_700_000_000_000_000 + np.arange(ticks, dtype=np.int64) * int(1e6 / rate_hz)
    t = np.arange(ticks) / rate_hz
    bus_v = 12.0
    # throttle: 0.55 with steps (a climb at 3 s, back at 9.5 s) and a slow wander below the step size
    throttle = 0.55 + 0.1 * ((t >= 3.0) & (t < 9.5)) + 0.003 * np.sin(2 * np.pi * 0.3 * t)
    pwm_motor = np.round(1000 + 1000 * throttle).astype(np.int64)
    thr_q = (pwm_motor - 1000) / 1000.0
    motor_of_output = {o: f - 32 for o, f in FUNCTIONS.items() if f}
    shape = (ticks, 8)
    pwm = np.zeros(shape, np.int64)
    rpm = np.zeros(shape, np.int64)
    cv = np.zeros(shape, np.int64)
    ca = np.zeros(shape, np.int64)
    temp = np.full(shape, 35, np.int64)
    count = np.zeros(shape, np.int64)
    for output, motor in motor_of_output.items():
        col = output - 1
        pwm[:, col] = pwm_motor
        w, i = faulty_steady_state(params, "NORMAL", thr_q * bus_v)
        for f in faults:
            if f.motor != motor:
                continue
            active = (t >= f.start_s) & (t < f.end_s)
            wf, i_f = faulty_steady_state(params, f.fault, thr_q[active] * bus_v, f.severity)
            w = w.copy()
            i = i.copy()
            w[active], i[active] = wf, i_f
        w = w + rng.uniform(-6.0, 6.0, ticks)
        i = i + rng.uniform(-0.08, 0.08, ticks)
        rpm[:, col] = np.maximum(np.round(w * 60 / (2 * np.pi)), 0)
        cv[:, col] = round(bus_v * 100) + rng.integers(-3, 4, ticks)
        ca[:, col] = np.maximum(np.round(i * thr_q * 100), 0)
        count[:, col] = np.arange(1, ticks + 1) % 65536
    battery_ca = ca.sum(axis=1) + 60  # the ESCs and 0.6 A of avionics
    battery_ca = np.where(t >= BATTERY_MISSCALED_FROM_S, 3 * battery_ca, battery_ca)
    return FlightFields(stamp_us, pwm, rpm, cv, ca, temp, count, battery_ca)


def write_tlog(fields: FlightFields, path: Path) -> Path:
    mav = mavlink2.MAVLink(None, 1, 1)
    out = bytearray()

    def put(stamp: int, msg) -> None:
        out.extend(struct.pack(">Q", int(stamp)))
        out.extend(msg.pack(mav))

    first = int(fields.stamp_us[0]) - FIRST_RECORD_LEAD_US
    put(first, mav.heartbeat_encode(13, 3, 0, 0, 4))
    for n, (output, function) in enumerate(FUNCTIONS.items()):
        put(first + n, mav.param_value_encode(f"SERVO{output}_FUNCTION".encode(), function, 9, 10, n))
    put(first + 20, mav.param_value_encode(b"MOT_PWM_MIN", 1000, 9, 10, 8))
    put(first + 21, mav.param_value_encode(b"MOT_PWM_MAX", 2000, 9, 10, 9))
    for k, stamp in enumerate(fields.stamp_us.tolist()):
        put(stamp, mav.servo_output_raw_encode(k & 0xFFFFFFFF, 0, *fields.pwm[k].tolist()))
        put(stamp, mav.sys_status_encode(0, 0, 0, 0, 12000, int(fields.battery_ca[k]), -1, 0, 0, 0, 0, 0, 0))
        for group, encode in ((0, mav.esc_telemetry_1_to_4_encode), (4, mav.esc_telemetry_5_to_8_encode)):
            sl = slice(group, group + 4)
            put(
                stamp,
                encode(
                    fields.temperature[k, sl].tolist(),
                    fields.voltage_cv[k, sl].tolist(),
                    fields.current_ca[k, sl].tolist(),
                    [0] * 4,
                    fields.rpm[k, sl].tolist(),
                    fields.count[k, sl].tolist(),
                ),
            )
    path.write_bytes(bytes(out))
    return path


def table_from_fields(fields: FlightFields) -> TelemetryTable:
    """The same integers as a log reader would tabulate them (one row per motor sample)."""
    params = {f"SERVO{o}_FUNCTION": float(f) for o, f in FUNCTIONS.items()}
    low, high = mavlink_esc.pwm_range({"MOT_PWM_MIN": 1000, "MOT_PWM_MAX": 2000})
    cols: dict[str, list[np.ndarray]] = {
        k: []
        for k in (
            "time_s",
            "motor",
            "omega_rad_s",
            "current_a",
            "voltage_v",
            "bus_voltage_v",
            "throttle",
            "esc_current_a",
            "esc_temp_c",
            "battery_current_a",
            "pairing_s",
            "command_age_s",
        )
    }
    time_s = (
        fields.stamp_us - (int(fields.stamp_us[0]) - FIRST_RECORD_LEAD_US)
    ) / 1e6  # from the first record
    for output in range(1, 9):
        motor = mavlink_esc.motor_for_output(output, params)
        if motor is None:
            continue
        col = output - 1
        si = mavlink_esc.esc_fields_to_si(
            fields.temperature[:, col],
            fields.voltage_cv[:, col],
            fields.current_ca[:, col],
            fields.rpm[:, col],
        )
        throttle = mavlink_esc.throttle_from_pwm(fields.pwm[:, col], low, high)
        voltage, current = mavlink_esc.motor_inputs(throttle, si["bus_voltage_v"], si["esc_current_a"])
        cols["time_s"].append(time_s)
        cols["motor"].append(np.full(time_s.shape, motor))
        cols["omega_rad_s"].append(si["omega_rad_s"])
        cols["current_a"].append(current)
        cols["voltage_v"].append(voltage)
        cols["bus_voltage_v"].append(si["bus_voltage_v"])
        cols["throttle"].append(throttle)
        cols["esc_current_a"].append(si["esc_current_a"])
        cols["esc_temp_c"].append(si["esc_temp_c"])
        cols["battery_current_a"].append(fields.battery_ca / 100.0)
        # each ESC message carries the ESC's last packet, measured since the motor's message before (a
        # tick: the reader's pairing, telemetry/assemble.py; the command comes with the message: age 0)
        cols["pairing_s"].append(np.diff(time_s, prepend=time_s[0]))
        cols["command_age_s"].append(np.zeros(time_s.shape))
    return TelemetryTable({k: np.concatenate(v) for k, v in cols.items()}, source="synthetic flight")
