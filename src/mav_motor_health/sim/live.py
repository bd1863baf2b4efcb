"""A live simulated vehicle on a MAVLink link: an ArduPilot hexacopter whose motors can fail.

:class:`SimVehicle` runs :class:`~mav_motor_health.sim.engine.Simulation` in a background thread and
speaks MAVLink (pymavlink, ``ardupilotmega`` dialect) on a pymavlink connection URL:
``udpout:HOST:PORT`` (send to a ground station listening there), ``udpin:HOST:PORT`` (listen; answer
whoever sends), ``tcpin:HOST:PORT`` (TCP server) or ``tcp:HOST:PORT`` (TCP client).

What it does, as ArduCopter would:

* HEARTBEAT 1 Hz: ``MAV_TYPE_HEXAROTOR``, ``MAV_AUTOPILOT_ARDUPILOTMEGA``, armed, LOITER;
* streams SYS_STATUS, BATTERY_STATUS (1 Hz), SERVO_OUTPUT_RAW, ATTITUDE (10 Hz), VFR_HUD,
  GLOBAL_POSITION_INT (4 Hz), ESC_TELEMETRY_1_TO_4 / _5_TO_8 (10 Hz) — rates in *simulated* time;
* ``MAV_CMD_SET_MESSAGE_INTERVAL`` (per message: µs, −1 off, 0 default) and ``REQUEST_DATA_STREAM``
  (ArduPilot's stream groups) change the rates; answered with COMMAND_ACK;
* PARAM_REQUEST_LIST / PARAM_REQUEST_READ / PARAM_SET (echoed with PARAM_VALUE);
* records every STATUSTEXT, NAMED_VALUE_FLOAT and NAMED_VALUE_INT it receives
  (:attr:`SimVehicle.received`, also logged with :mod:`logging`, and ``on_message`` callback);
* fault injection at run time:

  - parameters ``SIM_MOT_FAULT`` (0 none, 1 F1.1, 2 F2.1, 3 F3.1, 4 F4.1, 5 F4.2), ``SIM_MOT_FLT_NUM``
    (motor 1–6) and ``SIM_MOT_FLT_SEV`` (severity 0–1; 0 = the paper's strength): setting
    ``SIM_MOT_FAULT`` starts the fault now on that motor, setting it to 0 clears all faults;
  - ``COMMAND_LONG`` ``MAV_CMD_USER_1`` (31010) with param1 = fault code, param2 = motor,
    param3 = severity does the same in one message;
  - or from Python: :meth:`SimVehicle.inject`.

``speed`` runs the simulation faster (or slower) than real time. Use as a context manager::

    with SimVehicle(load_scenario("flight/healthy_calm"), "udpout:127.0.0.1:14550", speed=4) as vehicle:
        ...  # a ground station or the agent listens on udpin:127.0.0.1:14550
        vehicle.inject("F2.1", motor=3)

or ``async with`` from asyncio (start and stop run in a worker thread).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import math
import threading
import time
from collections.abc import Callable
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from ..errors import LinkError
from .engine import Simulation
from .faults import FAULT_KINDS, FaultSpec
from .scenario import Scenario
from .writers.tlog import esc_telemetry_messages, heartbeat

__all__ = ["DEFAULT_RATES_HZ", "FAULT_CODES", "ReceivedMessage", "SimVehicle", "mavlink2_connection"]

log = logging.getLogger(__name__)

#: SIM_MOT_FAULT value → fault
FAULT_CODES = {k + 1: kind for k, kind in enumerate(FAULT_KINDS)}
MAV_CMD_USER_1 = 31010
#: default stream rates [Hz of simulated time], as ArduCopter's SRx defaults roughly are
DEFAULT_RATES_HZ: dict[str, float] = {
    "HEARTBEAT": 1.0,
    "SYS_STATUS": 1.0,
    "BATTERY_STATUS": 1.0,
    "SERVO_OUTPUT_RAW": 10.0,
    "ATTITUDE": 10.0,
    "VFR_HUD": 4.0,
    "GLOBAL_POSITION_INT": 4.0,
    "ESC_TELEMETRY": 10.0,
}
#: REQUEST_DATA_STREAM groups (ArduPilot's GCS_MAVLink stream lists, the messages we produce)
STREAM_GROUPS: dict[int, tuple[str, ...]] = {
    mavlink.MAV_DATA_STREAM_EXTENDED_STATUS: ("SYS_STATUS",),
    mavlink.MAV_DATA_STREAM_RC_CHANNELS: ("SERVO_OUTPUT_RAW",),
    mavlink.MAV_DATA_STREAM_POSITION: ("GLOBAL_POSITION_INT",),
    mavlink.MAV_DATA_STREAM_EXTRA1: ("ATTITUDE",),
    mavlink.MAV_DATA_STREAM_EXTRA2: ("VFR_HUD",),
    mavlink.MAV_DATA_STREAM_EXTRA3: ("BATTERY_STATUS", "ESC_TELEMETRY"),
}
_MSG_IDS = {
    "HEARTBEAT": mavlink.MAVLINK_MSG_ID_HEARTBEAT,
    "SYS_STATUS": mavlink.MAVLINK_MSG_ID_SYS_STATUS,
    "BATTERY_STATUS": mavlink.MAVLINK_MSG_ID_BATTERY_STATUS,
    "SERVO_OUTPUT_RAW": mavlink.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW,
    "ATTITUDE": mavlink.MAVLINK_MSG_ID_ATTITUDE,
    "VFR_HUD": mavlink.MAVLINK_MSG_ID_VFR_HUD,
    "GLOBAL_POSITION_INT": mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
    "ESC_TELEMETRY": mavlink.MAVLINK_MSG_ID_ESC_TELEMETRY_1_TO_4,
}
_ESC_5_TO_8 = mavlink.MAVLINK_MSG_ID_ESC_TELEMETRY_5_TO_8


def mavlink2_connection(url: str, **kwargs: Any) -> Any:
    """A pymavlink connection that speaks MAVLink 2 with the ``ardupilotmega`` dialect.

    ``mavutil.mavlink_connection`` picks MAVLink 1 unless the process-wide ``MAVLINK20`` environment
    variable is set; ArduPilot's ESC_TELEMETRY and SERVO_OUTPUT_RAW extensions need MAVLink 2, so the
    connection's encoder/parser is replaced by the MAVLink 2 one (which also reads MAVLink 1).
    """
    conn = mavutil.mavlink_connection(url, dialect="ardupilotmega", autoreconnect=True, **kwargs)
    conn.mav = mavlink.MAVLink(
        conn, srcSystem=kwargs.get("source_system", 255), srcComponent=kwargs.get("source_component", 0)
    )
    conn.mav.robust_parsing = True
    conn.WIRE_PROTOCOL_VERSION = "2.0"
    return conn


@dataclasses.dataclass(frozen=True)
class ReceivedMessage:
    """A STATUSTEXT or NAMED_VALUE_* the vehicle received."""

    sim_time_s: float
    wall_time_s: float
    type: str
    fields: dict[str, Any]
    source_system: int
    source_component: int


class SimVehicle:
    """A simulated ArduPilot hexacopter on a MAVLink connection, run in a background thread."""

    def __init__(
        self,
        scenario: Scenario,
        url: str,
        *,
        speed: float = 1.0,
        system_id: int = 1,
        component_id: int = 1,
        on_message: Callable[[ReceivedMessage], None] | None = None,
    ) -> None:
        if scenario.mode != "flight":
            scenario = dataclasses.replace(scenario, mode="flight", dt_s=0.01)
        if not speed > 0:
            raise ValueError("speed must be > 0")
        self.scenario = dataclasses.replace(scenario, duration_s=math.inf)
        self.url = url
        self.speed = speed
        self.system_id, self.component_id = system_id, component_id
        self.on_message = on_message
        self.sim = Simulation(self.scenario)
        self.params: dict[str, float] = self.sim.ardupilot_params()
        self.rates_hz = dict(DEFAULT_RATES_HZ)
        if self.sim.world is not None:  # a world streams as its logs are written
            self.rates_hz["ESC_TELEMETRY"] = self.sim.world.esc_stream_hz
            self.rates_hz["SERVO_OUTPUT_RAW"] = self.sim.world.log_hz
        self._next_send: dict[str, float] = dict.fromkeys(self.rates_hz, 0.0)
        self.received: list[ReceivedMessage] = []
        self.sent_counts: dict[str, int] = {}
        self._lock = threading.Lock()
        self._pending: list[Callable[[], None]] = []
        self._stop = threading.Event()
        self._ready = threading.Event()
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self._conn: Any = None
        self._latest_esc: list[tuple[int, int, int, int, int, int] | None] = [None] * self.sim.n

    # -- lifecycle --------------------------------------------------------------------------------
    def start(self, timeout_s: float = 5.0) -> SimVehicle:
        if self._thread is not None:
            raise RuntimeError("already started")
        self._thread = threading.Thread(target=self._run, name=f"SimVehicle {self.url}", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout_s):
            self.stop()
            raise LinkError(f"{self.url}: the simulated vehicle did not start within {timeout_s} s")
        if self._error is not None:
            error = self._error
            self.stop()
            raise LinkError(f"{self.url}: cannot open the link: {error}") from error
        return self

    def stop(self, timeout_s: float = 5.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def __enter__(self) -> SimVehicle:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    async def __aenter__(self) -> SimVehicle:
        return await asyncio.to_thread(self.start)

    async def __aexit__(self, *exc: object) -> None:
        await asyncio.to_thread(self.stop)

    # -- control from Python (thread-safe) --------------------------------------------------------
    @property
    def sim_time_s(self) -> float:
        return self.sim.time_s

    def inject(
        self, kind: str, motor: int, severity: float | None = None, stall_current_a: float | None = None
    ) -> None:
        """Start a fault now (applied by the simulation thread at its next step)."""
        spec = FaultSpec(kind, motor, 0.0, severity, stall_current_a)  # validates
        self._call(lambda: self._inject_now(spec))

    def clear_faults(self) -> None:
        self._call(self.sim.clear_faults)

    def _call(self, fn: Callable[[], None]) -> None:
        with self._lock:
            self._pending.append(fn)

    def _inject_now(self, spec: FaultSpec) -> None:
        fault = dataclasses.replace(spec, onset_s=self.sim.time_s)
        self.sim.inject(fault)
        log.info("fault %s injected on motor %d at %.2f s", fault.kind, fault.motor, fault.onset_s)
        self._statustext(f"SIM: {fault.kind} on motor {fault.motor}")

    # -- the thread -------------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            self._conn = mavlink2_connection(
                self.url, source_system=self.system_id, source_component=self.component_id
            )
        except Exception as exc:  # pymavlink raises OSError and others for bad URLs
            self._error = exc
            self._ready.set()
            return
        self._ready.set()
        try:
            self._loop()
        except Exception:  # pragma: no cover - logged, the thread ends
            log.exception("simulated vehicle stopped")
        finally:
            with contextlib.suppress(Exception):
                self._conn.close()

    def _loop(self) -> None:
        start = time.monotonic()
        sim_start = self.sim.time_s
        dt = self.sim.dt
        while not self._stop.is_set():
            with self._lock:
                pending, self._pending = self._pending, []
            for fn in pending:
                fn()
            target = sim_start + (time.monotonic() - start) * self.speed
            steps = 0
            while self.sim.time_s + dt <= target and steps < 2000:
                for s in self.sim.step():
                    j = s.motor - 1
                    self._latest_esc[j] = (s.temp_c, s.voltage_cv, s.esc_current_ca, 0, s.rpm, s.reports)
                self._send_due()
                steps += 1
            if steps >= 2000:  # cannot keep up: let simulated time slip rather than spin
                start = time.monotonic()
                sim_start = self.sim.time_s
            self._receive()
            if steps == 0:
                time.sleep(min(dt / self.speed, 0.005))

    def _send(self, msg: Any) -> None:
        try:
            self._conn.mav.send(msg)
        except OSError as exc:  # nobody listening yet (udpout/tcp): drop, as a radio would
            log.debug("send failed: %s", exc)
            return
        name = msg.get_type()
        self.sent_counts[name] = self.sent_counts.get(name, 0) + 1

    def _send_due(self) -> None:
        t = self.sim.time_s
        for name, rate in self.rates_hz.items():
            if rate <= 0 or t < self._next_send[name]:
                continue
            self._next_send[name] = max(self._next_send[name] + 1.0 / rate, t)
            self._send_stream(name)

    def _send_stream(self, name: str) -> None:
        mav = self._conn.mav
        snap = self.sim.snapshot()
        t = snap.time_s
        if name == "HEARTBEAT":
            self._send(heartbeat(mav))
        elif name == "SYS_STATUS":
            self._send(
                mav.sys_status_encode(
                    0,
                    0,
                    0,
                    500,
                    round(snap.bus_voltage_v * 1000),
                    round(snap.battery_current_a * 100),
                    snap.remaining_pct,
                    0,
                    0,
                    0,
                    0,
                    0,
                    0,
                )
            )
        elif name == "BATTERY_STATUS":
            cells = [65535] * 10
            cells[0] = round(snap.bus_voltage_v * 1000)
            self._send(
                mav.battery_status_encode(
                    0,
                    mavlink.MAV_BATTERY_FUNCTION_ALL,
                    mavlink.MAV_BATTERY_TYPE_LIPO,
                    32767,
                    cells,
                    round(snap.battery_current_a * 100),
                    round(snap.consumed_mah),
                    -1,
                    snap.remaining_pct,
                )
            )
        elif name == "SERVO_OUTPUT_RAW":
            pwm = list(snap.pwm_us) + [0] * (16 - len(snap.pwm_us))
            self._send(mav.servo_output_raw_encode(int(t * 1e6) & 0xFFFFFFFF, 0, *pwm[:8], *pwm[8:16]))
        elif name == "ATTITUDE":
            self._send(
                mav.attitude_encode(int(t * 1000), snap.roll_rad, snap.pitch_rad, snap.yaw_rad, 0.0, 0.0, 0.0)
            )
        elif name == "VFR_HUD":
            speed = math.hypot(snap.vel_ned_m_s[0], snap.vel_ned_m_s[1])
            heading = int(math.degrees(snap.yaw_rad)) % 360
            self._send(
                mav.vfr_hud_encode(speed, speed, heading, snap.throttle_pct, snap.alt_m, snap.climb_m_s)
            )
        elif name == "GLOBAL_POSITION_INT":
            heading = int(math.degrees(snap.yaw_rad)) % 360
            self._send(
                mav.global_position_int_encode(
                    int(t * 1000),
                    round(snap.lat_deg * 1e7),
                    round(snap.lon_deg * 1e7),
                    round(snap.alt_m * 1000),
                    round(snap.alt_m * 1000),
                    *(round(x * 100) for x in snap.vel_ned_m_s),
                    heading * 100,
                )
            )
        elif name == "ESC_TELEMETRY":
            for msg in esc_telemetry_messages(mav, list(self._latest_esc)):
                self._send(msg)

    def _statustext(self, text: str, severity: int = mavlink.MAV_SEVERITY_INFO) -> None:
        self._send(self._conn.mav.statustext_encode(severity, text.encode()[:50]))

    # -- incoming ---------------------------------------------------------------------------------
    def _receive(self) -> None:
        for _ in range(100):
            try:
                msg = self._conn.recv_match(blocking=False)
            except (OSError, ConnectionError) as exc:  # pragma: no cover - peer went away
                log.debug("receive failed: %s", exc)
                return
            if msg is None:
                return
            self._handle(msg)

    def _handle(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            return
        if kind in ("STATUSTEXT", "NAMED_VALUE_FLOAT", "NAMED_VALUE_INT"):
            fields = msg.to_dict()
            fields.pop("mavpackettype", None)
            item = ReceivedMessage(
                self.sim.time_s, time.time(), kind, fields, msg.get_srcSystem(), msg.get_srcComponent()
            )
            self.received.append(item)
            log.info("received %s %s", kind, fields)
            if self.on_message is not None:
                self.on_message(item)
            return
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self.system_id):
            return
        if kind == "PARAM_REQUEST_LIST":
            names = sorted(self.params)
            for k, name in enumerate(names):
                self._send_param(name, k, len(names))
        elif kind == "PARAM_REQUEST_READ":
            names = sorted(self.params)
            name = (
                msg.param_id
                if msg.param_index < 0
                else (names[msg.param_index] if msg.param_index < len(names) else "")
            )
            if name in self.params:
                self._send_param(name, names.index(name), len(names))
        elif kind == "PARAM_SET":
            self._param_set(msg.param_id, float(msg.param_value))
        elif kind == "COMMAND_LONG":
            self._command(msg)
        elif kind == "REQUEST_DATA_STREAM":
            groups = (
                STREAM_GROUPS.values()
                if msg.req_stream_id == mavlink.MAV_DATA_STREAM_ALL
                else [STREAM_GROUPS.get(msg.req_stream_id, ())]
            )
            for group in groups:
                for name in group:
                    self.rates_hz[name] = float(msg.req_message_rate) if msg.start_stop else 0.0
                    self._next_send[name] = self.sim.time_s

    def _send_param(self, name: str, index: int, count: int) -> None:
        self._send(
            self._conn.mav.param_value_encode(
                name.encode(), float(self.params[name]), mavlink.MAV_PARAM_TYPE_REAL32, count, index
            )
        )

    def _param_set(self, name: str, value: float) -> None:
        if name not in self.params:
            return
        self.params[name] = value
        names = sorted(self.params)
        self._send_param(name, names.index(name), len(names))
        if name == "SIM_MOT_FAULT":
            self._apply_fault_params()

    def _apply_fault_params(self) -> None:
        code = int(self.params["SIM_MOT_FAULT"])
        if code == 0:
            self.sim.clear_faults()
            self._statustext("SIM: faults cleared")
            return
        kind = FAULT_CODES.get(code)
        motor = int(self.params["SIM_MOT_FLT_NUM"]) or 1
        severity = float(self.params["SIM_MOT_FLT_SEV"]) or None
        if kind is None or not 1 <= motor <= self.sim.n or (severity is not None and not 0 < severity <= 1):
            self._statustext(f"SIM: bad fault {code} motor {motor}", mavlink.MAV_SEVERITY_WARNING)
            return
        self._inject_now(FaultSpec(kind, motor, self.sim.time_s, severity))

    def _command(self, msg: Any) -> None:
        result = mavlink.MAV_RESULT_ACCEPTED
        if msg.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            msg_id, interval_us = int(msg.param1), float(msg.param2)
            names = [
                n
                for n, i in _MSG_IDS.items()
                if i == msg_id or (msg_id == _ESC_5_TO_8 and n == "ESC_TELEMETRY")
            ]
            if not names:
                result = mavlink.MAV_RESULT_DENIED
            for name in names:
                if interval_us < 0:
                    self.rates_hz[name] = 0.0
                elif interval_us == 0:
                    self.rates_hz[name] = DEFAULT_RATES_HZ[name]
                else:
                    self.rates_hz[name] = 1e6 / interval_us
                self._next_send[name] = self.sim.time_s
        elif msg.command == MAV_CMD_USER_1:
            self.params["SIM_MOT_FLT_NUM"] = float(msg.param2)
            self.params["SIM_MOT_FLT_SEV"] = float(msg.param3)
            self.params["SIM_MOT_FAULT"] = float(msg.param1)
            self._apply_fault_params()
        elif msg.command == mavlink.MAV_CMD_REQUEST_MESSAGE:
            names = [n for n, i in _MSG_IDS.items() if i == int(msg.param1)]
            for name in names:
                self._send_stream(name)
            if not names:
                result = mavlink.MAV_RESULT_UNSUPPORTED
        else:
            result = mavlink.MAV_RESULT_UNSUPPORTED
        self._send(self._conn.mav.command_ack_encode(msg.command, result))
