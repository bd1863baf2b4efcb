"""The MAVLink link: pymavlink as a bytes-to-messages parser and encoder; nothing waits on the loop.

:class:`MavlinkLink` is an async context manager. Transports come from pymavlink's ``mavutil`` (serial,
``udpin:``, ``udpout:``, ``tcp:``, ``tcpin:``), used for their bytes only, and are opened in a worker
thread (opening a serial port or a TCP connection can take seconds). Then the event loop watches the
transport's file descriptor (``loop.add_reader``) and, when it is readable, reads what is there without
waiting and parses it with one MAVLink 2 ``ardupilotmega`` parser; every message keeps its arrival time.
On an event loop without ``add_reader`` (Windows' proactor) a reader thread waits in ``select`` instead
and hands batches to the loop with ``loop.call_soon_threadsafe``. Frames to send go through a queue to a
writer thread, so a slow serial port or a full TCP buffer never stalls the loop. A broken transport (an
error, a TCP end of file) is closed and reopened with back-off; the loop only sees messages stop and
start again.

A ``.tlog`` path is a transport too (replay through the live path): a reader thread hands its records to
the loop with their own timestamps (seconds from the first record, as the log readers count them),
waiting for the loop instead of dropping messages.

Connection URLs: ``/dev/serial0:921600`` (device and baud rate), ``udpin:0.0.0.0:14550``,
``udpout:127.0.0.1:14550``, ``tcp:127.0.0.1:5760``, ``tcpin:0.0.0.0:5760``, ``flight.tlog``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import queue
import select
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from ..errors import LinkError

__all__ = ["LinkUrl", "MavlinkLink", "Received", "mavlink2", "parse_url"]

log = logging.getLogger(__name__)

_SOCKET_SCHEMES = ("udpin", "udpout", "udp", "tcp", "tcpin")
_QUEUE_LIMIT = 20_000  # messages waiting for the loop before the oldest are dropped (live links only)


@dataclass(frozen=True)
class LinkUrl:
    """A parsed connection URL: ``kind`` is ``socket``, ``serial`` or ``tlog``."""

    kind: str
    device: str
    baud: int = 921600

    def __str__(self) -> str:
        return f"{self.device}:{self.baud}" if self.kind == "serial" else self.device


def parse_url(url: str) -> LinkUrl:
    """Check a connection URL and split serial device and baud rate; raises :class:`LinkError`."""
    text = url.strip()
    scheme, sep, rest = text.partition(":")
    if sep and scheme in _SOCKET_SCHEMES:
        host, _, port = rest.rpartition(":")
        if not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise LinkError(f"bad MAVLink URL {url!r}: expected {scheme}:HOST:PORT")
        return LinkUrl("socket", text)
    if text.lower().endswith(".tlog"):
        return LinkUrl("tlog", text)
    if text.startswith("/dev/") or text.upper().startswith("COM"):
        device, _, baud = text.rpartition(":") if ":" in text else (text, "", "921600")
        if not baud.isdigit():
            raise LinkError(f"bad serial URL {url!r}: expected DEVICE[:BAUD], e.g. /dev/serial0:921600")
        return LinkUrl("serial", device, int(baud))
    raise LinkError(
        f"bad MAVLink URL {url!r}: expected /dev/DEVICE[:BAUD], udpin:HOST:PORT, udpout:HOST:PORT, "
        "tcp:HOST:PORT, tcpin:HOST:PORT or a .tlog file"
    )


@dataclass(frozen=True)
class Received:
    """One message and when it arrived: ``time_s`` on the link's clock (monotonic, or the tlog's)."""

    time_s: float
    msg: Any


class _QueueWriter:
    """The file object the encoder writes to: frames go to the writer thread."""

    def __init__(self, frames: queue.Queue[bytes | None]) -> None:
        self.frames = frames

    def write(self, data: bytes) -> None:
        self.frames.put_nowait(bytes(data))


class MavlinkLink:
    """A MAVLink connection for the event loop; ``async with MavlinkLink(url) as link: ... await link.recv()``.

    ``send(msg)`` never blocks: the frame goes to the writer thread. ``mav`` is the encoder
    (``link.mav.heartbeat_encode(...)``); ``set_source(system, component)`` changes who we say we are.
    """

    def __init__(
        self,
        url: str,
        *,
        source_system: int = 1,
        source_component: int = mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER,
        reconnect_s: float = 1.0,
        deliver_s: float = 0.01,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.url = parse_url(url)
        self.reconnect_s = reconnect_s
        self.deliver_s = deliver_s
        self.clock = clock
        self._frames: queue.Queue[bytes | None] = queue.Queue(maxsize=1000)
        self.mav = mavlink2.MAVLink(_QueueWriter(self._frames), source_system, source_component)
        self._inbox: asyncio.Queue[list[Received] | None] = asyncio.Queue()
        self._queued = 0  # messages in the inbox
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._conn: Any = None
        self._conn_lock = threading.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self.dropped = 0  #: messages dropped because the loop fell behind (live links)
        self.bad_bytes = 0  #: bytes the parser could not use
        self.opened = threading.Event()
        self._reader_task: asyncio.Task[None] | None = None
        self._parser: Any = None
        #: where a live link's messages go as they are read, on the loop (None: to the inbox, for
        #: :meth:`recv`). A consumer that handles them at once saves a queue, a future and a task step per
        #: datagram (the agent, issue 18); nothing then waits, so nothing is dropped here either (a loop
        #: that falls behind leaves them in the socket's buffer). A .tlog always goes through the inbox.
        self.on_messages: Callable[[list[Received]], None] | None = None

    # -- context manager ---------------------------------------------------------------------------
    async def __aenter__(self) -> MavlinkLink:
        self._loop = loop = asyncio.get_running_loop()
        self._threads = [threading.Thread(target=self._write_loop, name="mavlink-writer", daemon=True)]
        if self.url.kind == "tlog":
            self._threads.append(threading.Thread(target=self._read_tlog, name="mavlink-reader", daemon=True))
        elif _loop_can_watch_fds(loop):
            # sockets and serial ports: the loop watches the descriptor and reads what is there without
            # waiting (no reader thread, so no GIL hand-over per datagram); opening runs in a worker thread
            self._reader_task = loop.create_task(self._watch(), name="mavlink-reader")
        else:  # an event loop without add_reader (Windows' proactor): a reader thread
            self._threads.append(threading.Thread(target=self._read_live, name="mavlink-reader", daemon=True))
        for thread in self._threads:
            thread.start()
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        self._stop.set()
        task, self._reader_task = self._reader_task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        with contextlib.suppress(queue.Full):
            self._frames.put_nowait(None)
        loop = asyncio.get_running_loop()
        for thread in self._threads:
            await loop.run_in_executor(None, thread.join, 2.0)
        self._close_conn()

    # -- the loop's side -----------------------------------------------------------------------------
    async def recv(self) -> list[Received] | None:
        """The next messages (those that arrived together); None when the link has ended (a .tlog's end)."""
        batch = await self._inbox.get()
        if batch is not None:
            self._queued -= len(batch)
        return batch

    def send(self, msg: Any) -> None:
        """Encode and queue a message; drops it (with a log line) if the writer is far behind."""
        try:
            self.mav.send(msg)
        except queue.Full:
            log.warning("MAVLink writer queue full: dropped %s", msg.get_type())

    def set_source(self, system: int, component: int | None = None) -> None:
        self.mav.srcSystem = system
        if component is not None:
            self.mav.srcComponent = component

    @property
    def connected(self) -> bool:
        return self.opened.is_set()

    # -- threads -------------------------------------------------------------------------------------
    def _deliver(self, batch: list[Received] | None, *, wait: bool = False) -> None:
        """Hand messages to the loop: one wake-up per batch (a datagram, a read, a slice of a .tlog)."""
        loop = self._loop
        assert loop is not None
        if wait:
            asyncio.run_coroutine_threadsafe(self._put_waiting(batch), loop).result()
            return
        loop.call_soon_threadsafe(self._put_live, batch)

    async def _put_waiting(self, batch: list[Received] | None) -> None:
        self._queued += len(batch or ())
        await self._inbox.put(batch)

    def _put_live(self, batch: list[Received] | None) -> None:
        if batch is not None and self.on_messages is not None:
            self.on_messages(batch)
            return
        while batch and self._queued >= _QUEUE_LIMIT and not self._inbox.empty():
            old = self._inbox.get_nowait()  # the loop fell far behind: the oldest go first
            self._queued -= len(old or ())
            self.dropped += len(old or ())
        self._queued += len(batch or ())
        self._inbox.put_nowait(batch)

    def _open(self) -> Any:
        from pymavlink import mavutil  # transports only; imported late (it reads the environment)

        if self.url.kind == "serial":
            return mavutil.mavlink_connection(self.url.device, baud=self.url.baud, autoreconnect=True)
        return mavutil.mavlink_connection(
            self.url.device, retries=0, autoreconnect=False, reconnect_delay=0.1
        )

    def _close_conn(self) -> None:
        with self._conn_lock:
            conn, self._conn = self._conn, None
            self.opened.clear()
        if conn is not None:
            with contextlib.suppress(Exception):
                conn.close()

    async def _watch(self) -> None:
        """Keep the transport open and let the loop read it whenever it is readable."""
        loop = asyncio.get_running_loop()
        await loop.run_in_executor(None, _register_extra_messages)
        self._parser = mavlink2.MAVLink(None, 0, 0)
        self._parser.robust_parsing = True
        while True:
            try:
                conn = await loop.run_in_executor(None, self._open)
            except Exception as exc:  # any transport failure: retry, the vehicle may come later
                log.warning(
                    "MAVLink %s: cannot open (%s); retrying in %.1f s", self.url, exc, self.reconnect_s
                )
                await asyncio.sleep(self.reconnect_s)
                continue
            with self._conn_lock:
                self._conn = conn
                self.opened.set()
            log.info("MAVLink %s: open", self.url)
            broken = asyncio.Event()
            loop.add_reader(conn.fd, self._readable, conn, broken)
            try:
                await broken.wait()
            finally:
                loop.remove_reader(conn.fd)
            self._close_conn()
            await asyncio.sleep(self.reconnect_s)

    def _readable(self, conn: Any, broken: asyncio.Event) -> None:
        """The descriptor has data: read what is there (never waiting), parse, queue the messages."""
        batch: list[Received] = []
        now = self.clock()
        for _ in range(64):
            try:
                data = _raw_recv(conn)
            except (BlockingIOError, InterruptedError):
                break
            except (OSError, ValueError) as exc:
                log.warning("MAVLink %s: %s; reopening", self.url, exc)
                broken.set()
                break
            if not data:
                if _is_stream(conn) and not batch:
                    log.warning("MAVLink %s: peer closed; reconnecting", self.url)
                    broken.set()
                break
            batch.extend(Received(now, msg) for msg in self._parse(self._parser, data))
        if batch:
            self._put_live(batch)

    def _read_live(self) -> None:
        _register_extra_messages()
        parser = mavlink2.MAVLink(None, 0, 0)
        parser.robust_parsing = True
        pending: list[Received] = []
        deliver_at = math.inf
        while not self._stop.is_set():
            if pending and self.clock() >= deliver_at:
                # one wake-up of the loop per `deliver_s`, not one per datagram (CPU on a small computer)
                self._deliver(pending)
                pending, deliver_at = [], math.inf
            if self._conn is None:
                try:
                    conn = self._open()
                except Exception as exc:  # any transport failure: retry, the vehicle may come later
                    log.warning(
                        "MAVLink %s: cannot open (%s); retrying in %.1f s", self.url, exc, self.reconnect_s
                    )
                    self._stop.wait(self.reconnect_s)
                    continue
                with self._conn_lock:
                    self._conn = conn
                    self.opened.set()
                log.info("MAVLink %s: open", self.url)
            conn = self._conn
            try:
                wait_s = 0.2 if not pending else max(0.0, deliver_at - self.clock())
                ready, _, _ = select.select([conn.fd], [], [], wait_s)
                if not ready:
                    continue
                data = _raw_recv(conn)
            except (OSError, ValueError) as exc:
                log.warning("MAVLink %s: %s; reopening", self.url, exc)
                self._close_conn()
                self._stop.wait(self.reconnect_s)
                continue
            if not data:
                if _is_stream(conn):
                    # a TCP peer that closed: select says readable, recv gives nothing
                    log.warning("MAVLink %s: peer closed; reconnecting", self.url)
                    self._close_conn()
                    self._stop.wait(self.reconnect_s)
                continue
            now = self.clock()
            msgs = self._parse(parser, data)
            if msgs:
                if not pending:
                    deliver_at = now + self.deliver_s
                pending.extend(Received(now, msg) for msg in msgs)
        if pending:
            self._deliver(pending)

    def _parse(self, parser: Any, data: bytes | str) -> list[Any]:
        if isinstance(data, str):
            data = data.encode("latin-1")
        try:
            msgs = parser.parse_buffer(data) or []
        except mavlink2.MAVError:
            self.bad_bytes += len(data)
            return []
        good = []
        for msg in msgs:
            if msg.get_type() == "BAD_DATA":
                self.bad_bytes += len(msg.get_msgbuf())
            else:
                good.append(msg)
        return good

    def _read_tlog(self) -> None:
        """A .tlog: 8-byte big-endian µs timestamp, then one MAVLink 1 or 2 frame."""
        _register_extra_messages()
        parser = mavlink2.MAVLink(None, 0, 0)
        parser.robust_parsing = True
        path = Path(self.url.device)
        try:
            data = path.read_bytes()
        except OSError as exc:
            log.error("MAVLink %s: %s", path, exc)
            self._deliver(None, wait=True)
            return
        self.opened.set()
        pos = 0
        origin_us: int | None = None
        last_us = -1
        batch: list[Received] = []
        while pos + 9 <= len(data) and not self._stop.is_set():
            (stamp_us,) = struct.unpack_from(">Q", data, pos)
            magic = data[pos + 8]
            if magic == 0xFD and pos + 10 <= len(data):
                size = 10 + data[pos + 9] + 2 + (13 if data[pos + 10] & 1 else 0)
            elif magic == 0xFE:
                size = 6 + data[pos + 9] + 2
            else:
                self.bad_bytes += 1
                pos += 1  # resynchronise on the next plausible record
                continue
            frame = data[pos + 8 : pos + 8 + size]
            pos += 8 + size
            if origin_us is None:
                origin_us = stamp_us  # seconds from the first record, as the log readers count them
            if len(batch) >= 200 and stamp_us != last_us:
                # batches end between two time stamps, never inside one: replay pairs a sample with a
                # command stamped at the same time whatever their order, and so must the batches
                self._deliver(batch, wait=True)
                batch = []
            last_us = stamp_us
            batch.extend(Received((stamp_us - origin_us) / 1e6, msg) for msg in self._parse(parser, frame))
        if batch:
            self._deliver(batch, wait=True)
        self._deliver(None, wait=True)

    def _write_loop(self) -> None:
        while True:
            frame = self._frames.get()
            if frame is None or self._stop.is_set():
                return
            with self._conn_lock:
                conn = self._conn
            if conn is None:
                continue  # not connected: MAVLink is lossy anyway; HEARTBEAT and streams are repeated
            try:
                _raw_write(conn, frame)
            except (OSError, ValueError) as exc:
                log.debug("MAVLink %s: write failed: %s", self.url, exc)


def _loop_can_watch_fds(loop: asyncio.AbstractEventLoop) -> bool:
    return hasattr(loop, "add_reader") and not type(loop).__name__.startswith("Proactor")


def _is_stream(conn: Any) -> bool:
    return type(conn).__name__ in ("mavtcp", "mavtcpin")


def _raw_recv(conn: Any) -> bytes | str:
    # mavutil's TCP recv prints to stdout and reconnects by itself; we want the bare socket's answer
    if type(conn).__name__ == "mavtcp":
        return conn.port.recv(4096)
    return conn.recv(4096)


def _raw_write(conn: Any, frame: bytes) -> None:
    if type(conn).__name__ == "mavtcp":
        conn.port.sendall(frame)
    else:
        conn.write(frame)


def _register_extra_messages() -> None:
    """PX4's ESC_STATUS (missing from pymavlink's dialects) and our MOTOR_HEALTH become decodable."""
    from ..publish import dialect

    dialect.register(mavlink2)
