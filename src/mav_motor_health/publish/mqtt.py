"""MQTT publishing through aiomqtt: the topic tree in ``docs/agent.md``, surviving broker outages.

Topics under ``<prefix>/<vehicle>/``: ``status`` and ``info`` (retained), ``motor/<n>/state`` (retained),
``motor/<n>/telemetry`` (QoS 0, not retained) and ``events`` (QoS 1). The last will publishes
``{"online": false, "run_id": ...}`` retained on ``status``.

:class:`MqttPublisher` is an async context manager that owns one connection task in a ``TaskGroup``
(cancelled on exit). Callers never wait for the broker: ``state``, ``event`` and ``telemetry`` put a
message in the :class:`Outbox` and return. The connection task (re)connects with back-off and drains
the outbox in order of importance: retained topics (latest payload per topic), events (in order, never
dropped while there is room), then telemetry (a short queue whose oldest entries are dropped first, and
which gives up its room to events when the outbox is full). After every (re)connect all retained topics are
published again, so a broker that restarted without persistence is whole again. A message leaves the
outbox only once the broker acknowledged it (QoS 1): delivery is at-least-once.

At-least-once means a consumer can get one event twice (a PUBACK lost in a broker restart: the event goes
out again). So every event carries ``run_id`` (one per publisher, i.e. per agent run) and ``seq`` (1, 2, 3...
within the run), and :class:`EventDedupe` drops what a consumer has seen already by that pair.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import math
import secrets
import ssl
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any
from urllib.parse import unquote, urlsplit

import aiomqtt

from .._aio import TaskGroup
from ..errors import ConfigError

__all__ = [
    "EventDedupe",
    "MqttPublisher",
    "MqttSettings",
    "Outbox",
    "event_key",
    "new_run_id",
    "parse_mqtt_url",
    "utc_now",
]

log = logging.getLogger(__name__)


def utc_now() -> str:
    """ISO 8601 UTC time with ``Z``, millisecond resolution."""
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def new_run_id() -> str:
    """An id for one agent run: its start time (UTC, readable in a log) and 32 random bits (two agents
    started in the same second differ). ``seq`` starts at 1 again in every run; the id is how a consumer
    tells a restarted agent's low ``seq`` from an old event delivered again."""
    return f"{datetime.now(timezone.utc):%Y%m%dT%H%M%SZ}-{secrets.token_hex(4)}"


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


def event_key(payload: Mapping[str, Any]) -> tuple[str, int] | None:
    """An event's ``(run_id, seq)``, or None when it has none (an agent from before they existed)."""
    run_id, seq = payload.get("run_id"), payload.get("seq")
    if not isinstance(run_id, str) or not run_id or not isinstance(seq, int) or isinstance(seq, bool):
        return None
    return run_id, seq


@dataclass
class _RunSeen:
    """The ``seq`` numbers seen of one run: the highest, and every one within the window below it."""

    highest: int = 0
    seqs: set[int] = field(default_factory=set)


class EventDedupe:
    """Drops events a consumer has seen already, by ``(run_id, seq)``: ``if dedupe.accept(payload): ...``.

    Events go out at QoS 1, delivered at least once: after a broker restart the same event can arrive
    twice, with the same ``run_id`` and ``seq``. A new ``run_id`` is a restarted agent, whose ``seq``
    starts at 1 again: accepted, not taken for repeats.

    Out of order: a ``seq`` not seen before is accepted even below the highest one seen (a late delivery
    is news, not a repeat; the agent sends in order, but a bridge or a second subscription may not keep
    it), as long as it is one of the ``window`` numbers up to the highest (``seq > highest - window``);
    further back it is dropped, because the record of which ones came there is gone. A gap (``seq`` jumping) is accepted: it means events were
    lost (the agent's outbox was full), not repeated. Payloads without ``run_id``/``seq`` are always
    accepted: nothing tells a repeat of them. The ``runs`` most recently heard runs are remembered.
    The display's page has the same rules in JavaScript (``MmhEventDedupe`` in ``web/static/mqtt.js``).
    """

    def __init__(self, window: int = 1024, runs: int = 64) -> None:
        self.window = window
        self.runs = runs
        self.dropped = 0  #: repeats dropped so far
        self._seen: dict[str, _RunSeen] = {}  # least recently heard run first

    def accept(self, payload: Mapping[str, Any]) -> bool:
        """True the first time an event is seen (pass it on), False for a repeat (drop it)."""
        key = event_key(payload)
        if key is None:
            return True
        run_id, seq = key
        seen = self._run(run_id)
        if seq in seen.seqs or seq <= seen.highest - self.window:
            self.dropped += 1
            return False
        seen.seqs.add(seq)
        if seq > seen.highest:
            seen.highest = seq
            if len(seen.seqs) > 2 * self.window:  # forget the ones out of the window, now and then
                seen.seqs = {s for s in seen.seqs if s > seq - self.window}
        return True

    def _run(self, run_id: str) -> _RunSeen:
        """The run's record, now the most recently heard; the least recent one forgotten past ``runs``."""
        seen = self._seen.pop(run_id, None) or _RunSeen()
        self._seen[run_id] = seen
        if len(self._seen) > self.runs:
            del self._seen[next(iter(self._seen))]
        return seen


