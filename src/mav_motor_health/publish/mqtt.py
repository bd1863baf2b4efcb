"""MQTT publishing through aiomqtt: the topic tree in ``docs/agent.md``, surviving broker outages.

Topics under ``<prefix>/<vehicle>/``: ``status`` and ``info`` (retained), ``motor/<n>/state`` (retained),
``motor/<n>/telemetry`` (QoS 0, not retained) and ``events`` (QoS 1). The last will publishes
``{"online": false}`` retained on ``status``.

:class:`MqttPublisher` is an async context manager that owns one connection task in a ``TaskGroup``
(cancelled on exit). Callers never wait for the broker: ``state``, ``event`` and ``telemetry`` put a
message in the :class:`Outbox` and return. The connection task (re)connects with back-off and drains
the outbox in order of importance: retained topics (latest payload per topic), events (in order, never
dropped while there is room), then telemetry (a short queue whose oldest entries are dropped first, and
which gives up its room to events when the outbox is full). After every (re)connect all retained topics are
published again, so a broker that restarted without persistence is whole again. A message leaves the
outbox only once the broker acknowledged it (QoS 1): delivery is at-least-once.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import math
import ssl
from collections import deque
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any
from urllib.parse import unquote, urlsplit

import aiomqtt

from .._aio import TaskGroup
from ..errors import ConfigError

__all__ = ["MqttPublisher", "MqttSettings", "Outbox", "parse_mqtt_url", "utc_now"]

log = logging.getLogger(__name__)


def utc_now() -> str:
    """ISO 8601 UTC time with ``Z``, millisecond resolution."""
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _clean(value: Any) -> Any:
    """JSON-safe: non-finite floats become null (MQTT.md), numpy scalars become Python numbers."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps(payload: dict[str, Any]) -> bytes:
    return json.dumps(_clean(payload), separators=(",", ":"), allow_nan=False).encode()


@dataclass(frozen=True)
class MqttSettings:
    """Where and how to publish. ``tls`` is on for ``mqtts://`` URLs or when a CA file is given."""

    host: str
    port: int = 1883
    username: str | None = None
    password: str | None = None
    tls: bool = False
    ca_file: str | None = None
    cert_file: str | None = None
    key_file: str | None = None
    tls_insecure: bool = False
    prefix: str = "mmh"
    vehicle_id: str = "vehicle1"
    client_id: str | None = None
    keepalive_s: int = 10
    reconnect_min_s: float = 0.5
    reconnect_max_s: float = 10.0
    queue_limit: int = 100_000
    telemetry_limit: int = 300

    def topic(self, *parts: object) -> str:
        return "/".join([self.prefix, self.vehicle_id, *(str(p) for p in parts)])


def parse_mqtt_url(url: str, **overrides: Any) -> MqttSettings:
    """``mqtt://[user[:password]@]host[:port]`` or ``mqtts://...`` (TLS, default port 8883)."""
    parts = urlsplit(url if "://" in url else f"mqtt://{url}")
    if parts.scheme not in ("mqtt", "mqtts", "tcp", "ssl") or not parts.hostname:
        raise ConfigError(
            f"bad MQTT URL {url!r}",
            key="mqtt.url",
            expected="mqtt://[user:password@]host[:port] or mqtts://...",
        )
    tls = parts.scheme in ("mqtts", "ssl")
    try:
        port = parts.port or (8883 if tls else 1883)
    except ValueError:
        raise ConfigError(
            f"bad port in MQTT URL {url!r}", key="mqtt.url", expected="a port 1-65535"
        ) from None
    values: dict[str, Any] = {
        "host": parts.hostname,
        "port": port,
        "tls": tls,
        "username": unquote(parts.username) if parts.username else None,
        "password": unquote(parts.password) if parts.password else None,
    }
    values.update({k: v for k, v in overrides.items() if v is not None})
    return MqttSettings(**values)


@dataclass(frozen=True)
class _Message:
    topic: str
    payload: bytes
    qos: int
    retain: bool


