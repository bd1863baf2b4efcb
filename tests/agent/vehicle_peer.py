"""A MAVLink vehicle for the agent's tests: real UDP sockets, real pymavlink encoding, driven by the test.

It behaves like ArduPilot where the agent depends on it: HEARTBEAT as a hexacopter, streams only what was
asked for with MAV_CMD_SET_MESSAGE_INTERVAL (one ESC_TELEMETRY_1_TO_4 request drives 1_TO_4 and 5_TO_8),
answers PARAM_REQUEST_READ, repeats a silent ESC's last values with a frozen ``count``, forgets the
requested streams on reboot, and routes what the companion computer sends to a ground-station link.
Motors follow the paper's steady-state model (``faulty_steady_state``) at a constant throttle with
seeded noise; ``inject`` puts a fault on a motor.
"""

from __future__ import annotations

import contextlib
import math
import select
import socket
import threading
import time
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from mav_motor_health.model.params import MotorParams
from mav_motor_health.publish import dialect
from mav_motor_health.sim.steady import faulty_steady_state

dialect.register(mavlink2)  # so the vehicle decodes the agent's MOTOR_HEALTH


class _Sink:
    def __init__(self, peer: VehiclePeer) -> None:
        self.peer = peer

    def write(self, data: bytes) -> None:
        self.peer._send_raw(bytes(data))


