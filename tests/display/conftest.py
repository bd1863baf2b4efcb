"""Real parts for the display tests: a mosquitto broker with a WebSocket listener, headless Chromium
driven by Playwright, the display's HTTP server, and a real MQTT client publishing as the agent would.
"""

from __future__ import annotations

import itertools
import json
import os
import shutil
import socket
import subprocess
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
import pytest

from loopback import listen_port
from mav_motor_health.publish.web import DisplayConfig, DisplayServer

MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait_for_port(port: int, proc: subprocess.Popen[bytes], log: Path, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"mosquitto exited ({proc.returncode}):\n{log.read_text()}")
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return
        except OSError:
            time.sleep(0.05)
    raise RuntimeError(f"mosquitto did not open port {port} in {timeout_s} s:\n{log.read_text()}")


@dataclass
class Broker:
    mqtt_port: int
    ws_port: int
    workdir: Path
    process: subprocess.Popen[bytes] | None = None

    def stop(self) -> None:
        if self.process is not None:
            stop(self.process)

    @property
    def ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.ws_port}"


def start_mosquitto(
    workdir: Path, extra: str = "", listener_extra: str = "", ports: tuple[int, int] | None = None
) -> tuple[Broker, subprocess.Popen[bytes]]:
    """mosquitto 2.x with a plain MQTT and a WebSocket listener on free loopback ports (or ``ports``)."""
    workdir.mkdir(parents=True, exist_ok=True)
    # a test restarts the broker on these ports: below the ephemeral range (tests/loopback.py)
    mqtt_port, ws_port = ports or (listen_port(), listen_port())
    conf = workdir / "mosquitto.conf"
    # As root mosquitto drops to user "mosquitto", which cannot read files in pytest's private tmp.
    run_as = "user root\n" if os.geteuid() == 0 else ""
    conf.write_text(
        run_as + "per_listener_settings false\n"
        f"{extra}"
        f"listener {mqtt_port} 127.0.0.1\n"
        f"listener {ws_port} 127.0.0.1\nprotocol websockets\n"
        f"{listener_extra}"
    )
    log = workdir / "mosquitto.log"
    with log.open("wb") as out:
        proc = subprocess.Popen([MOSQUITTO, "-c", str(conf), "-v"], stdout=out, stderr=subprocess.STDOUT)
    try:
        _wait_for_port(mqtt_port, proc, log)
        _wait_for_port(ws_port, proc, log)
    except Exception:
        proc.kill()
        proc.wait()
        raise
    return Broker(mqtt_port, ws_port, workdir), proc


def stop(proc: subprocess.Popen[bytes]) -> None:
    proc.terminate()
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@pytest.fixture(scope="module")
def broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Broker]:
    b, proc = start_mosquitto(tmp_path_factory.mktemp("mosquitto"), extra="allow_anonymous true\n")
    yield b
    stop(proc)


@pytest.fixture(scope="module")  # a live sync Playwright holds an event loop: end it with the module
def browser() -> Iterator[Any]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    context = browser.new_context(viewport={"width": 1280, "height": 900}, device_scale_factor=1)
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    pg.set_default_timeout(10_000)
    yield pg
    context.close()
    assert not errors, f"JavaScript errors on the page: {errors}"


_prefixes = itertools.count(1)


@pytest.fixture
def prefix() -> str:
    """A topic prefix of its own per test, so retained messages of one test never reach another."""
    return f"mmhtest{next(_prefixes)}-{int(time.time() * 1000) % 100000}"


@pytest.fixture
def display(broker: Broker, prefix: str) -> Callable[..., DisplayServer]:
    """Factory: a running display server for this test's prefix (stopped at the end of the test)."""
    servers: list[DisplayServer] = []

    def make(**overrides: Any) -> DisplayServer:
        kw: dict[str, Any] = {"broker_ws_url": broker.ws_url, "topic_prefix": prefix, "stale_after_s": 4.0}
        kw.update(overrides)
        server = DisplayServer(DisplayConfig(**kw), port=0).__enter__()
        servers.append(server)
        return server

    yield make  # type: ignore[misc]
    for s in servers:
        s.__exit__(None, None, None)


