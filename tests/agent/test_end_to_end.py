"""End to end on loopback with real parts: a MAVLink vehicle on a UDP socket ↔ the agent ↔ Mosquitto, and
MAVProxy as the ground station receiving the agent's STATUSTEXT through the vehicle.
"""

from __future__ import annotations

import asyncio
import os
import signal
import subprocess
import sys
from typing import Any

from agent_parts import REPO, MqttListener, agent_events, until, wait_for
from vehicle_peer import VehiclePeer

from mav_motor_health.agent import Agent, load_agent_config
from mav_motor_health.diagnosis.states import MotorState

VEHICLE = "hexa-test"


def agent_config(peer: VehiclePeer, broker_port: int, **kw: Any):
    # The peer holds every motor at one constant throttle with steady-state faults, like the paper's
    # testbed: the testbed profile is the one for it (the flight profile's bands are tuned for gusts).
    kw.setdefault("profile", "testbed")
    return load_agent_config(
        None,
        connect=f"udpout:127.0.0.1:{peer.port}",
        mqtt_url=f"mqtt://127.0.0.1:{broker_port}",
        vehicle_id=VEHICLE,
        **kw,
    )


def gcs_up(gcs) -> bool:
    """MAVProxy is forwarding the vehicle (a one-shot STATUSTEXT sent before it listens would be lost)."""
    return any(m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1 for _, m in list(gcs.received))


def all_normal(listener: MqttListener) -> bool:
    states = listener.states()
    return len(states) == 6 and set(states.values()) == {"NORMAL"}


def model_checked(listener: MqttListener) -> bool:
    """The agent has checked the motor model against the vehicle (no fault is announced before)."""
    infos = listener.on("/info")
    return bool(infos) and infos[-1][1].get("model_check", {}).get("verdict") == "fits"


def test_fault_is_announced_over_mavlink_and_mqtt_within_a_second(paper_motor, broker, mavproxy):
    listener = MqttListener(broker.port, f"mmh/{VEHICLE}/#")

    async def main() -> None:
        with VehiclePeer(paper_motor, gcs_port=mavproxy.master_port) as peer:
            async with Agent(agent_config(peer, broker.port)) as agent:
                await until(lambda: all_normal(listener), 30, "six motors NORMAL on MQTT")
                await until(lambda: gcs_up(mavproxy), 30, "MAVProxy forwarding the vehicle")
                # the agent asked ArduPilot for ESC telemetry with SET_MESSAGE_INTERVAL, read the mapping
                asked = {int(m.param1) for _, m in peer.messages("COMMAND_LONG") if m.command == 511}
                assert {11030, 36} <= asked
                assert {m.param_id for _, m in peer.messages("PARAM_REQUEST_READ")} >= {
                    "SERVO1_FUNCTION",
                    "MOT_PWM_MAX",
                }
                beats = peer.messages("HEARTBEAT")
                assert beats and all(m.type == 18 and m.get_srcComponent() == 191 for _, m in beats)

                await until(
                    lambda: model_checked(listener), 30, "the motor model checked against the vehicle"
                )
                onset = peer.inject(4, "F3.1")
                mqtt_at = await until(
                    lambda: next(
                        (t for t, p in listener.on("/events") if p["motor"] == 4 and p["state"] == "F3.1"),
                        None,
                    ),
                    10,
                    "the F3.1 event on MQTT",
                )
                gcs_at = await until(
                    lambda: next(
                        (
                            t
                            for t, sev, text in mavproxy.texts()
                            if text == "Motor 4: propeller damage (F3.1)"
                        ),
                        None,
                    ),
                    10,
                    "the STATUSTEXT at MAVProxy",
                    lambda: (
                        list(agent.statustexts),
                        [m.text for _, m in peer.messages("STATUSTEXT")],
                        mavproxy.texts(),
                    ),
                )
                assert mqtt_at - onset < 1.0, f"MQTT event {mqtt_at - onset:.2f} s after onset"
                assert gcs_at - onset < 1.0, (
                    f"STATUSTEXT at the ground station {gcs_at - onset:.2f} s after onset"
                )
                assert [sev for _, sev, text in mavproxy.texts() if "(F3.1)" in text] == [4]  # WARNING
                state = await until(
                    lambda: next((p for _, p in reversed(listener.on("motor/4/state"))), None),
                    5,
                    "retained state",
                )
                assert (state["state"], state["code"], state["description"], state["fresh"]) == (
                    "F3.1",
                    3,
                    "propeller damage",
                    True,
                )
                # steady telemetry on MQTT, measured against the model
                tele = await until(
                    lambda: [
                        p
                        for _, p in listener.on("motor/4/telemetry")
                        if p["raw_state"] == "F3.1" and p["steady"]
                    ],
                    5,
                    "steady F3.1 telemetry",
                )
                assert tele[-1]["omega_rad_s"] > tele[-1]["omega_model_rad_s"] + 20
                assert tele[-1]["current_a"] < tele[-1]["current_model_a"]
                # NAMED_VALUE_INT reaches the ground station; MOTOR_HEALTH reaches the vehicle
                await until(
                    lambda: any(
                        m.get_type() == "NAMED_VALUE_INT" and m.name == "MH_M4" and m.value == 3
                        for _, m in list(mavproxy.received)
                    ),
                    5,
                    "NAMED_VALUE_INT MH_M4 = 3 at MAVProxy",
                )
                await until(
                    lambda: any(m.motor == 4 and m.state == 3 for _, m in peer.messages("MOTOR_HEALTH")),
                    5,
                    "MOTOR_HEALTH for motor 4 at the vehicle",
                )
                info = next(p for _, p in reversed(listener.on("/info")))
                assert info["autopilot"] == "ardupilot" and info["motors"] == 6
                assert agent.link.dropped == 0 and agent.link.bad_bytes == 0

    try:
        asyncio.run(main())
    finally:
        listener.close()