class Outbox:
    """What waits for the broker: retained topics (latest wins), events (FIFO), telemetry (FIFO, lossy).

    ``limit`` bounds events + telemetry; telemetry alone is held to ``telemetry_limit``. When full, the
    oldest telemetry goes first; events are dropped only when nothing else is left to drop (and logged).
    """

    def __init__(self, limit: int = 100_000, telemetry_limit: int = 300) -> None:
        self.limit = limit
        self.telemetry_limit = telemetry_limit
        self.retained: dict[str, _Message] = {}  # every retained topic's current payload
        self.dirty: dict[str, None] = {}  # retained topics not yet delivered (ordered set)
        self.events: deque[_Message] = deque()
        self.telemetry: deque[_Message] = deque()
        self.dropped_telemetry = 0
        self.dropped_events = 0
        self.wake = asyncio.Event()

    def __len__(self) -> int:
        return len(self.dirty) + len(self.events) + len(self.telemetry)

    def put_retained(self, topic: str, payload: bytes) -> None:
        self.retained[topic] = _Message(topic, payload, 1, True)
        self.dirty.pop(topic, None)
        self.dirty[topic] = None
        self.wake.set()

    def put_event(self, topic: str, payload: bytes) -> None:
        self._make_room()
        if len(self.events) + len(self.telemetry) >= self.limit:
            self.events.popleft()
            self.dropped_events += 1
            log.error("MQTT outbox full (%d): dropped the oldest event", self.limit)
        self.events.append(_Message(topic, payload, 1, False))
        self.wake.set()

    def put_telemetry(self, topic: str, payload: bytes) -> None:
        if len(self.telemetry) >= self.telemetry_limit:
            self.telemetry.popleft()
            self.dropped_telemetry += 1
        self._make_room()
        if len(self.events) + len(self.telemetry) < self.limit:
            self.telemetry.append(_Message(topic, payload, 0, False))
            self.wake.set()
        else:
            self.dropped_telemetry += 1

    def _make_room(self) -> None:
        while self.telemetry and len(self.events) + len(self.telemetry) >= self.limit:
            self.telemetry.popleft()
            self.dropped_telemetry += 1

    def mark_all_retained_dirty(self) -> None:
        for topic in self.retained:
            self.dirty.setdefault(topic, None)

    def peek(self) -> _Message | None:
        """The next message to deliver (it stays until :meth:`done`)."""
        if self.dirty:
            return self.retained[next(iter(self.dirty))]
        if self.events:
            return self.events[0]
        if self.telemetry:
            return self.telemetry[0]
        return None

    def done(self, message: _Message) -> None:
        """The broker has ``message``: remove it (a retained topic only if its payload is unchanged)."""
        if message.retain:
            if self.retained.get(message.topic) is message:
                self.dirty.pop(message.topic, None)
        elif self.events and self.events[0] is message:
            self.events.popleft()
        elif self.telemetry and self.telemetry[0] is message:
            self.telemetry.popleft()


