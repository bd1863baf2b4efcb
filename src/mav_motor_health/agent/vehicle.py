"""Finding the autopilot, noticing it leave, come back or reboot, and what to ask it for.

:class:`AutopilotTracker` is a small state machine over received messages and the link's clock (no I/O):
it picks the autopilot from HEARTBEATs (ArduPilot or PX4, by ``autopilot``), declares the link lost when
HEARTBEATs stop for ``heartbeat_timeout_s``, and detects a reboot from the autopilot's boot clock
(``SYSTEM_TIME.time_boot_ms`` going backwards; a reboot slower than the HEARTBEAT timeout is a loss
and a return). Each of ``found``,
``returned`` and ``rebooted`` means: ask for the streams and parameters again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

__all__ = ["AutopilotTracker", "stream_requests", "wanted_params"]

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12
MAV_AUTOPILOT_INVALID = 8
_NOT_VEHICLES = {6, 18, 26, 27, 30}  # GCS, onboard controller, gimbal, ADSB, camera... (MAV_TYPE)

MSG_SYS_STATUS = 1
MSG_SYSTEM_TIME = 2
MSG_SERVO_OUTPUT_RAW = 36
MSG_BATTERY_STATUS = 147
MSG_ESC_INFO = 290
MSG_ESC_STATUS = 291
MSG_ESC_TELEMETRY_1_TO_4 = 11030


def stream_requests(autopilot: str | None, esc_rate_hz: float) -> list[tuple[int, float]]:
    """(message id, rate Hz) pairs to ask for with MAV_CMD_SET_MESSAGE_INTERVAL.

    On ArduPilot one request for ESC_TELEMETRY_1_TO_4 makes it send every ESC_TELEMETRY group it has
    (5_TO_8 for a hexacopter too); PX4 sends ESC_STATUS and ESC_INFO.
    """
    common = [
        (MSG_SERVO_OUTPUT_RAW, esc_rate_hz),
        (MSG_SYS_STATUS, 2.0),
        (MSG_BATTERY_STATUS, 2.0),
        (MSG_SYSTEM_TIME, 1.0),
    ]
    ardupilot = [(MSG_ESC_TELEMETRY_1_TO_4, esc_rate_hz)]
    px4 = [(MSG_ESC_STATUS, esc_rate_hz), (MSG_ESC_INFO, 1.0)]
    if autopilot == "ardupilot":
        return ardupilot + common
    if autopilot == "px4":
        return px4 + common
    return ardupilot + px4 + common


def wanted_params(autopilot: str | None, motors: int) -> list[str]:
    """Parameters the motor mapping and throttle need (ArduPilot names; PX4 uses the defaults)."""
    if autopilot == "px4":
        return []
    outputs = max(motors, 8)
    return [f"SERVO{n}_FUNCTION" for n in range(1, outputs + 1)] + ["MOT_PWM_MIN", "MOT_PWM_MAX"]


@dataclass
class AutopilotTracker:
    """Which autopilot we talk to, and whether it is there."""

    heartbeat_timeout_s: float = 3.0
    system: int | None = None
    component: int | None = None
    autopilot: str | None = None
    last_heartbeat_s: float = -math.inf
    up: bool = False
    boot_ms: float = math.nan
    reboots: int = 0
    losses: int = 0

    def on_message(self, msg: Any, now_s: float) -> str | None:
        """Update from one message; returns ``found``, ``returned``, ``rebooted`` or None."""
        kind = msg.get_type()
        src_system, src_component = msg.get_srcSystem(), msg.get_srcComponent()
        if kind == "HEARTBEAT":
            if msg.autopilot == MAV_AUTOPILOT_INVALID or msg.type in _NOT_VEHICLES:
                return None
            if self.system is None:
                self.system, self.component = src_system, src_component
                self.autopilot = {MAV_AUTOPILOT_ARDUPILOTMEGA: "ardupilot", MAV_AUTOPILOT_PX4: "px4"}.get(
                    msg.autopilot, "generic"
                )
                self.last_heartbeat_s, self.up = now_s, True
                return "found"
            if (src_system, src_component) != (self.system, self.component):
                return None
            self.last_heartbeat_s = now_s
            if not self.up:
                self.up = True
                return "returned"
            return None
        if src_system != self.system or src_component != self.component:
            return None
        if kind == "SYSTEM_TIME":
            boot_ms = float(msg.time_boot_ms)
            previous, self.boot_ms = self.boot_ms, boot_ms
            if previous - boot_ms > 1000.0:
                self.reboots += 1
                return "rebooted"
        return None

    def check(self, now_s: float) -> str | None:
        """``lost`` once when HEARTBEATs have stopped for longer than the timeout."""
        if self.up and now_s - self.last_heartbeat_s > self.heartbeat_timeout_s:
            self.up = False
            self.losses += 1
            return "lost"
        return None
