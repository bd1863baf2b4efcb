"""``mav-motor-health sim --connect URL``: a live simulated ArduPilot hexacopter on a MAVLink link.

``--world SEED`` flies a randomised world's vehicle (:mod:`..sim.worlds`); without ``--scenario`` it flies
the world's own manoeuvre plan, then hovers."""

from __future__ import annotations

import argparse
import dataclasses
import logging
import time

from ..agent.demo import parse_fault
from ..errors import ConfigError
from ..sim.live import FAULT_CODES, SimVehicle
from ..sim.scenario import WORLD_SCENARIO_NAMES, load_scenario, world_scenario
from ..sim.worlds import draw_world
from ._common import non_negative_int, positive_float, socket_url


def add_parser(sub: argparse._SubParsersAction) -> None:
    codes = ", ".join(f"{k} {v}" for k, v in FAULT_CODES.items())
    p = sub.add_parser(
        "sim",
        help="run a live simulated hexacopter on a MAVLink link (UDP or TCP)",
        description="A MAVLink vehicle (ArduPilot hexacopter) whose motors obey the paper's physics. "
        f"Inject faults with PARAM_SET SIM_MOT_FAULT ({codes}; 0 clears), SIM_MOT_FLT_NUM (motor) and "
        "SIM_MOT_FLT_SEV (severity 0-1), or COMMAND_LONG 31010 (MAV_CMD_USER_1: fault, motor, severity).",
    )
    p.add_argument(
        "--connect",
        required=True,
        type=socket_url,
        metavar="URL",
        help="udpout:HOST:PORT, udpin:..., tcpin:..., tcp:...",
    )
    p.add_argument(
        "--scenario",
        default=None,
        help="flight scenario (default flight/healthy_calm; with --world the world's own plan)",
    )
    p.add_argument(
        "--world",
        type=non_negative_int,
        default=None,
        metavar="SEED",
        help="fly the randomised world of SEED (its vehicle, motors, ESCs, telemetry)",
    )
    p.add_argument(
        "--speed", type=positive_float, default=1.0, help="simulated seconds per real second (default 1)"
    )
    p.add_argument(
        "--duration", type=positive_float, default=None, metavar="S", help="stop after S real seconds"
    )
    p.add_argument(
        "--fault",
        default=None,
        metavar="F@T:M",
        help="inject e.g. F2.1@30:3 (fault at sim time 30 s on motor 3)",
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    if args.world is not None and (args.scenario is None or args.scenario in WORLD_SCENARIO_NAMES):
        scenario = world_scenario(args.world)
    elif args.scenario in WORLD_SCENARIO_NAMES:
        raise ConfigError(
            f"scenario {args.scenario!r} flies a randomised world", key="--world", expected="--world SEED"
        )
    else:
        scenario = load_scenario(args.scenario or "flight/healthy_calm")
        if args.world is not None:
            scenario = dataclasses.replace(scenario, world=args.world)
    if scenario.world is not None:
        print(draw_world(scenario.world).report(), flush=True)
    fault_at = None
    if args.fault:
        plan = parse_fault(args.fault)
        fault_at = (plan.kind, plan.at_s, plan.motor)
    started = time.monotonic()
    with SimVehicle(scenario, args.connect, speed=args.speed) as vehicle:
        print(f"simulated hexacopter on {args.connect} (speed x{args.speed}); Ctrl-C to stop", flush=True)
        while args.duration is None or time.monotonic() - started < args.duration:
            time.sleep(0.2)
            if fault_at and vehicle.sim_time_s >= fault_at[1]:
                vehicle.inject(fault_at[0], fault_at[2])
                fault_at = None
            if not vehicle.running:
                return 1
    return 0
