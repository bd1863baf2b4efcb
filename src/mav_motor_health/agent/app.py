"""The agent: MAVLink in, the diagnosis core, health out over MAVLink and MQTT. One asyncio process.

:class:`Agent` is an async context manager that owns its parts and tasks::

    MavlinkLink (reader/writer threads) ──► receive task: tracker, SampleAssembler, HealthMonitor
                                                  │ state changes
    heartbeat task (1 Hz HEARTBEAT)               ├─► STATUSTEXT (rate-limited), MQTT state + event
    supervise task (streams, params, link loss)   └─► view
    periodic task (silence, NAMED_VALUE_*, MOTOR_HEALTH, MQTT telemetry, view redraw)
    MqttPublisher (its own connection task)

All tasks live in one ``TaskGroup`` and are cancelled on exit; the link's threads and the MQTT
connection close after them. :func:`run_agent` runs it until SIGTERM/SIGINT or the end of a ``.tlog``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import signal
import sys
import time
from collections import deque
from collections.abc import Callable
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from .. import __version__
from .._aio import TaskGroup
from ..diagnosis.states import MotorState
from ..diagnosis.vehicle_check import VehicleFit
from ..publish import dialect as health_dialect
from ..publish.mavlink_health import (
    MAV_SEVERITY_WARNING,
    StatustextGate,
    motor_health_message,
    named_value_messages,
    severity_for,
    statustext_for,
    statustext_message,
)
from ..publish.mqtt import MqttPublisher, utc_now
from .config import AgentConfig
from .link import MavlinkLink, Received, mavlink2
from .monitor import HealthMonitor, StateChange
from .samples import SampleAssembler
from .vehicle import AutopilotTracker, stream_requests, wanted_params

__all__ = ["Agent", "run_agent"]

log = logging.getLogger("mav_motor_health.agent")

MAV_CMD_SET_MESSAGE_INTERVAL = 511
_TICK_S = 0.05
#: Messages that wait, without ESC telemetry due, before they are read anyway (what they set is kept).
_READ_AT_LATEST = 1000


class Agent:
    """One vehicle's motor-health agent. ``async with Agent(config) as agent: await agent.wait()``.

    ``on_row`` (optional) sees every diagnosed sample row; ``changes`` keeps the last state changes.
    """

    def __init__(
        self,
        config: AgentConfig,
        *,
        view: Any = None,
        on_row: Callable[[dict[str, Any]], None] | None = None,
    ) -> None:
        self.config = config
        self.view = view
        self.on_row = on_row
        self.link = MavlinkLink(
            config.connect, source_system=config.system_id or 1, source_component=config.component_id
        )
        self.tlog = self.link.url.kind == "tlog"
        self.assembler = SampleAssembler(config.motors)
        self.monitor = HealthMonitor(
            config.params,
            config.profile,
            config.motors,
            config.stale_s,
            esc=config.esc,
            current=config.current,
            noise=config.noise,
        )
        self.tracker = AutopilotTracker(config.heartbeat_timeout_s)
        p = config.publish
        self.gate = StatustextGate(burst=p.statustext_burst, interval_s=p.statustext_interval_s)
        self.mqtt = MqttPublisher(config.mqtt, f"mav-motor-health {__version__}") if config.mqtt else None
        self.changes: deque[StateChange] = deque(maxlen=10_000)
        self.statustexts: deque[tuple[int, str]] = deque(maxlen=1000)  # (severity, text) sent
        self.finished = asyncio.Event()
        self._dialect: Any = None
        self._group: TaskGroup | None = None
        self._tasks: list[asyncio.Task[None]] = []
        self._start_mono = time.monotonic()
        self._last_time_s = -math.inf  # newest message time on the link's clock
        self._last_esc_s = -math.inf
        self._params_pending: dict[str, int] = {}
        self._request_streams_at = math.inf
        self._telemetry_sent: dict[int, float] = {}
        self._esc_lost_told = False
        # ESC telemetry on its way to the core: messages not read yet (the time of the first, of the last)
        # and samples read, waiting for their batch to complete (the time of the first)
        self._waiting_since: float | None = None
        self._waiting_last = -math.inf
        self._pending: list[dict[str, NDArray[Any]]] = []
        self._pending_since: float | None = None
        self._vehicle_fit_told = self.monitor.vehicle_fit
        self._mqtt_refused_told = False
        self._failed: asyncio.Future[None] | None = None  # a live link's handling failed (_received)

    # -- lifetime ------------------------------------------------------------------------------------
    async def __aenter__(self) -> Agent:
        loop = asyncio.get_running_loop()
        self._dialect = await loop.run_in_executor(None, health_dialect.load)
        if not self.tlog:  # live messages handled as they are read (a .tlog: through the receive task)
            self._failed = loop.create_future()
            self.link.on_messages = self._received
        await self.link.__aenter__()
        try:
            if self.mqtt is not None:
                await self.mqtt.__aenter__()
                self.mqtt.info(self._info())
            self._group = TaskGroup()
            await self._group.__aenter__()
            for name, coro in (
                ("receive", self._receive()),
                ("heartbeat", self._heartbeat()),
                ("supervise", self._supervise()),
                ("periodic", self._periodic()),
            ):
                self._tasks.append(self._group.create_task(coro, name=f"agent-{name}"))
        except BaseException:
            await self.link.aclose()
            raise
        log.info(
            "agent for vehicle %s on %s (%d motors, model %s, profile %s)%s",
            self.config.vehicle_id,
            self.link.url,
            self.config.motors,
            self.config.params_name,
            self.config.profile.name,
            f", MQTT {self.config.mqtt.host}:{self.config.mqtt.port}" if self.config.mqtt else "",
        )
        return self

    async def __aexit__(self, *exc_info: Any) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        """Stop the tasks, tell MQTT we are offline, close the link. Safe to call twice."""
        if self._group is not None:
            for task in self._tasks:
                task.cancel()
            group, self._group = self._group, None
            with contextlib.suppress(asyncio.CancelledError):
                await group.__aexit__(None, None, None)
            if self.mqtt is not None:
                await self.mqtt.aclose()
            await self.link.aclose()
            log.info("agent stopped")

    async def wait(self) -> None:
        """Until the link ends (a .tlog read to its end); live links run until cancelled."""
        await self.finished.wait()

    # -- time ----------------------------------------------------------------------------------------
    def now(self) -> float:
        """The link's clock: monotonic for live links, the log's time for a .tlog."""
        return self._last_time_s if self.tlog else self.link.clock()

    def _boot_ms(self) -> int:
        return int((time.monotonic() - self._start_mono) * 1000)

    # -- receiving -----------------------------------------------------------------------------------
    async def _receive(self) -> None:
        if self._failed is not None:  # a live link hands its messages to _received: fail as this task would
            await self._failed
        while True:
            batch = await self.link.recv()
            if batch is None:
                self.flush()
                for change in self.monitor.check_silence(self._last_time_s + 2 * self.monitor.stale_s):
                    self._changed(change)
                self.finished.set()
                return
            self._take(batch)

    def _received(self, batch: list[Received]) -> None:
        """A live link's messages, as they are read: handled at once, an error ending the receive task."""
        assert self._failed is not None
        if self._failed.done():
            return
        try:
            self._take(batch)
        except Exception as exc:  # raised again by the receive task, as if it had met it
            self._failed.set_exception(exc)

    def _take(self, batch: list[Received]) -> None:
        for item in batch:
            self.handle(item)
        if self._due(self._waiting_last) or self.assembler.waiting >= _READ_AT_LATEST:
            self.read()

    def handle(self, item: Received) -> None:
        """Everything one message does on arrival; its samples come with :meth:`read`."""
        msg, t = item.msg, item.time_s
        self._last_time_s = max(self._last_time_s, t)
        event = self.tracker.on_message(msg, t)
        if event is not None:
            self._on_vehicle_event(event, t)
        if msg.get_type() == "PARAM_VALUE" and (
            self.tracker.system is None or msg.get_srcSystem() == self.tracker.system
        ):
            self._params_pending.pop(str(msg.param_id).rstrip("\x00"), None)
        if self.assembler.add(msg, t):  # ESC telemetry: samples to come
            if self._waiting_since is None:
                self._waiting_since = t
            self._waiting_last = t

    def _due(self, now: float) -> bool:
        """Whether the first ESC telemetry not yet diagnosed has waited ``batch_s``."""
        since = self._pending_since if self._pending_since is not None else self._waiting_since
        return since is not None and now - since >= self.config.batch_s

    def read(self) -> None:
        """Read the messages waiting into samples — one call of the reading replay uses
        (telemetry/mavlink_messages.py) for all of them — and diagnose those whose batch is complete:
        each ESC message's samples wait at most ``batch_s`` to go through the core with those after it."""
        samples = self.assembler.take()
        self._waiting_since = None
        n = len(samples["time_s"])
        if not n:
            return
        self._last_esc_s = float(samples["time_s"][-1])
        firsts = np.flatnonzero(np.diff(samples["position"], prepend=-1))  # each ESC message's first sample
        ends = [*firsts[1:].tolist(), n]
        start, since = 0, self._pending_since
        for t, end in zip(samples["time_s"][firsts].tolist(), ends):
            if since is None:
                since = t
            if t - since >= self.config.batch_s:  # this message's samples complete a batch
                self._pending.append({name: values[start:end] for name, values in samples.items()})
                self._diagnose_pending()
                start, since = end, None
        if start < n:
            self._pending.append({name: values[start:] for name, values in samples.items()})
        self._pending_since = since

    def flush(self) -> None:
        """Read what waits and diagnose every sample (the core runs per motor on a few at a time)."""
        self.read()
        self._diagnose_pending()

    def _diagnose_pending(self) -> None:
        self._pending_since = None
        if not self._pending:
            return
        pending, self._pending = self._pending, []
        samples = (
            pending[0]
            if len(pending) == 1
            else {name: np.concatenate([part[name] for part in pending]) for name in pending[0]}
        )
        rows, changes = self.monitor.feed_columns(samples, rows=self.on_row is not None)
        if self.on_row is not None:
            for row in rows:
                self.on_row(row)
        for change in changes:
            self._changed(change)
        if self.monitor.vehicle_fit != self._vehicle_fit_told:
            self._vehicle_fit_told = self.monitor.vehicle_fit
            self._vehicle_fit_changed()

    def _vehicle_fit_description(self) -> str:
        check = self.monitor.diagnoser.vehicle
        return check.describe(self.monitor.vehicle_fit, f"the motor model {self.config.params_name!r}")

    def _vehicle_fit_changed(self) -> None:
        """Say once, in one line, whether the motor model describes this vehicle (vehicle_check.py)."""
        if self.monitor.vehicle_fit == VehicleFit.SPEED_OFF:
            log.warning("%s", self._vehicle_fit_description())
            if self.config.publish.statustext and not self.tlog:
                self._send_text("Motor model does not fit this vehicle: fit one", MAV_SEVERITY_WARNING)
        else:
            log.info("%s", self._vehicle_fit_description())
        if self.mqtt is not None:
            self.mqtt.info(self._info())

    def _on_vehicle_event(self, event: str, t: float) -> None:
        tr = self.tracker
        if event == "found":
            log.info("autopilot found: system %d component %d (%s)", tr.system, tr.component, tr.autopilot)
            if not self.config.system_id and tr.system is not None:
                self.link.set_source(tr.system)  # a companion computer shares its autopilot's system id
            if self.mqtt is not None:
                self.mqtt.info(self._info())
        else:
            log.warning("autopilot %s: asking for streams and parameters again", event)
        self._request_streams_at = -math.inf
        self._params_pending = {name: 0 for name in wanted_params(tr.autopilot, self.config.motors)}

    # -- state changes -------------------------------------------------------------------------------
    def _changed(self, change: StateChange) -> None:
        self.changes.append(change)
        level = logging.WARNING if change.state != MotorState.NORMAL else logging.INFO
        if self.view is not None and not self.view.live:
            level = logging.DEBUG  # the view writes one line per change with its evidence: not twice
        log.log(
            level,
            "motor %d: %s -> %s (%s)",
            change.motor,
            change.previous.label,
            change.state.label,
            change.state.description,
        )
        if self.view is not None:
            self.view.change(change)
        if self.mqtt is not None:
            self.mqtt.state(change.motor, self._state_payload(change.motor))
            self.mqtt.event(
                {
                    "time_utc": utc_now(),
                    "t_s": change.time_s,
                    "motor": change.motor,
                    "state": change.state.label,
                    "previous": change.previous.label,
                    "evidence": change.evidence,
                }
            )
        if self.config.publish.statustext and not self.tlog:
            self._statustext_change(change)

    def _statustext_change(self, change: StateChange) -> None:
        now = self.now()
        statuses = self.monitor.status
        if change.state == MotorState.NO_DATA and change.previous != MotorState.NO_DATA:
            had_data = [s for s in statuses.values() if math.isfinite(s.last_sample_s)]
            if had_data and all(s.state == MotorState.NO_DATA for s in had_data):
                # everything went silent: one line for the ESC telemetry, not one per motor
                if not self._esc_lost_told:
                    self._esc_lost_told = True
                    self._send_text("ESC telemetry lost", MAV_SEVERITY_WARNING)
                for s in had_data:
                    self.gate.mark_sent(s.motor, MotorState.NO_DATA)
                return
        if change.state == MotorState.UNCALIBRATED:
            self.gate.mark_sent(change.motor, change.state)  # one line for the vehicle says it
            return
        if change.state != MotorState.NO_DATA:
            self._esc_lost_told = False
        first_data = change.previous == MotorState.NO_DATA and change.motor not in self.gate.last_sent
        if first_data and change.state == MotorState.NORMAL:
            self.gate.mark_sent(change.motor, change.state)  # first data: nothing to announce
            return
        if self.gate.offer(change.motor, change.state, now):
            self._send_text(statustext_for(change.motor, change.state), severity_for(change.state))

    def _send_text(self, text: str, severity: int) -> None:
        self.statustexts.append((severity, text))
        self.link.send(statustext_message(self.link.mav, text, severity))

    def _state_payload(self, motor: int) -> dict[str, Any]:
        s = self.monitor.status[motor]
        since = time.time() - (self.now() - s.since_s) if math.isfinite(s.since_s) else time.time()
        return {
            "motor": motor,
            "state": s.state.label,
            "code": int(s.state),
            "description": s.state.description,
            "since_utc": _iso(since),
            "time_utc": utc_now(),
            "fresh": s.fresh,
        }

    def _info(self) -> dict[str, Any]:
        return {
            "vehicle_id": self.config.vehicle_id,
            "frame": self.config.frame,
            "motors": self.config.motors,
            "autopilot": self.tracker.autopilot if self.tracker.autopilot in ("ardupilot", "px4") else None,
            "profile": self.config.profile.name,
            "params": self.config.params_name,
            "model_check": {
                "verdict": {VehicleFit.FITS: "fits", VehicleFit.CHECKING: "checking"}.get(
                    self.monitor.vehicle_fit, "does_not_fit"
                ),
                "message": self._vehicle_fit_description(),
            },
        }

    # -- periodic work -------------------------------------------------------------------------------
    async def _heartbeat(self) -> None:
        if self.tlog:
            return
        while True:
            self.link.send(
                self.link.mav.heartbeat_encode(
                    mavlink2.MAV_TYPE_ONBOARD_CONTROLLER,
                    mavlink2.MAV_AUTOPILOT_INVALID,
                    0,
                    0,
                    mavlink2.MAV_STATE_ACTIVE,
                )
            )
            await asyncio.sleep(1.0)

    async def _supervise(self) -> None:
        """Streams and parameters: ask when the autopilot appears, returns or reboots, and while ESC data is missing."""
        if self.tlog:
            return
        param_retry_at = -math.inf
        while True:
            now = self.now()
            if self.tracker.check(now) == "lost":
                log.warning("autopilot lost: no HEARTBEAT for %.1f s", self.config.heartbeat_timeout_s)
            tr = self.tracker
            if tr.up and tr.system is not None:
                esc_missing = now - self._last_esc_s > 3.0
                if now >= self._request_streams_at:
                    self._request_streams()
                    self._request_streams_at = now + 3.0
                if self._params_pending and now >= param_retry_at:
                    for name, tries in list(self._params_pending.items()):
                        if tries >= 5:
                            del self._params_pending[name]  # not on this autopilot: keep the default
                            continue
                        self._params_pending[name] = tries + 1
                        self.link.send(
                            self.link.mav.param_request_read_encode(
                                tr.system, tr.component or 1, name.encode(), -1
                            )
                        )
                    param_retry_at = now + 2.0
                if not esc_missing:
                    self._request_streams_at = max(self._request_streams_at, now + 3.0)
            await asyncio.sleep(0.2)

    def _request_streams(self) -> None:
        tr = self.tracker
        assert tr.system is not None
        for msg_id, rate_hz in stream_requests(tr.autopilot, self.config.esc_rate_hz):
            self.link.send(
                self.link.mav.command_long_encode(
                    tr.system,
                    tr.component or 1,
                    MAV_CMD_SET_MESSAGE_INTERVAL,
                    0,
                    float(msg_id),
                    1e6 / rate_hz,
                    0,
                    0,
                    0,
                    0,
                    0,
                )
            )
        log.debug("asked %s for its streams", tr.autopilot)

    async def _periodic(self) -> None:
        p = self.config.publish
        next_named = next_health = next_view = 0.0
        telemetry_period = 1.0 / p.telemetry_hz if p.telemetry_hz > 0 else math.inf
        while True:
            await asyncio.sleep(_TICK_S)
            mono = time.monotonic()
            if self._due(self.now()):
                self.flush()
            if not self.tlog:
                for change in self.monitor.check_silence(self.now()):
                    self._changed(change)
                for motor, state in self.gate.due(self.now()):
                    self._send_text(statustext_for(motor, state), severity_for(state))
                if p.named_value_hz > 0 and mono >= next_named:
                    next_named = mono + 1.0 / p.named_value_hz
                    self._send_named_values()
                if p.motor_health_hz > 0 and mono >= next_health:
                    next_health = mono + 1.0 / p.motor_health_hz
                    self._send_motor_health()
            if self.mqtt is not None:
                self._publish_telemetry(telemetry_period)
                if self.mqtt.login_refused and not self._mqtt_refused_told:
                    self._mqtt_refused_told = True  # said once; the diagnosis goes on over MAVLink
                    if self.config.publish.statustext and not self.tlog:
                        self._send_text("MQTT login refused: no MQTT", MAV_SEVERITY_WARNING)
            if self.view is not None and mono >= next_view:
                next_view = mono + 0.2
                header = f"{self.tracker.autopilot or 'no autopilot yet'}{'' if self.tracker.up else ' (link down)'}"
                if self.mqtt is not None and self.mqtt.login_refused:
                    header += "  MQTT: login refused"
                self.view.redraw(self.monitor.status, self.now(), header)

    def _send_named_values(self) -> None:
        ms = self._boot_ms()
        for motor, s in self.monitor.status.items():
            for msg in named_value_messages(self.link.mav, ms, motor, s.state, s.row):
                self.link.send(msg)

    def _send_motor_health(self) -> None:
        ms = self._boot_ms()
        now = self.now()
        for motor, s in self.monitor.status.items():
            since = now - s.since_s if math.isfinite(s.since_s) else 0.0
            self.link.send(motor_health_message(self._dialect, ms, motor, s.state, since, s.fresh, s.row))

    def _publish_telemetry(self, period_s: float) -> None:
        assert self.mqtt is not None
        for motor, s in self.monitor.status.items():
            row = s.row
            if not row or not s.fresh:
                continue
            t = float(row["time_s"])
            if t - self._telemetry_sent.get(motor, -math.inf) < period_s:
                continue
            self._telemetry_sent[motor] = t
            self.mqtt.telemetry(
                motor,
                {
                    "time_utc": utc_now(),
                    "t_s": t,
                    "omega_rad_s": row.get("omega_rad_s"),
                    "omega_model_rad_s": row.get("omega_model_rad_s"),
                    "current_a": row.get("current_a"),
                    "current_model_a": row.get("current_model_a"),
                    "voltage_v": row.get("voltage_v"),
                    "raw_state": MotorState(int(row["state"])).label,
                    "steady": bool(row.get("steady")),
                },
            )