class VehiclePeer:
    """``with VehiclePeer(params) as v: ...``; the agent connects to ``udpout:127.0.0.1:{v.port}``."""

    def __init__(
        self,
        params: MotorParams,
        *,
        motors: int = 6,
        bus_v: float = 12.0,
        throttle: float = 0.6,
        seed: int = 7,
        system_id: int = 1,
        gcs_port: int | None = None,
        params_table: dict[str, float] | None = None,
    ) -> None:
        self.params = params
        self.motors = motors
        self.bus_v = bus_v
        self.throttle = throttle
        self.rng = np.random.default_rng(seed)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.gcs_addr = ("127.0.0.1", gcs_port) if gcs_port else None
        self.gcs_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM) if gcs_port else None
        if self.gcs_sock is not None:
            self.gcs_sock.bind(("127.0.0.1", 0))
        self.agent_addr: tuple[str, int] | None = None
        self.enc = mavlink2.MAVLink(_Sink(self), system_id, 1)
        self.parser = mavlink2.MAVLink(None, 0, 0)
        self.parser.robust_parsing = True
        self.gcs_parser = mavlink2.MAVLink(None, 0, 0)
        self.gcs_parser.robust_parsing = True
        self.lock = threading.Lock()
        self.received: list[tuple[float, Any]] = []
        self.intervals: dict[int, float] = {}  # message id → interval s
        self.faults: dict[int, tuple[str, float]] = {}
        self.silent: set[int] = set()
        self.link_up = True
        self.param_values = {f"SERVO{n}_FUNCTION": 32.0 + n for n in range(1, motors + 1)}
        self.param_values.update({f"SERVO{n}_FUNCTION": 0.0 for n in range(motors + 1, 17)})
        self.param_values.update({"MOT_PWM_MIN": 1000.0, "MOT_PWM_MAX": 2000.0})
        self.param_values.update(params_table or {})
        self.boot_s = time.monotonic()
        self.counts = [0] * 12
        self.last_esc: dict[int, tuple[int, int, int, int]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="vehicle-peer", daemon=True)
        self._cache: dict[tuple[str, float], tuple[float, float]] = {}

    # -- test controls -----------------------------------------------------------------------------
    def __enter__(self) -> VehiclePeer:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)
        self.sock.close()
        if self.gcs_sock is not None:
            self.gcs_sock.close()

    def inject(self, motor: int, fault: str, severity: float = 1.0) -> float:
        """Put a fault on a motor now; returns the onset time (time.monotonic())."""
        with self.lock:
            if fault == "NORMAL":
                self.faults.pop(motor, None)
            else:
                self.faults[motor] = (fault, severity)
            return time.monotonic()

    def reboot(self) -> None:
        """Boot clock back to zero; requested streams forgotten (as an autopilot reboot does)."""
        with self.lock:
            self.boot_s = time.monotonic()
            self.intervals.clear()

    def messages(self, kind: str) -> list[tuple[float, Any]]:
        with self.lock:
            return [(t, m) for t, m in self.received if m.get_type() == kind]

    # -- the vehicle --------------------------------------------------------------------------------
    def _send_raw(self, data: bytes) -> None:
        if self.agent_addr is not None and self.link_up:
            with contextlib.suppress(OSError):
                self.sock.sendto(data, self.agent_addr)

    def _to_gcs(self, data: bytes) -> None:
        if self.gcs_sock is not None and self.gcs_addr is not None:
            with contextlib.suppress(OSError):
                self.gcs_sock.sendto(data, self.gcs_addr)

    def _send(self, msg: Any) -> None:
        buf = msg.pack(self.enc)
        self._send_raw(buf)
        if msg.get_type() in ("HEARTBEAT",):
            self._to_gcs(buf)

    def _run(self) -> None:
        next_at: dict[str, float] = {}
        while not self._stop.is_set():
            now = time.monotonic()
            socks = [self.sock] + ([self.gcs_sock] if self.gcs_sock is not None else [])
            ready, _, _ = select.select(socks, [], [], 0.002)
            for sock in ready:
                try:
                    data, addr = sock.recvfrom(65535)
                except OSError:
                    continue
                if sock is self.sock:
                    if not self.link_up:
                        continue
                    self.agent_addr = addr
                    self._handle(data, now)
            if not self.link_up:
                continue
            with self.lock:
                schedule = [("hb", 1.0), ("systime", 1.0)]
                esc_interval = self.intervals.get(11030)
                if esc_interval:
                    schedule.append(("esc", esc_interval))
                servo_interval = self.intervals.get(36)
                if servo_interval:
                    schedule.append(("servo", servo_interval))
                if self.intervals.get(1):
                    schedule.append(("sys", self.intervals[1]))
            for name, period in schedule:
                if now >= next_at.get(name, 0.0):
                    next_at[name] = max(next_at.get(name, 0.0) + period, now)
                    getattr(self, f"_emit_{name}")(now)

    def _handle(self, data: bytes, now: float) -> None:
        try:
            msgs = self.parser.parse_buffer(data) or []
        except mavlink2.MAVError:
            return
        for msg in msgs:
            kind = msg.get_type()
            if kind == "BAD_DATA":
                continue
            with self.lock:
                self.received.append((now, msg))
            if kind == "COMMAND_LONG" and msg.command == mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL:
                with self.lock:
                    if msg.param2 > 0:
                        self.intervals[int(msg.param1)] = msg.param2 / 1e6
                    else:
                        self.intervals.pop(int(msg.param1), None)
                self._send(self.enc.command_ack_encode(msg.command, mavlink2.MAV_RESULT_ACCEPTED))
            elif kind == "PARAM_REQUEST_READ":
                name = msg.param_id.rstrip("\x00")
                if name in self.param_values:
                    self._send(
                        self.enc.param_value_encode(
                            name.encode(),
                            self.param_values[name],
                            mavlink2.MAV_PARAM_TYPE_REAL32,
                            len(self.param_values),
                            0,
                        )
                    )
            if kind in ("STATUSTEXT", "NAMED_VALUE_INT", "NAMED_VALUE_FLOAT", "MOTOR_HEALTH"):
                self._to_gcs(msg.get_msgbuf())  # route the companion's messages to the ground station

    def _emit_hb(self, now: float) -> None:
        self._send(
            self.enc.heartbeat_encode(
                mavlink2.MAV_TYPE_HEXAROTOR,
                mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
                mavlink2.MAV_MODE_FLAG_SAFETY_ARMED | mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                0,
                mavlink2.MAV_STATE_ACTIVE,
            )
        )

    def _emit_systime(self, now: float) -> None:
        self._send(
            self.enc.system_time_encode(int(time.time() * 1e6), max(0, int((now - self.boot_s) * 1000)))
        )

    def _emit_sys(self, now: float) -> None:
        self._send(
            self.enc.sys_status_encode(0, 0, 0, 500, int(self.bus_v * 1000), 2000, 80, 0, 0, 0, 0, 0, 0)
        )

    def _pwm(self) -> int:
        return round(1000 + 1000 * self.throttle)

    def _emit_servo(self, now: float) -> None:
        pwm = [self._pwm() if n <= self.motors else 0 for n in range(1, 9)]
        self._send(
            self.enc.servo_output_raw_encode(max(0, int((now - self.boot_s) * 1e6)) & 0xFFFFFFFF, 0, *pwm)
        )

    def _motor_truth(self, motor: int) -> tuple[float, float]:
        with self.lock:
            fault, severity = self.faults.get(motor, ("NORMAL", 1.0))
        key = (fault, severity)
        if key not in self._cache:
            throttle = (self._pwm() - 1000) / 1000
            w, i = faulty_steady_state(self.params, fault, [throttle * self.bus_v], severity)
            self._cache[key] = (float(w[0]), float(i[0]))
        return self._cache[key]

    def _emit_esc(self, now: float) -> None:
        throttle = (self._pwm() - 1000) / 1000
        slots = []
        for motor in range(1, 13):
            if motor > self.motors:
                slots.append((0, 0, 0, 0))
                continue
            with self.lock:
                silent = motor in self.silent
            if silent and motor in self.last_esc:
                slots.append(self.last_esc[motor])  # ArduPilot repeats the last values, count frozen
                continue
            w, i = self._motor_truth(motor)
            w += self.rng.uniform(-5.0, 5.0)
            i += self.rng.uniform(-0.05, 0.05)
            self.counts[motor - 1] = (self.counts[motor - 1] + 1) & 0xFFFF
            values = (
                max(0, round(w * 60 / (2 * math.pi))),
                round(self.bus_v * 100),
                max(0, round(i * throttle * 100)),
                self.counts[motor - 1],
            )
            self.last_esc[motor] = values
            slots.append(values)
        for group, encode in (
            (0, self.enc.esc_telemetry_1_to_4_encode),
            (4, self.enc.esc_telemetry_5_to_8_encode),
        ):
            part = slots[group : group + 4]
            if not any(v[0] or v[3] for v in part):
                continue
            self._send(
                encode(
                    [30] * 4,
                    [v[1] for v in part],
                    [v[2] for v in part],
                    [0] * 4,
                    [v[0] for v in part],
                    [v[3] for v in part],
                )
            )
