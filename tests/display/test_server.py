"""The display's HTTP server and command: what is served, what is refused, and the real CLI process."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from mav_motor_health.cli import main
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.errors import ConfigError
from mav_motor_health.publish.web import HEXA_X, DisplayConfig, DisplayServer
from mav_motor_health.publish.web.server import STATIC_FILES

pytestmark = pytest.mark.timeout(60)
SRC = Path(__file__).resolve().parents[2] / "src"


def fetch(url: str, method: str = "GET") -> tuple[int, dict[str, str], bytes]:
    req = urllib.request.Request(url, method=method)
    try:
        with urllib.request.urlopen(req, timeout=5) as resp:
            return resp.status, dict(resp.headers), resp.read()
    except urllib.error.HTTPError as exc:
        return exc.code, dict(exc.headers), exc.read()


@pytest.fixture(scope="module")
def server() -> Any:
    with DisplayServer(
        DisplayConfig(broker_ws_url="wss://broker.example:8081", topic_prefix="fleet/a"), port=0
    ) as s:
        yield s


def test_page_and_assets_are_served_with_a_strict_policy(server: DisplayServer) -> None:
    status, headers, body = fetch(server.url)
    assert status == 200 and headers["Content-Type"].startswith("text/html")
    assert "script-src 'self'" in headers["Content-Security-Policy"]
    assert headers["X-Content-Type-Options"] == "nosniff"
    page = body.decode()
    refs = re.findall(r'(?:src|href)="([^"]+)"', page)
    assert refs and all("/" + r in STATIC_FILES for r in refs), refs  # nothing from elsewhere: no CDN
    for path in STATIC_FILES:
        status, _, body = fetch(server.url.rstrip("/") + path)
        assert status == 200 and body, path


def test_config_json_says_where_the_broker_is_and_how_to_draw(server: DisplayServer) -> None:
    status, headers, body = fetch(server.url + "config.json")
    cfg = json.loads(body)
    assert status == 200 and headers["Content-Type"] == "application/json"
    assert cfg["broker_ws_url"] == "wss://broker.example:8081"
    assert cfg["topic_prefix"] == "fleet/a"
    assert cfg["layouts"]["hexa-x"] == [m.to_dict() for m in HEXA_X]
    assert set(cfg["states"]) == {s.label for s in MotorState}
    assert cfg["states"]["F3.1"] == {"code": 3, "description": "propeller damage", "kind": "fault"}
    assert cfg["states"]["NO_DATA"]["kind"] == "nodata"
    assert not any("pass" in k or "user" in k for k in cfg)


def test_read_only_and_nothing_else_served(server: DisplayServer) -> None:
    for method in ("POST", "PUT", "DELETE"):
        status, headers, _ = fetch(server.url + "config.json", method)
        assert status == 405 and headers["Allow"] == "GET, HEAD"
    for path in ("../server.py", "static/index.html", "%2e%2e/layout.py", "server.py", "x.js"):
        assert fetch(server.url + path)[0] == 404, path
    status, _, body = fetch(server.url + "display.js", "HEAD")
    assert status == 200 and body == b""


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"broker_ws_url": "ws://viewer:secret@broker:9001"}, "holds credentials"),
        ({"broker_ws_url": "mqtt://broker:1883"}, "not usable"),
        ({"topic_prefix": "mmh/#"}, "prefix"),
        ({"topic_prefix": ""}, "prefix"),
        ({"stale_after_s": 0.0}, "positive"),
    ],
)
def test_bad_configuration_is_refused(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        DisplayConfig(**kwargs)


def test_cli_refuses_credentials_in_the_url(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["display", "--broker-ws", "wss://u:p@broker:8081", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert "display: error" in err and "credentials" in err


def test_cli_serves_until_interrupted(tmp_path: Path) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "mav_motor_health", "display", "--port", "0", "--prefix", "lab"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin"},
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        url = re.search(r"http://\S+/", line)
        assert url, line
        cfg = json.loads(fetch(url.group(0) + "config.json")[2])
        assert cfg["topic_prefix"] == "lab" and cfg["broker_ws_url"] is None
        proc.send_signal(signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
            pytest.fail(f"display did not stop on SIGINT within 30 s; its stderr:\n{err}")
        assert proc.returncode == 130, err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_layout_is_ardupilot_hexa_x() -> None:
    """AP_MotorsMatrix::setup_hexa_matrix, MOTOR_FRAME_TYPE_X: {angle, yaw factor, testing order}."""
    ardupilot = {
        1: (90, "CW", 2),
        2: (-90, "CCW", 5),
        3: (-30, "CW", 6),
        4: (150, "CCW", 3),
        5: (30, "CCW", 1),
        6: (-150, "CW", 4),
    }
    assert {m.number: (m.angle_deg, m.spin, m.testing_order) for m in HEXA_X} == ardupilot
    right, forward = HEXA_X[4].right_forward  # motor 5: front right
    assert right > 0 and forward > 0
