"""Real parts for the agent's tests: a Mosquitto broker, MAVProxy, MQTT listeners (used by conftest.py's fixtures
and imported by the tests; a module name of its own, so no other test folder's conftest can shadow it)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import paho.mqtt.client as paho
import pytest

from loopback import listen_port
from mav_motor_health.publish.mqtt import EventDedupe

MOSQUITTO = "/usr/sbin/mosquitto"
MAVPROXY = str(Path(sys.executable).parent / "mavproxy.py")
REPO = Path(__file__).resolve().parents[2]


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for(predicate: Callable[[], Any], timeout_s: float, what: str, poll_s: float = 0.02) -> Any:
    """Poll until ``predicate()`` is truthy; fail naming ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(poll_s)
    pytest.fail(f"timed out after {timeout_s} s waiting for {what}")


class Broker:
    """A Mosquitto process on a free port below the ephemeral range (``loopback.listen_port``: the tests
    restart it on the same port), with persistence so a restart keeps sessions."""

    def __init__(self, folder: Path, port: int | None = None) -> None:
        self.folder = folder
        self.port = port or listen_port()
        self.proc: subprocess.Popen[bytes] | None = None
        self.conf = folder / "mosquitto.conf"
        self.conf.write_text(
            f"listener {self.port} 127.0.0.1\nallow_anonymous true\npersistence true\n"
            f"persistence_location {folder}/\nautosave_interval 1\n"
            # as root, mosquitto would switch to user 'mosquitto', who cannot write in pytest's folders
            + ("user root\n" if os.geteuid() == 0 else "")
        )

    def start(self) -> None:
        self.proc = subprocess.Popen(
            [MOSQUITTO, "-c", str(self.conf)],
            stdout=subprocess.DEVNULL,
            stderr=(self.folder / "log").open("ab"),
        )
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                log = (self.folder / "log").read_text(errors="replace")[-2000:]
                raise RuntimeError(f"mosquitto exited ({self.proc.returncode}) on port {self.port}: {log}")
            with (
                contextlib.suppress(OSError),
                socket.create_connection(("127.0.0.1", self.port), timeout=0.2),
            ):
                return
            time.sleep(0.05)
        raise RuntimeError(f"mosquitto did not start on port {self.port}")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self.proc = None


class MqttListener:
    """A paho client in its own thread recording every message (persistent session, QoS 1)."""

    def __init__(self, port: int, topic: str, client_id: str = "test-listener") -> None:
        self.messages: list[tuple[float, str, dict[str, Any] | None, bool]] = []
        self.lock = threading.Lock()
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=False)
        self.client.on_message = self._on_message
        self.client.on_connect = lambda c, u, f, rc, p: c.subscribe(topic, qos=1)
        # a test publishes right after making its listener: wait until the broker has the subscription, or
        # a loaded machine delivers the first messages before it (a fresh-clone CI run missed run 1's events)
        self.subscribed = threading.Event()
        self.client.on_subscribe = lambda c, u, mid, codes, p: self.subscribed.set()
        self.client.reconnect_delay_set(0.1, 0.5)
        self.client.connect("127.0.0.1", port, keepalive=5)
        self.client.loop_start()
        if not self.subscribed.wait(10.0):
            self.client.loop_stop()
            raise TimeoutError(f"the listener did not subscribe to {topic} on port {port} within 10 s")

    def _on_message(self, client: Any, userdata: Any, msg: Any) -> None:
        try:
            payload = json.loads(msg.payload) if msg.payload else None
        except ValueError:
            payload = None
        with self.lock:
            self.messages.append((time.monotonic(), msg.topic, payload, bool(msg.retain)))

    def on(self, suffix: str) -> list[tuple[float, dict[str, Any]]]:
        with self.lock:
            return [(t, p) for t, topic, p, _ in self.messages if topic.endswith(suffix) and p is not None]

    def states(self) -> dict[int, str]:
        """The latest state per motor on the ``.../state`` topics."""
        return {p["motor"]: p["state"] for _, p in self.on("/state")}

    def event_payloads(self, vehicle: str) -> list[dict[str, Any]]:
        """Every event of ``vehicle`` in arrival order, repeats dropped as a consumer does: QoS 1 delivers
        at least once, and after a broker restart one event can arrive twice (same run_id and seq)."""
        dedupe = EventDedupe()
        return [p for _, p in self.on(f"{vehicle}/events") if dedupe.accept(p)]

    def events(self, vehicle: str) -> list[tuple[int, str, str]]:
        """(motor, previous, state) of every event of ``vehicle``, in arrival order, without repeats."""
        return [(p["motor"], p["previous"], p["state"]) for p in self.event_payloads(vehicle)]

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


