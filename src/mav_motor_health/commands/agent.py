"""``mav-motor-health agent --connect URL``: the live agent beside the autopilot."""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys
from pathlib import Path

from ..agent.app import run_agent
from ..agent.config import load_agent_config
from ..agent.demo import parse_fault, run_with_sim
from ..errors import ConfigError, DataError
from ._common import positive_float


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "agent",
        help="watch the motors live over MAVLink; publish health over MAVLink and MQTT",
        description="Runs beside the autopilot (companion computer): reads ESC telemetry over MAVLink, "
        "diagnoses every motor sample and announces changes as STATUSTEXT, NAMED_VALUE_*, MOTOR_HEALTH "
        "and MQTT. Options override the --config file.",
    )
    p.add_argument("--config", metavar="FILE", help="agent TOML (see params/agent.example.toml)")
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--connect",
        metavar="URL",
        help="MAVLink: /dev/serial0:921600, udpin:0.0.0.0:14550, udpout:HOST:PORT, tcp:HOST:PORT or a .tlog",
    )
    where.add_argument(
        "--sim",
        nargs="?",
        const="flight/healthy_calm",
        metavar="SCENARIO",
        help="run against the simulated hexacopter in this process (default scenario flight/healthy_calm)",
    )
    p.add_argument(
        "--fault", metavar="F@T:M", help="with --sim: inject e.g. F3.1@20:3 (fault at 20 s on motor 3)"
    )
    p.add_argument(
        "--duration",
        type=positive_float,
        metavar="S",
        help="stop after S seconds (default: run until SIGTERM)",
    )
    p.add_argument("--mqtt", metavar="URL", help="broker: mqtt://[user:pass@]host[:port] or mqtts://...")
    p.add_argument("--params", metavar="FILE", help="motor parameters TOML or a name in params/motors")
    p.add_argument("--profile", metavar="P", help="threshold profile: testbed, flight or a TOML file")
    p.add_argument("--vehicle-id", metavar="ID", help="vehicle id for the MQTT topics")
    view = p.add_mutually_exclusive_group()
    view.add_argument(
        "--tui", action="store_true", default=None, help="redraw a live table (default on a tty)"
    )
    view.add_argument("--no-tui", dest="tui", action="store_false", help="one line per change of state")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    p.set_defaults(run=run)


def setup_logging(verbose: bool) -> None:
    """Logs to stderr; without timestamps under systemd (journald adds its own)."""
    under_systemd = "JOURNAL_STREAM" in os.environ or "INVOCATION_ID" in os.environ
    fmt = (
        "%(levelname)s %(name)s: %(message)s"
        if under_systemd
        else "%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.INFO, format=fmt, stream=sys.stderr, force=True
    )


def run(args: argparse.Namespace) -> int:
    if args.fault and not args.sim:
        raise ConfigError("--fault needs --sim", key="--fault", expected="--sim [SCENARIO] --fault F3.1@20:3")
    config = load_agent_config(
        args.config,
        connect=args.connect or ("udpin:127.0.0.1:14550" if args.sim else None),
        mqtt_url=args.mqtt,
        params=args.params,
        profile=args.profile,
        vehicle_id=args.vehicle_id,
    )
    if config.connect.lower().endswith(".tlog"):  # replay through the live path: the file must hold data
        log = Path(config.connect)
        if not log.is_file():
            raise DataError("file not found" if not log.exists() else "is not a file", path=log)
        if log.stat().st_size == 0:
            raise DataError("empty file: no MAVLink messages to replay", path=log)
    setup_logging(args.verbose)
    live_view = sys.stdout.isatty() if args.tui is None else args.tui
    if live_view and sys.stderr.isatty() and not args.verbose:
        logging.getLogger().setLevel(logging.ERROR)  # the table shows the states; log lines would scroll it
    if args.sim:
        fault = parse_fault(args.fault) if args.fault else None
        return asyncio.run(run_with_sim(config, args.sim, fault, tui=args.tui, duration_s=args.duration))
    return asyncio.run(run_agent(config, tui=args.tui, duration_s=args.duration))