def test_link_loss_reboot_and_silent_esc_lose_no_state_change(paper_motor, broker, mavproxy):
    listener = MqttListener(broker.port, f"mmh/{VEHICLE}/#", client_id="listener-link")

    async def main() -> None:
        with VehiclePeer(paper_motor, gcs_port=mavproxy.master_port) as peer:
            fast = agent_config(peer, broker.port).with_overrides(heartbeat_timeout_s=1.5)
            async with Agent(fast) as agent:
                await until(lambda: all_normal(listener), 30, "six motors NORMAL")
                await until(lambda: gcs_up(mavproxy), 30, "MAVProxy forwarding the vehicle")
                # one ESC goes silent: ArduPilot repeats its values with a frozen count
                peer.silent.add(6)
                await until(lambda: listener.states().get(6) == "NO_DATA", 5, "motor 6 NO_DATA")
                await until(
                    lambda: any(t == "Motor 6: no ESC telemetry" for _, _, t in mavproxy.texts()),
                    5,
                    "silence told",
                )
                peer.silent.discard(6)
                await until(lambda: listener.states().get(6) == "NORMAL", 5, "motor 6 back")

                # the link drops; the autopilot reboots meanwhile (forgets the streams) and a motor fails
                peer.link_up = False
                await until(lambda: not agent.tracker.up, 10, "the agent noticing the lost autopilot")
                await until(lambda: set(listener.states().values()) == {"NO_DATA"}, 5, "all motors NO_DATA")
                peer.reboot()
                peer.inject(2, "F2.1")
                peer.link_up = True
                await until(
                    lambda: listener.states().get(2) == "F2.1",
                    15,
                    "motor 2 F2.1 after the link returns",
                )
                await until(
                    lambda: any(
                        sev == 2 and t == "Motor 2: phase open (F2.1)" for _, sev, t in mavproxy.texts()
                    ),
                    5,
                    "CRITICAL STATUSTEXT for motor 2",
                )
                assert agent.tracker.losses >= 1
                # every change the agent made is on MQTT, in order
                await until(
                    lambda: listener.events(VEHICLE) == agent_events(agent),
                    5,
                    "MQTT events = agent changes",
                    lambda: (listener.events(VEHICLE), agent_events(agent)),
                )
                assert (6, "NORMAL", "NO_DATA") in agent_events(agent)
                assert (2, "NO_DATA", "F2.1") in agent_events(agent) or (2, "NORMAL", "F2.1") in agent_events(
                    agent
                )

                # ESC telemetry stops for all motors (streams dropped) while HEARTBEAT goes on:
                # one "ESC telemetry lost" line, and the agent asks for the streams again by itself
                with peer.lock:
                    peer.intervals.clear()
                await until(
                    lambda: any(t == "ESC telemetry lost" for _, _, t in mavproxy.texts()), 8, "ESC lost told"
                )
                await until(lambda: listener.states().get(1) == "NORMAL", 10, "streams requested again")

    try:
        asyncio.run(main())
    finally:
        listener.close()


