"""The two ways docs/display.md lets viewers in without baking a secret into the page: anonymous
read-only access through the broker's ACL, or credentials the viewer types into the page."""

from __future__ import annotations

import json
import subprocess
import urllib.request
from typing import Any

import pytest

pytestmark = pytest.mark.timeout(60)

# The ACL of docs/display.md: anonymous clients (the displays) may only read; the agent may write.
ACL = """\
topic read mmh-acl/#

user agent-hexa-01
topic readwrite mmh-acl/hexa-01/#

user viewer
topic read mmh-acl/#
"""


def make_password_file(path: Any, users: dict[str, str]) -> None:
    for k, (user, password) in enumerate(users.items()):
        flags = ["-b", "-c"] if k == 0 else ["-b"]
        subprocess.run(
            ["mosquitto_passwd", *flags, str(path), user, password], check=True, capture_output=True
        )


def served_bytes(url: str) -> bytes:
    out = b""
    for path in ("", "config.json", "display.js", "mqtt.js", "hexaview.js", "index.html"):
        with urllib.request.urlopen(url + path, timeout=5) as resp:
            out += resp.read()
    return out


def test_anonymous_viewers_read_only_through_the_acl(
    mosquitto_factory: Any,
    make_publisher: Any,
    display_for: Any,
    page: Any,
    open_display: Any,
    tmp_path: Any,
) -> None:
    make_password_file(tmp_path / "passwd", {"agent-hexa-01": "agent-secret"})
    (tmp_path / "acl").write_text(ACL)
    broker = mosquitto_factory(
        f"allow_anonymous true\npassword_file {tmp_path / 'passwd'}\nacl_file {tmp_path / 'acl'}\n"
    )
    server = display_for(broker, "mmh-acl")
    open_display(page, server)
    agent = make_publisher("agent", "agent-hexa-01", "agent-secret", port=broker.mqtt_port)
    state = {
        "motor": 4,
        "state": "F2.1",
        "code": 2,
        "description": "phase open",
        "since_utc": "2026-01-01T00:00:00Z",
    }
    agent.publish("mmh-acl/hexa-01/motor/4/state", state, retain=True, qos=1)
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="4"][data-state="F2.1"]')

    # an anonymous client (anyone who can load the page) cannot write: its forged state never arrives
    intruder = make_publisher("intruder", port=broker.mqtt_port)
    intruder.publish(
        "mmh-acl/hexa-01/motor/4/state", {**state, "state": "NORMAL", "code": 0}, retain=True, qos=1
    )
    agent.publish("mmh-acl/hexa-01/motor/3/state", {**state, "motor": 3, "state": "F1.1"}, retain=True, qos=1)
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="3"][data-state="F1.1"]')
    assert page.locator('#hexaview .mmh-hv-motor[data-motor="4"]').get_attribute("data-state") == "F2.1"
    assert b"agent-secret" not in served_bytes(server.url)


def test_viewer_types_credentials_into_the_page(
    mosquitto_factory: Any, make_publisher: Any, display_for: Any, page: Any, tmp_path: Any
) -> None:
    make_password_file(tmp_path / "passwd", {"agent-hexa-01": "agent-secret", "viewer": "viewer-secret"})
    (tmp_path / "acl").write_text(ACL)
    broker = mosquitto_factory(
        f"allow_anonymous false\npassword_file {tmp_path / 'passwd'}\nacl_file {tmp_path / 'acl'}\n"
    )
    server = display_for(broker, "mmh-acl", ask_credentials=True)
    agent = make_publisher("agent", "agent-hexa-01", "agent-secret", port=broker.mqtt_port)
    agent.publish(
        "mmh-acl/hexa-01/motor/1/state",
        {
            "motor": 1,
            "state": "F4.2",
            "code": 5,
            "description": "back-EMF signal error",
            "since_utc": "2026-01-01T00:00:00Z",
        },
        retain=True,
        qos=1,
    )
    page.goto(server.url)
    page.wait_for_selector("#login", state="visible")
    assert not json.loads(urllib.request.urlopen(server.url + "config.json", timeout=5).read())[
        "broker_ws_url"
    ].count("@")

    page.fill("#login-user", "viewer")
    page.fill("#login-password", "wrong")
    page.click("#login button[type=submit]")
    page.wait_for_selector('#broker-status[data-state="unauthorised"]')
    assert page.locator("#login").is_visible()
    assert "refused" in page.locator("#login-reason").inner_text()

    page.fill("#login-user", "viewer")
    page.fill("#login-password", "viewer-secret")
    page.click("#login button[type=submit]")
    page.wait_for_selector('#broker-status[data-state="connected"]')
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="1"][data-state="F4.2"]')
    assert page.locator("#login").is_hidden()
    assert page.locator("#login-password").input_value() == ""  # not left in the form
    assert b"viewer-secret" not in served_bytes(server.url)