class MqttPublisher:
    """Publishes the agent's topics; ``async with MqttPublisher(settings) as mqtt: mqtt.state(...)``."""

    def __init__(self, settings: MqttSettings, agent_name: str = "mav-motor-health") -> None:
        self.settings = settings
        self.agent_name = agent_name
        self.outbox = Outbox(settings.queue_limit, settings.telemetry_limit)
        self.connected = asyncio.Event()
        self.connections = 0  #: successful connections so far
        self.published = 0
        self._group: TaskGroup | None = None
        self._task: asyncio.Task[None] | None = None
        self._client: aiomqtt.Client | None = None
        self.outbox.put_retained(settings.topic("status"), self._status(True))

    # -- what the agent calls ----------------------------------------------------------------------
    def info(self, payload: dict[str, Any]) -> None:
        self.outbox.put_retained(self.settings.topic("info"), dumps(payload))

    def state(self, motor: int, payload: dict[str, Any]) -> None:
        self.outbox.put_retained(self.settings.topic("motor", motor, "state"), dumps(payload))

    def event(self, payload: dict[str, Any]) -> None:
        self.outbox.put_event(self.settings.topic("events"), dumps(payload))

    def telemetry(self, motor: int, payload: dict[str, Any]) -> None:
        self.outbox.put_telemetry(self.settings.topic("motor", motor, "telemetry"), dumps(payload))

    async def flush(self, timeout_s: float) -> bool:
        """Wait until the outbox is empty (True) or ``timeout_s`` passed (False)."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout_s
        while len(self.outbox) and loop.time() < deadline:
            await asyncio.sleep(0.02)
        return not len(self.outbox)

    # -- lifetime ----------------------------------------------------------------------------------
    async def __aenter__(self) -> MqttPublisher:
        self._group = TaskGroup()
        await self._group.__aenter__()
        self._task = self._group.create_task(self._run(), name="mqtt")
        return self

    async def __aexit__(self, *exc_info: Any) -> None:
        await self.aclose()

    async def aclose(self, flush_s: float = 2.0) -> None:
        """Deliver what is waiting (up to ``flush_s``), say offline, disconnect, end the task."""
        if self._group is None:
            return
        if self.connected.is_set():
            await self.flush(flush_s)
            client = self._client
            if client is not None:
                with contextlib.suppress(aiomqtt.MqttError, asyncio.TimeoutError):
                    await client.publish(
                        self.settings.topic("status"), self._status(False), qos=1, retain=True, timeout=2.0
                    )
        assert self._task is not None
        self._task.cancel()
        group, self._group = self._group, None
        with contextlib.suppress(asyncio.CancelledError):
            await group.__aexit__(None, None, None)

    def _status(self, online: bool) -> bytes:
        if not online:
            return dumps({"online": False, "time_utc": utc_now()})
        return dumps({"online": True, "time_utc": utc_now(), "agent": self.agent_name})

    def _client_kwargs(self) -> dict[str, Any]:
        s = self.settings
        kwargs: dict[str, Any] = {
            "hostname": s.host,
            "port": s.port,
            "username": s.username,
            "password": s.password,
            "identifier": s.client_id,
            "keepalive": s.keepalive_s,
            "timeout": 10.0,
            "will": aiomqtt.Will(s.topic("status"), dumps({"online": False}), qos=1, retain=True),
        }
        if s.tls or s.ca_file:
            context = ssl.create_default_context(cafile=s.ca_file)
            if s.cert_file:
                context.load_cert_chain(s.cert_file, s.key_file)
            if s.tls_insecure:
                context.check_hostname = False
                context.verify_mode = ssl.CERT_NONE
            kwargs["tls_context"] = context
            kwargs["tls_insecure"] = s.tls_insecure
        return kwargs

    async def _run(self) -> None:
        delay = self.settings.reconnect_min_s
        while True:
            try:
                async with aiomqtt.Client(**self._client_kwargs()) as client:
                    self._client = client
                    self.connections += 1
                    delay = self.settings.reconnect_min_s
                    log.info(
                        "MQTT connected to %s:%d (%s)",
                        self.settings.host,
                        self.settings.port,
                        self.settings.topic(),
                    )
                    self.outbox.put_retained(self.settings.topic("status"), self._status(True))
                    self.outbox.mark_all_retained_dirty()
                    self.connected.set()
                    await self._drain(client)
            except aiomqtt.MqttError as exc:
                if self.connected.is_set():
                    log.warning("MQTT connection lost: %s; %d messages wait", exc, len(self.outbox))
                else:
                    log.warning(
                        "MQTT %s:%d: %s; retrying in %.1f s",
                        self.settings.host,
                        self.settings.port,
                        exc,
                        delay,
                    )
            finally:
                client_gone, self._client = self._client, None
                self.connected.clear()
                _consume_disconnect_error(client_gone)
            await asyncio.sleep(delay)
            delay = min(delay * 2, self.settings.reconnect_max_s)

    async def _drain(self, client: aiomqtt.Client) -> None:
        while True:
            message = self.outbox.peek()
            if message is None:
                self.outbox.wake.clear()
                # wake up now and then to notice a dead broker even when there is nothing to send
                with contextlib.suppress(asyncio.TimeoutError):
                    await asyncio.wait_for(self.outbox.wake.wait(), timeout=1.0)
                if self.outbox.peek() is None and not client._client.is_connected():
                    raise aiomqtt.MqttError("disconnected")
                continue
            await client.publish(
                message.topic, message.payload, qos=message.qos, retain=message.retain, timeout=5.0
            )
            self.outbox.done(message)
            self.published += 1


def _consume_disconnect_error(client: aiomqtt.Client | None) -> None:
    """aiomqtt leaves an unexpected disconnection's error in a future nobody reads; we have handled it."""
    future = getattr(client, "_disconnected", None)
    if future is not None and future.done() and not future.cancelled():
        future.exception()