def test_broker_restart_mid_flight_loses_no_state_change(paper_motor, broker):
    listener = MqttListener(broker.port, f"mmh/{VEHICLE}/#", client_id="listener-broker")

    async def main() -> None:
        with VehiclePeer(paper_motor) as peer:
            config = agent_config(peer, broker.port)
            async with Agent(config) as agent:
                await until(lambda: all_normal(listener), 30, "six motors NORMAL")
                await until(
                    lambda: listener.events(VEHICLE) == agent_events(agent),
                    10,
                    "events delivered before the stop",
                )
                connections = agent.mqtt.connections
                await asyncio.get_running_loop().run_in_executor(None, broker.stop)
                peer.inject(5, "F3.1")
                await until(
                    lambda: agent.monitor.status[5].state == MotorState.F3_1, 5, "motor 5 F3.1 (broker down)"
                )
                peer.inject(5, "NORMAL")
                await until(
                    lambda: agent.monitor.status[5].state == MotorState.NORMAL,
                    5,
                    "motor 5 back (broker down)",
                )
                peer.inject(1, "F4.2")
                await until(
                    lambda: agent.monitor.status[1].state == MotorState.F4_2, 5, "motor 1 F4.2 (broker down)"
                )
                assert len(agent.mqtt.outbox.events) >= 3  # waiting for the broker
                await asyncio.get_running_loop().run_in_executor(None, broker.start)
                await until(lambda: agent.mqtt.connections > connections, 20, "the agent reconnecting")
                await until(
                    lambda: listener.events(VEHICLE) == agent_events(agent),
                    20,
                    "every change on MQTT, in order",
                    lambda: (
                        listener.events(VEHICLE),
                        agent_events(agent),
                        agent.mqtt.connections,
                        len(agent.mqtt.outbox),
                    ),
                )
                await until(lambda: listener.states().get(1) == "F4.2", 5, "retained state after the restart")
                # every event of this run numbered 1, 2, 3... across the motors, whatever the broker did
                # (the listener's events() dropped repeats by (run_id, seq)); anything that came twice
                # was the very same event
                kept = listener.event_payloads(VEHICLE)
                assert [p["seq"] for p in kept] == list(range(1, len(agent.changes) + 1))
                assert {p["run_id"] for p in kept} == {agent.mqtt.run_id}
                by_seq = {p["seq"]: p for p in kept}
                assert all(p == by_seq[p["seq"]] for _, p in listener.on(f"{VEHICLE}/events"))

    try:
        asyncio.run(main())
    finally:
        listener.close()


def test_cli_agent_shuts_down_cleanly_on_sigterm(paper_motor, broker, tmp_path):
    listener = MqttListener(broker.port, f"mmh/{VEHICLE}/#", client_id="listener-cli")
    with VehiclePeer(paper_motor) as peer:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "mav_motor_health",
                "agent",
                "--connect",
                f"udpout:127.0.0.1:{peer.port}",
                "--mqtt",
                f"mqtt://127.0.0.1:{broker.port}",
                "--vehicle-id",
                VEHICLE,
                "--no-tui",
            ],
            stdout=subprocess.PIPE,
            stderr=(tmp_path / "agent.err").open("wb"),
            env={**os.environ, "PYTHONPATH": str(REPO / "src")},
        )
        try:
            wait_for(lambda: any(p.get("online") for _, p in listener.on("/status")), 30, "status online")
            wait_for(lambda: all_normal(listener), 30, "six motors NORMAL")
            proc.send_signal(signal.SIGTERM)
            out, _ = proc.communicate(timeout=15)
            err = (tmp_path / "agent.err").read_text()
            assert proc.returncode == 0, err
            wait_for(lambda: listener.on("/status")[-1][1]["online"] is False, 5, "status offline")
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            listener.close()
    assert "agent stopped" in err and "Traceback" not in err
    # one line per change of state when stdout is not a terminal
    assert b"NO_DATA -> NORMAL" in out
