"""``mav-motor-health display``: serve the ground-station health page (docs/display.md).

The page subscribes to the agent's MQTT topics through the broker's WebSocket listener; this command only
serves the page and its configuration. It never publishes and never holds broker credentials.
"""

from __future__ import annotations

import argparse

from ..publish.web import DisplayConfig, DisplayServer
from ._common import port_or_zero


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "display",
        help="serve the live motor-health page (MQTT over WebSocket, read-only)",
        description="Serve the live motor-health page. Browsers connect to the MQTT broker's WebSocket "
        "listener themselves; broker credentials are never part of the served files.",
    )
    p.add_argument(
        "--broker-ws",
        metavar="URL",
        default=None,
        help="broker WebSocket URL the page connects to, e.g. wss://broker.example:8081 "
        "(default: ws://<host the page was loaded from>:9001)",
    )
    p.add_argument(
        "--port", type=port_or_zero, default=8080, help="HTTP port (default 8080; 0 picks a free one)"
    )
    p.add_argument(
        "--bind",
        default="127.0.0.1",
        metavar="ADDR",
        help="address to listen on (default 127.0.0.1; 0.0.0.0 to serve other machines)",
    )
    p.add_argument("--prefix", default="mmh", help="MQTT topic prefix (default mmh)")
    p.add_argument(
        "--stale-after",
        type=float,
        default=10.0,
        metavar="S",
        help="show 'no data' for a vehicle or motor silent this many seconds (default 10)",
    )
    p.add_argument(
        "--ask-credentials",
        action="store_true",
        help="ask each viewer for a broker user name and password before connecting",
    )
    p.add_argument(
        "--keepalive",
        type=int,
        default=20,
        metavar="S",
        help="MQTT keep-alive of the page's connection in seconds (default 20)",
    )
    p.set_defaults(run=run)


def config_from_args(args: argparse.Namespace) -> DisplayConfig:
    return DisplayConfig(
        broker_ws_url=args.broker_ws,
        topic_prefix=args.prefix,
        stale_after_s=args.stale_after,
        ask_credentials=args.ask_credentials,
        keepalive_s=args.keepalive,
    )


def run(args: argparse.Namespace) -> int:
    server = DisplayServer(config_from_args(args), host=args.bind, port=args.port)
    broker = args.broker_ws or "ws://<this host>:9001"
    print(
        f"motor-health display on {server.url} (broker {broker}, topics {args.prefix}/#); Ctrl-C stops",
        flush=True,
    )
    server.serve_forever()
    return 0