class Publisher:
    """A real MQTT client publishing as the agent does (MQTT.md): JSON payloads, retained state."""

    def __init__(self, port: int, client_id: str, username: str | None = None, password: str | None = None):
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=client_id)
        if username is not None:
            self.client.username_pw_set(username, password)
        self.client.connect("127.0.0.1", port, keepalive=30)
        self.client.loop_start()

    def publish(self, topic: str, payload: dict[str, Any], *, retain: bool = False, qos: int = 0) -> None:
        info = self.client.publish(topic, json.dumps(payload), qos=qos, retain=retain)
        if qos > 0:  # acknowledged by the broker; QoS 0 keeps its order on the same connection anyway
            info.wait_for_publish(timeout=5)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


@pytest.fixture
def publisher(broker: Broker) -> Iterator[Publisher]:
    pub = Publisher(broker.mqtt_port, f"test-agent-{time.monotonic_ns()}")
    yield pub
    pub.close()


@pytest.fixture
def make_publisher(broker: Broker) -> Iterator[Callable[..., Publisher]]:
    """Factory: more MQTT clients (another vehicle's agent, or a user with credentials)."""
    made: list[Publisher] = []

    def make(
        client_id: str, username: str | None = None, password: str | None = None, port: int | None = None
    ) -> Publisher:
        pub = Publisher(port or broker.mqtt_port, client_id, username, password)
        made.append(pub)
        return pub

    yield make
    for pub in made:
        pub.close()


def _open_display(page: Any, server: DisplayServer, query: str = "") -> None:
    page.goto(server.url + query)
    page.wait_for_selector('#broker-status[data-state="connected"]')  # set on SUBACK: subscribed


@pytest.fixture
def open_display() -> Callable[..., None]:
    """Load the page and wait until it is connected to the broker and subscribed."""
    return _open_display


def utc(ts: float | None = None) -> str:
    t = time.time() if ts is None else ts
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(t)) + f".{int((t % 1) * 1000):03d}Z"


class AgentLike:
    """Publishes one vehicle's topic tree exactly as MQTT.md describes, with the project's motor model
    giving the model speed/current and a seeded generator the measurement noise."""

    def __init__(self, pub: Publisher, prefix: str, vehicle: str, seed: int = 1) -> None:
        import numpy as np

        from mav_motor_health.config import load_motor_params

        self.pub = pub
        self.base = f"{prefix}/{vehicle}"
        self.vehicle = vehicle
        self.params = load_motor_params("paper_x2212")
        self.rng = np.random.default_rng(seed)
        self.faults: dict[int, str] = {}
        self.states: dict[int, str] = {}
        self.run_id = f"run-{vehicle}-{seed}"
        self.seq = 0  # the last event's

    def announce(self, motors: int = 6) -> None:
        self.pub.publish(
            f"{self.base}/status",
            {"online": True, "time_utc": utc(), "agent": "mav-motor-health 0.1.0"},
            retain=True,
            qos=1,
        )
        self.pub.publish(
            f"{self.base}/info",
            {
                "vehicle_id": self.vehicle,
                "frame": "hexa-x",
                "motors": motors,
                "autopilot": "ardupilot",
                "profile": "flight",
                "params": "paper_x2212",
            },
            retain=True,
            qos=1,
        )

    def offline(self) -> None:
        self.pub.publish(f"{self.base}/status", {"online": False}, retain=True, qos=1)

    def state(self, motor: int, label: str, since_s_ago: float = 0.0, fresh: bool = True) -> str | None:
        """Publish motor's announced state (retained); returns the previous one."""
        from mav_motor_health.diagnosis.states import MotorState

        st = MotorState.from_label(label)
        previous = self.states.get(motor)
        self.states[motor] = label
        self.pub.publish(
            f"{self.base}/motor/{motor}/state",
            {
                "motor": motor,
                "state": st.label,
                "code": int(st),
                "description": st.description,
                "since_utc": utc(time.time() - since_s_ago),
                "time_utc": utc(),
                "fresh": fresh,
            },
            retain=True,
            qos=1,
        )
        return previous

    def event(self, motor: int, label: str, previous: str, t_s: float, ago_s: float = 0.0) -> dict[str, Any]:
        """A state change, its evidence computed as the telemetry is (same model, same fault), numbered
        with the run's next ``seq``; returns the payload (to publish it again as QoS 1 may)."""
        from mav_motor_health.model.equations import steady_state
        from mav_motor_health.sim.steady import faulty_steady_state

        voltage = self.flight_voltage(t_s) + 0.1 * motor
        model = steady_state(self.params, voltage)
        omega, current = faulty_steady_state(self.params, self.faults.get(motor, "NORMAL"), voltage)
        self.seq += 1
        payload = {
            "time_utc": utc(time.time() - ago_s),
            "t_s": t_s,
            "motor": motor,
            "state": label,
            "previous": previous,
            "evidence": {
                "omega_rad_s": float(omega),
                "omega_model_rad_s": float(model.omega_rad_s),
                "current_a": float(current),
                "current_model_a": float(model.current_a),
            },
            "run_id": self.run_id,
            "seq": self.seq,
        }
        self.pub.publish(f"{self.base}/events", payload, qos=1)
        return payload

    def telemetry(
        self, motor: int, t_s: float, voltage_v: float, model: tuple[float, float] | None = None
    ) -> None:
        """One telemetry sample; ``model`` (speed, current) when the caller computed it already."""
        from mav_motor_health.model.equations import steady_state
        from mav_motor_health.sim.steady import faulty_steady_state

        if model is None:
            s = steady_state(self.params, voltage_v)
            model = (float(s.omega_rad_s), float(s.current_a))
        fault = self.faults.get(motor, "NORMAL")
        omega, current = model if fault == "NORMAL" else faulty_steady_state(self.params, fault, voltage_v)
        self.pub.publish(
            f"{self.base}/motor/{motor}/telemetry",
            {
                "time_utc": utc(),
                "t_s": round(t_s, 3),
                "omega_rad_s": float(omega) + float(self.rng.uniform(-10, 10)),
                "omega_model_rad_s": model[0],
                "current_a": float(current) + float(self.rng.uniform(-0.15, 0.15)),
                "current_model_a": model[1],
                "voltage_v": voltage_v,
                "raw_state": fault,
                "steady": True,
            },
        )

    def flight_voltage(self, t_s: float) -> float:
        """A hover with slow manoeuvres: the motor voltage the telemetry is computed at."""
        import math

        return 7.0 + 1.2 * math.sin(t_s / 4.0) + 0.5 * math.sin(t_s / 1.3)

    def tick(self, t_s: float, motors: tuple[int, ...] = (1, 2, 3, 4, 5, 6)) -> None:
        """One sample of each motor; the model solved for all of them at once (vectorised)."""
        import numpy as np

        from mav_motor_health.model.equations import steady_state

        volts = np.array([self.flight_voltage(t_s) + 0.1 * m for m in motors])
        s = steady_state(self.params, volts)
        for k, m in enumerate(motors):
            self.telemetry(m, t_s, float(volts[k]), (float(s.omega_rad_s[k]), float(s.current_a[k])))


