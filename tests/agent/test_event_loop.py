"""Nothing the agent does blocks its event loop: not a dead broker, not a dead MAVLink peer, not 6 × 50 Hz."""

from __future__ import annotations

import asyncio
import socket
import time

from agent_parts import free_port
from vehicle_peer import VehiclePeer

from mav_motor_health.agent import Agent, load_agent_config


async def max_loop_lag(seconds: float, period_s: float = 0.01) -> float:
    """The longest the loop was late for a 10 ms timer during ``seconds``."""
    worst = 0.0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        before = time.monotonic()
        await asyncio.sleep(period_s)
        worst = max(worst, time.monotonic() - before - period_s)
    return worst


def test_loop_stays_responsive_with_a_silent_broker_and_a_dead_tcp_peer(paper_motor):
    # a "broker" that accepts TCP connections and never answers (CONNACK never comes)
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(16)
    dead_tcp = free_port()  # nothing listens here: every connect is refused

    async def main() -> tuple[float, float]:
        with VehiclePeer(paper_motor) as peer:
            cfg = load_agent_config(
                None,
                connect=f"udpout:127.0.0.1:{peer.port}",
                mqtt_url=f"mqtt://127.0.0.1:{silent.getsockname()[1]}",
            )
            async with Agent(cfg) as agent:
                while agent.monitor.samples < 300:  # streaming at 6 x 50 Hz
                    await asyncio.sleep(0.05)
                lag_live = await max_loop_lag(1.5)
                assert not agent.mqtt.connected.is_set()
            cfg2 = load_agent_config(None, connect=f"tcp:127.0.0.1:{dead_tcp}")
            async with Agent(cfg2):
                lag_dead = await max_loop_lag(1.0)
        return lag_live, lag_dead

    try:
        lag_live, lag_dead = asyncio.run(main())
    finally:
        silent.close()
    # generous bounds for a shared CI machine; a blocking connect or read would take seconds
    assert lag_live < 0.5, f"event loop late by {lag_live:.3f} s while streaming with a silent broker"
    assert lag_dead < 0.5, f"event loop late by {lag_dead:.3f} s with a refused TCP link"
