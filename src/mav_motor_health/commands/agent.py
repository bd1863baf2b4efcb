"""``mav-motor-health agent --connect URL``: the live agent beside the autopilot."""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys

from ..agent.app import run_agent
from ..agent.config import load_agent_config


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "agent",
        help="watch the motors live over MAVLink; publish health over MAVLink and MQTT",
        description="Runs beside the autopilot (companion computer): reads ESC telemetry over MAVLink, "
        "diagnoses every motor sample and announces changes as STATUSTEXT, NAMED_VALUE_*, MOTOR_HEALTH "
        "and MQTT. Options override the --config file.",
    )
    p.add_argument("--config", metavar="FILE", help="agent TOML (see params/agent.example.toml)")
    p.add_argument(
        "--connect",
        metavar="URL",
        help="MAVLink: /dev/serial0:921600, udpin:0.0.0.0:14550, udpout:HOST:PORT, tcp:HOST:PORT or a .tlog",
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
    config = load_agent_config(
        args.config,
        connect=args.connect,
        mqtt_url=args.mqtt,
        params=args.params,
        profile=args.profile,
        vehicle_id=args.vehicle_id,
    )
    setup_logging(args.verbose)
    return asyncio.run(run_agent(config, tui=args.tui))