class MqttPublisher:
    """Publishes the agent's topics; ``async with MqttPublisher(settings) as mqtt: mqtt.state(...)``.

    ``run_id`` names this run in every event and in ``status`` (a fresh :func:`new_run_id` by default);
    ``event_seq`` is the ``seq`` of the last event queued.
    """

    def __init__(
        self, settings: MqttSettings, agent_name: str = "mav-motor-health", run_id: str | None = None
    ) -> None:
        self.settings = settings
        self.agent_name = agent_name
        self.run_id = run_id or new_run_id()
        self.event_seq = 0
        #: set when the broker refused the credentials (then no more attempts are made)
        self.login_refused: str | None = None
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
        """Queue an event numbered with this run's next ``seq``: QoS 1 may deliver it twice, and
        ``(run_id, seq)`` is what lets a consumer drop the repeat (:class:`EventDedupe`)."""
        self.event_seq += 1
        stamped = {**payload, "run_id": self.run_id, "seq": self.event_seq}
        self.outbox.put_event(self.settings.topic("events"), dumps(stamped))

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
            return dumps({"online": False, "time_utc": utc_now(), "run_id": self.run_id})
        return dumps({"online": True, "time_utc": utc_now(), "agent": self.agent_name, "run_id": self.run_id})

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
            "will": aiomqtt.Will(
                s.topic("status"), dumps({"online": False, "run_id": self.run_id}), qos=1, retain=True
            ),
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
                refused = _login_refused(exc)
                if refused is not None:
                    # retrying cannot help: say it once; the agent's MAVLink side carries on without MQTT
                    self.login_refused = (
                        f"MQTT broker {self.settings.host}:{self.settings.port} refused the login "
                        f"({refused}); not retrying: check the user name and password"
                    )
                    log.error("%s", self.login_refused)
                    return
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


#: CONNACK codes that say the broker will not accept these credentials (MQTT 3.1.1: 4, 5; MQTT 5: 134, 135)
_LOGIN_REFUSED = {
    4: "bad user name or password",
    5: "not authorised",
    134: "bad user name or password",
    135: "not authorised",
}


def _login_refused(exc: aiomqtt.MqttError) -> str | None:
    """The reason if ``exc`` is the broker refusing the credentials, else None."""
    from aiomqtt.exceptions import MqttConnectError

    # only the broker's answer to CONNECT: a lost or refused socket raises MqttCodeError with paho's own
    # error numbers (4 and 5 there mean "no connection" and "connection refused")
    rc = exc.rc if isinstance(exc, MqttConnectError) else None
    if rc is None:
        return None
    code: Any = getattr(rc, "value", rc)
    try:
        return _LOGIN_REFUSED.get(int(code))
    except (TypeError, ValueError):
        return None


def _consume_disconnect_error(client: aiomqtt.Client | None) -> None:
    """aiomqtt leaves an unexpected disconnection's error in a future nobody reads; we have handled it."""
    future = getattr(client, "_disconnected", None)
    if future is not None and future.done() and not future.cancelled():
        future.exception()