def agent_events(agent: Any) -> list[tuple[int, str, str]]:
    """(motor, previous, state) of every state change the agent announced, in order."""
    return [(c.motor, c.previous.label, c.state.label) for c in agent.changes]


def start_mavproxy(workdir: Path, master_port: int, out_port: int, log: Any) -> subprocess.Popen:
    """MAVProxy (MAVLink 2) with its master on a UDP port we send to and one --out UDP port."""
    return subprocess.Popen(
        [
            sys.executable,
            MAVPROXY,
            f"--master=udpin:127.0.0.1:{master_port}",
            f"--out=udp:127.0.0.1:{out_port}",
            "--daemon",
            "--non-interactive",
            "--nowait",
            f"--state-basedir={workdir}",
        ],
        cwd=workdir,
        stdout=log,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        env={**os.environ, "MAVLINK20": "1"},
    )


def stop_process(proc: subprocess.Popen) -> None:
    """SIGTERM, then SIGKILL if it has not ended within 10 s."""
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(5)


class MavproxyGcs:
    """MAVProxy as the ground station: master on a UDP port the vehicle sends to, out to our socket."""

    def __init__(self, workdir: Path) -> None:
        self.master_port = free_port(socket.SOCK_DGRAM)
        self.out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.out.bind(("127.0.0.1", 0))
        self.out.settimeout(0.1)
        out_port = self.out.getsockname()[1]
        self.log = (workdir / "mavproxy.log").open("wb")
        self.proc = start_mavproxy(workdir, self.master_port, out_port, self.log)
        from pymavlink.dialects.v20 import ardupilotmega as mavlink2

        self.parser = mavlink2.MAVLink(None, 0, 0)
        self.parser.robust_parsing = True
        self.received: list[tuple[float, Any]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.out.recv(65535)
            except (TimeoutError, OSError):
                continue
            try:
                msgs = self.parser.parse_buffer(data) or []
            except Exception:
                continue
            now = time.monotonic()
            self.received.extend((now, m) for m in msgs if m.get_type() != "BAD_DATA")

    def texts(self) -> list[tuple[float, int, str]]:
        return [(t, m.severity, m.text) for t, m in list(self.received) if m.get_type() == "STATUSTEXT"]

    def close(self) -> None:
        self._stop.set()
        stop_process(self.proc)
        self._thread.join(2)
        self.out.close()
        self.log.close()


class MavproxyRouter:
    """MAVProxy forwarding between a vehicle (master, UDP in) and the agent (an --out UDP port)."""

    def __init__(self, workdir: Path) -> None:
        self.master_port = free_port(socket.SOCK_DGRAM)
        self.out_port = free_port(socket.SOCK_DGRAM)
        self.log = (workdir / "mavproxy-router.log").open("wb")
        self.proc = start_mavproxy(workdir, self.master_port, self.out_port, self.log)

    def close(self) -> None:
        stop_process(self.proc)
        self.log.close()


async def until(
    predicate: Callable[[], Any], timeout_s: float, what: str, show: Callable[[], Any] | None = None
) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        await asyncio.sleep(0.02)
    pytest.fail(f"timed out after {timeout_s} s waiting for {what}" + (f": {show()}" if show else ""))
