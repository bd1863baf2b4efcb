"""MQTT with TLS and username/password against a real Mosquitto: the agent connects with the right
credentials and CA; with wrong ones it says so once, stops asking, keeps diagnosing over MAVLink and ends
with a failing exit code."""

from __future__ import annotations

import asyncio
import io
import json
import logging
import os
import socket
import ssl
import subprocess
from pathlib import Path

import paho.mqtt.client as paho
import pytest
from agent_parts import MOSQUITTO, free_port, wait_for
from vehicle_peer import VehiclePeer

from mav_motor_health.agent import Agent, load_agent_config
from mav_motor_health.agent.app import run_agent


def _accepts(port: int) -> bool:
    try:
        socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
    except OSError:
        return False
    return True


def run(*cmd: str, cwd: Path) -> None:
    subprocess.run(cmd, cwd=cwd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


@pytest.fixture
def tls_broker(tmp_path: Path):
    d = tmp_path / "tls"
    d.mkdir()
    run("openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key", "-out", "ca.crt",
        "-days", "2", "-subj", "/CN=mmh-test-ca", cwd=d)  # fmt: skip
    run("openssl", "req", "-newkey", "rsa:2048", "-nodes", "-keyout", "server.key", "-out", "server.csr",
        "-subj", "/CN=127.0.0.1", cwd=d)  # fmt: skip
    (d / "san.ext").write_text("subjectAltName=IP:127.0.0.1\n")
    run("openssl", "x509", "-req", "-in", "server.csr", "-CA", "ca.crt", "-CAkey", "ca.key", "-CAcreateserial",
        "-out", "server.crt", "-days", "2", "-extfile", "san.ext", cwd=d)  # fmt: skip
    run("/usr/bin/mosquitto_passwd", "-b", "-c", "passwd", "pilot", "s3cret", cwd=d)
    port = free_port()
    (d / "mosquitto.conf").write_text(
        f"listener {port} 127.0.0.1\ncafile {d}/ca.crt\ncertfile {d}/server.crt\nkeyfile {d}/server.key\n"
        f"allow_anonymous false\npassword_file {d}/passwd\n" + ("user root\n" if os.geteuid() == 0 else "")
    )
    proc = subprocess.Popen([MOSQUITTO, "-c", str(d / "mosquitto.conf")], stderr=(d / "log").open("wb"))
    wait_for(lambda: _accepts(port), 10, "the TLS broker listening")
    yield d, port
    proc.terminate()
    proc.wait(10)


def test_agent_publishes_over_tls_with_a_password_and_survives_a_wrong_one(
    tls_broker, paper_motor, tmp_path, caplog
):
    folder, port = tls_broker
    received: list[tuple[str, dict]] = []
    listener = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id="tls-listener")
    listener.tls_set(ca_certs=str(folder / "ca.crt"), cert_reqs=ssl.CERT_REQUIRED)
    listener.username_pw_set("pilot", "s3cret")
    listener.on_connect = lambda c, u, f, rc, p: c.subscribe("mmh/#", qos=1)
    listener.on_message = lambda c, u, m: received.append((m.topic, json.loads(m.payload)))
    listener.connect("127.0.0.1", port)
    listener.loop_start()
    (tmp_path / "pw").write_text("s3cret\n")
    good = tmp_path / "good.toml"
    good.write_text(
        f'[agent]\nvehicle_id = "tls1"\n[mqtt]\nurl = "mqtts://127.0.0.1:{port}"\nusername = "pilot"\n'
        f'password_file = "pw"\nca_file = "{folder}/ca.crt"\nreconnect_min_s = 0.1\nreconnect_max_s = 0.5\n'
    )
    bad = tmp_path / "bad.toml"
    bad.write_text(
        f'[agent]\nvehicle_id = "tls2"\n[mqtt]\nurl = "mqtts://pilot:wrong@127.0.0.1:{port}"\n'
        f'ca_file = "{folder}/ca.crt"\nreconnect_min_s = 0.1\nreconnect_max_s = 0.5\n'
    )

    async def main() -> None:
        with VehiclePeer(paper_motor) as peer:
            url = f"udpout:127.0.0.1:{peer.port}"
            async with Agent(load_agent_config(good, connect=url)) as agent:
                while not any(t == "mmh/tls1/motor/3/state" for t, _ in received):
                    await asyncio.sleep(0.05)
                assert agent.mqtt is not None and agent.mqtt.settings.tls
            async with Agent(load_agent_config(bad, connect=url)) as agent:
                await asyncio.sleep(1.5)  # retrying could not help: one refusal, said once
                assert agent.mqtt is not None and agent.mqtt.connections == 0
                assert agent.mqtt.login_refused is not None
                assert "refused the login (" in agent.mqtt.login_refused  # Mosquitto: "not authorised"
                assert agent.monitor.samples > 0  # the MAVLink side carries on regardless
                assert ("MQTT login refused: no MQTT") in [text for _, text in agent.statustexts]

    try:
        with caplog.at_level(logging.ERROR, logger="mav_motor_health"):
            asyncio.run(asyncio.wait_for(main(), 60))
        said = [r.getMessage() for r in caplog.records if "refused the login" in r.getMessage()]
        assert len(said) == 1 and f"127.0.0.1:{port}" in said[0]
        status = [p for t, p in received if t == "mmh/tls1/status"]
        assert status[0]["online"] is True and status[-1]["online"] is False
        assert not any(t.startswith("mmh/tls2/") for t, _ in received)
    finally:
        listener.loop_stop()
        listener.disconnect()


def test_a_refused_login_ends_the_run_with_a_failing_exit_code(tls_broker, paper_motor, tmp_path) -> None:
    folder, port = tls_broker
    bad = tmp_path / "bad.toml"
    bad.write_text(
        f'[agent]\nvehicle_id = "tls3"\n[mqtt]\nurl = "mqtts://pilot:wrong@127.0.0.1:{port}"\n'
        f'ca_file = "{folder}/ca.crt"\n'
    )
    with VehiclePeer(paper_motor) as peer:
        config = load_agent_config(bad, connect=f"udpout:127.0.0.1:{peer.port}")
        code = asyncio.run(run_agent(config, tui=False, stream=io.StringIO(), duration_s=2.0))
    assert code == 3
