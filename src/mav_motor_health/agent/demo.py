"""The agent against the simulated hexacopter in one process: ``mav-motor-health agent --sim``.

The simulated vehicle (:class:`mav_motor_health.sim.live.SimVehicle`) streams over a loopback UDP port
to the agent exactly as a flight controller would; a fault can be injected part-way (``F3.1@20:3``:
propeller damage at 20 s of simulated time on motor 3).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import time
from dataclasses import dataclass, replace
from typing import Any

from ..errors import ConfigError
from .app import run_agent
from .config import AgentConfig

__all__ = ["FaultPlan", "demo_summary", "parse_fault", "run_with_sim"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FaultPlan:
    kind: str
    at_s: float
    motor: int


def parse_fault(text: str) -> FaultPlan:
    """``F3.1@20:3`` → propeller damage at 20 s (simulated time) on motor 3."""
    kind, _, rest = text.partition("@")
    when, _, motor = rest.partition(":")
    try:
        plan = FaultPlan(kind.strip().upper(), float(when or 0.0), int(motor or 1))
    except ValueError:
        raise ConfigError(
            f"bad fault {text!r}", key="--fault", expected="FAULT@SECONDS:MOTOR, e.g. F3.1@20:3"
        ) from None
    if plan.kind not in ("F1.1", "F2.1", "F3.1", "F4.1", "F4.2") or not 1 <= plan.motor <= 12:
        raise ConfigError(
            f"bad fault {text!r}", key="--fault", expected="F1.1, F2.1, F3.1, F4.1 or F4.2 on motor 1-12"
        )
    return plan


def demo_summary(
    agent: Any,
    scenario: str,
    fault: FaultPlan | None,
    flown_s: float,
    injected_at_s: float | None = None,
) -> str:
    """What was injected, what the agent announced and how soon, and where to go from here.
    ``injected_at_s``: when the fault was injected, on the agent's clock (its link's, monotonic); None:
    taken as the fault's simulated time after the agent's first state, which is off by however far the
    simulation fell behind real time before the fault (a machine busy at the start)."""
    origin = agent.changes[0].time_s if agent.changes else 0.0  # the agent's clock at the first state
    onset = None if fault is None else (origin + fault.at_s if injected_at_s is None else injected_at_s)
    faults = [c for c in agent.changes if c.state.is_fault]
    lines = ["", f"demo finished: {flown_s:.0f} s of the simulated flight '{scenario}'"]
    if fault is None:
        lines.append("  injected: nothing (a healthy flight)")
    else:
        lines.append(f"  injected: {fault.kind} on motor {fault.motor} at {fault.at_s:g} s")
    found = None
    if fault is not None:
        found = next(
            (
                c
                for c in faults
                if c.motor == fault.motor and c.state.label == fault.kind and c.time_s - origin >= 0
            ),
            None,
        )
    if found is not None and fault is not None and onset is not None:
        delay = found.time_s - onset
        lines.append(
            f"  announced: motor {found.motor} {found.state.label} ({found.state.description}) "
            f"{delay:.2f} s after the injection"
        )
    elif fault is not None:
        lines.append(f"  announced: {fault.kind} on motor {fault.motor} was NOT announced")
    others = [c for c in faults if found is None or c is not found]
    lines.append(
        "  other fault announcements: "
        + (
            ", ".join(f"motor {c.motor} {c.state.label} at {c.time_s - origin:.1f} s" for c in others)
            or "none"
        )
    )
    lines += [
        "next:",
        "  replay a flight log:    mav-motor-health replay LOG.tlog|.bin|.ulg --out DIR  (then open report.html)",
        "  watch in a browser:     mav-motor-health display --broker-ws ws://HOST:9001  (the agent with --mqtt URL)",
        "  your own vehicle:       mav-motor-health fit FLIGHT.tlog --out vehicle.toml, then --params vehicle.toml",
        "",
    ]
    return "\n".join(lines)


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def run_with_sim(
    config: AgentConfig,
    scenario: str = "flight/healthy_calm",
    fault: FaultPlan | None = None,
    tui: bool | None = None,
    duration_s: float | None = None,
) -> int:
    """Start the simulated hexacopter on a loopback port, then the agent on it, until the scenario's
    flight ends (or SIGTERM/Ctrl-C, or ``duration_s``); then print what happened and what to do next."""
    from ..sim.live import SimVehicle
    from ..sim.scenario import load_scenario

    logging.getLogger("mav_motor_health.sim").setLevel(logging.WARNING)  # it logs every message it receives
    port = _free_udp_port()
    config = replace(config, connect=f"udpin:127.0.0.1:{port}")
    vehicle = SimVehicle(load_scenario(scenario), f"udpout:127.0.0.1:{port}")
    await asyncio.to_thread(vehicle.start)

    injected: dict[str, float] = {}

    async def inject_later() -> None:
        if fault is None:
            return
        while vehicle.sim_time_s < fault.at_s:
            await asyncio.sleep(0.05)
        injected["at_s"] = time.monotonic()  # the link's clock (agent/link.py), the same process's
        vehicle.inject(fault.kind, fault.motor)
        log.info("simulator: %s injected on motor %d at %.1f s", fault.kind, fault.motor, fault.at_s)

    end_s = load_scenario(scenario).duration_s

    def report(agent: Any) -> str:
        return demo_summary(agent, scenario, fault, vehicle.sim_time_s, injected.get("at_s"))

    injector = asyncio.ensure_future(inject_later())
    try:
        return await run_agent(
            config, tui=tui, duration_s=duration_s, until=lambda: vehicle.sim_time_s >= end_s, report=report
        )
    finally:
        injector.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await injector
        await asyncio.to_thread(vehicle.stop)
