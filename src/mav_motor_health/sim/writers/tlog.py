"""MAVLink telemetry logs (``.tlog``) as a ground station records what ArduPilot streams.

A tlog is a sequence of ``[8-byte big-endian µs since 1970][MAVLink packet]``. The file starts with the
parameters a ground station fetches on connecting (PARAM_VALUE, including SERVOn_FUNCTION,
MOT_PWM_MIN/MAX, FRAME_CLASS/TYPE), then the streams: HEARTBEAT, SYS_STATUS and BATTERY_STATUS at
1 Hz; SERVO_OUTPUT_RAW, ATTITUDE, VFR_HUD and GLOBAL_POSITION_INT at ``log_hz``; ESC_TELEMETRY_1_TO_4 and
_5_TO_8 at ``esc_stream_hz`` carrying each ESC's latest report (its ``count`` rises with each new one),
as ArduPilot's AP_ESC_Telem does. Encoded with pymavlink's ``ardupilotmega`` dialect (MAVLink 2).
"""

from __future__ import annotations

import math
import struct
from pathlib import Path
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from ..engine import SimRecord

__all__ = ["START_EPOCH_S", "esc_telemetry_messages", "heartbeat", "param_messages", "write_tlog"]

#: wall-clock time of t = 0 in the files (fixed, so files are reproducible)
START_EPOCH_S = 1_622_505_600.0  # 2021-06-01 00:00:00 UTC
COPTER_MODE_LOITER = 5
BASE_MODE_ARMED = (
    mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
    | mavlink.MAV_MODE_FLAG_SAFETY_ARMED
)


def _mav() -> Any:
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    mav.robust_parsing = True
    return mav


def heartbeat(mav: Any) -> Any:
    return mav.heartbeat_encode(
        mavlink.MAV_TYPE_HEXAROTOR,
        mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
        BASE_MODE_ARMED,
        COPTER_MODE_LOITER,
        mavlink.MAV_STATE_ACTIVE,
    )


def param_messages(mav: Any, params: dict[str, float]) -> list[Any]:
    names = sorted(params)
    return [
        mav.param_value_encode(
            name.encode(), float(params[name]), mavlink.MAV_PARAM_TYPE_REAL32, len(names), k
        )
        for k, name in enumerate(names)
    ]


def esc_telemetry_messages(mav: Any, latest: list[tuple[int, int, int, int, int, int] | None]) -> list[Any]:
    """ESC_TELEMETRY_1_TO_4 / _5_TO_8 from per-ESC ``(temp_c, voltage_cv, current_ca, total_mah, rpm,
    count)`` (None: no report yet)."""
    out = []
    for first in range(0, len(latest), 4):
        group = latest[first : first + 4]
        group = group + [None] * (4 - len(group))
        fields = [[0] * 4 for _ in range(6)]
        for k, item in enumerate(group):
            if item is not None:
                for f in range(6):
                    fields[f][k] = item[f]
        temp, volt, curr, total, rpm, count = fields
        temp = [max(0, min(255, t)) for t in temp]
        clip16 = [[max(0, min(65535, v)) for v in arr] for arr in (volt, curr, total, rpm, count)]
        encode = mav.esc_telemetry_1_to_4_encode if first == 0 else mav.esc_telemetry_5_to_8_encode
        out.append(encode(temp, *clip16))
    return out


def write_tlog(record: SimRecord, path: Path) -> None:
    mav = _mav()
    events: list[tuple[float, int, bytes]] = []
    seq = 0

    def add(t: float, msg: Any) -> None:
        nonlocal seq
        events.append((t, seq, msg.pack(mav)))
        seq += 1

    add(0.0, heartbeat(mav))
    for msg in param_messages(mav, record.params):
        add(0.0, msg)
    vehicle = record.vehicle
    last_1hz = -1.0
    for v in vehicle:
        t = v.time_s
        if t - last_1hz >= 1.0 - 1e-9:
            last_1hz = t
            add(t, heartbeat(mav))
            mv = round(v.bus_voltage_v * 1000)
            # -1: not measured (MAVLink's convention; a testbed's supply has no monitor reading at t = 0)
            ca = -1 if math.isnan(v.battery_current_a) else round(v.battery_current_a * 100)
            add(t, mav.sys_status_encode(0, 0, 0, 500, mv, ca, v.remaining_pct, 0, 0, 0, 0, 0, 0))
            cells = [65535] * 10
            cells[0] = mv
            add(
                t,
                mav.battery_status_encode(
                    0,
                    mavlink.MAV_BATTERY_FUNCTION_ALL,
                    mavlink.MAV_BATTERY_TYPE_LIPO,
                    32767,
                    cells,
                    ca,
                    round(v.consumed_mah),
                    -1,
                    v.remaining_pct,
                ),
            )
        pwm = list(v.pwm_us) + [0] * (16 - len(v.pwm_us))
        add(t, mav.servo_output_raw_encode(int(t * 1e6) & 0xFFFFFFFF, 0, *pwm[:8], *pwm[8:16]))
        add(t, mav.attitude_encode(int(t * 1000), v.roll_rad, v.pitch_rad, v.yaw_rad, 0.0, 0.0, 0.0))
        speed = math.hypot(v.vel_ned_m_s[0], v.vel_ned_m_s[1])
        heading = int(math.degrees(v.yaw_rad)) % 360
        add(t, mav.vfr_hud_encode(speed, speed, heading, v.throttle_pct, v.alt_m, v.climb_m_s))
        add(
            t,
            mav.global_position_int_encode(
                int(t * 1000),
                round(v.lat_deg * 1e7),
                round(v.lon_deg * 1e7),
                round(v.alt_m * 1000),
                round(v.alt_m * 1000),
                *(round(x * 100) for x in v.vel_ned_m_s),
                heading * 100,
            ),
        )
    _add_esc_stream(record, mav, add)
    events.sort(key=lambda e: (e[0], e[1]))
    with path.open("wb") as handle:
        for t, _, packet in events:
            handle.write(struct.pack(">Q", round((START_EPOCH_S + t) * 1e6)))
            handle.write(packet)


def _add_esc_stream(record: SimRecord, mav: Any, add: Any) -> None:
    sc = record.scenario
    n = sc.n_motors
    cols = record.esc_columns()
    if not len(cols["time_s"]):
        return
    per_motor = []
    for m in range(1, n + 1):
        sel = np.flatnonzero(cols["motor"] == m)
        t = cols["time_s"][sel]
        esc_a = cols["esc_current_a"][sel]
        # total consumption of this ESC [mAh], integrated over its reports
        total = np.concatenate([[0.0], np.cumsum(esc_a[1:] * np.diff(t))]) / 3.6 if t.size else t
        per_motor.append((t, sel, total))
    period = 1.0 / sc.esc_stream_hz
    samples = record.esc
    for tick in np.arange(period, sc.duration_s + 1e-9, period):
        latest: list[tuple[int, int, int, int, int, int] | None] = []
        for t, sel, total in per_motor:
            k = int(np.searchsorted(t, tick, side="right")) - 1
            if k < 0:
                latest.append(None)
                continue
            s = samples[int(sel[k])]
            latest.append(
                (s.temp_c, s.voltage_cv, s.esc_current_ca, round(float(total[k])), s.rpm, s.reports)
            )
        for msg in esc_telemetry_messages(mav, latest):
            add(float(tick), msg)