@pytest.fixture
def agent_like(publisher: Publisher, prefix: str) -> Callable[..., AgentLike]:
    def make(vehicle: str, seed: int = 1, pub: Publisher | None = None) -> AgentLike:
        return AgentLike(pub or publisher, prefix, vehicle, seed)

    return make


@pytest.fixture
def mosquitto_factory(tmp_path: Path) -> Iterator[Callable[..., Broker]]:
    """Factory: a broker of its own with extra global config (auth, ACL), stopped after the test."""
    procs: list[subprocess.Popen[bytes]] = []

    def make(extra: str, ports: tuple[int, int] | None = None) -> Broker:
        b, proc = start_mosquitto(tmp_path / f"mosquitto{len(procs)}", extra=extra, ports=ports)
        b.process = proc
        procs.append(proc)
        return b

    yield make
    for proc in procs:
        if proc.poll() is None:
            stop(proc)


@pytest.fixture
def page_for(browser: Any) -> Iterator[Callable[[], Any]]:
    """Factory: more pages (a second viewer), closed after the test."""
    contexts: list[Any] = []

    def make() -> Any:
        context = browser.new_context(viewport={"width": 1280, "height": 900})
        contexts.append(context)
        return context.new_page()

    yield make
    for c in contexts:
        c.close()


@pytest.fixture
def display_for() -> Iterator[Callable[..., DisplayServer]]:
    """Factory: a display server for a given broker and prefix (stopped at the end of the test)."""
    servers: list[DisplayServer] = []

    def make(broker: Broker, prefix: str, **overrides: Any) -> DisplayServer:
        cfg = DisplayConfig(broker_ws_url=broker.ws_url, topic_prefix=prefix, **overrides)
        server = DisplayServer(cfg, port=0).__enter__()
        servers.append(server)
        return server

    yield make
    for s in servers:
        s.__exit__(None, None, None)


@pytest.fixture(name="free_port")
def free_port_fixture() -> Callable[[], int]:
    """A free loopback port (for UDP links too: TCP and UDP ports are separate but rarely both taken)."""
    return free_port