def _iso(epoch_s: float) -> str:
    from datetime import datetime, timezone

    return (
        datetime.fromtimestamp(epoch_s, timezone.utc)
        .isoformat(timespec="milliseconds")
        .replace("+00:00", "Z")
    )


async def run_agent(
    config: AgentConfig,
    *,
    tui: bool | None = None,
    stream: TextIO | None = None,
    duration_s: float | None = None,
    until: Callable[[], bool] | None = None,
    report: Callable[[Agent], str] | None = None,
) -> int:
    """Run until SIGTERM/SIGINT, a .tlog's end, ``duration_s`` seconds or ``until()`` turns true; then
    ``report(agent)`` (if given) is written to the output. Returns the exit code."""
    from .view import StateView

    out = stream or sys.stdout
    live = out.isatty() if tui is None else tui
    view = StateView(out, live, title=f"mav-motor-health: {config.vehicle_id}")
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    async with Agent(config, view=view) as agent:
        stopper = asyncio.ensure_future(stop.wait())
        finished = asyncio.ensure_future(agent.wait())
        waits = {stopper, finished}
        if until is not None:

            async def poll() -> None:
                while not until():
                    await asyncio.sleep(0.1)

            waits.add(asyncio.ensure_future(poll()))
        await asyncio.wait(waits, timeout=duration_s, return_when=asyncio.FIRST_COMPLETED)
        for fut in waits:
            fut.cancel()
        if stop.is_set():
            log.info("signal received: shutting down")
        if report is not None:
            agent.flush()
            out.write(report(agent))
            out.flush()
        refused = agent.mqtt.login_refused if agent.mqtt is not None else None
    for sig in (signal.SIGTERM, signal.SIGINT):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.remove_signal_handler(sig)
    if refused:  # the diagnosis ran, but what was asked of MQTT was not done
        log.error("%s", refused)
        return 3
    return 0
