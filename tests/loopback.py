"""Loopback ports for the servers the tests stop and start again (the Mosquitto brokers).

A server that a test stops and starts again on the same port must not listen on a port of the kernel's
ephemeral range: while it is down, any client connecting out of this machine (the agent reconnecting to
that very broker, a listener, pip) may be given that port as its own source port, and the restarted
server then fails to bind ("Address already in use"; a fresh-clone CI run lost
test_broker_restart_mid_flight_loses_no_state_change so). Ports below the range are never handed out
to outgoing connections.
"""

from __future__ import annotations

import itertools
import os
import socket
from pathlib import Path

#: the lowest port handed out (below: well-known and registered services' usual ports)
LOWEST_PORT = 20000
_calls = itertools.count()


def ephemeral_range() -> tuple[int, int]:
    """The kernel's range for outgoing connections' source ports (Linux's default where unreadable)."""
    try:
        low, high = (int(v) for v in Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split())
    except (OSError, ValueError):
        return 32768, 60999
    return low, high


def listen_port() -> int:
    """A TCP port on 127.0.0.1, free now and below the ephemeral range, different on every call of one
    test run (a deterministic walk from the process id, so two runs side by side start apart)."""
    low, _ = ephemeral_range()
    span = max(low - LOWEST_PORT, 1)
    start = (os.getpid() * 7919 + next(_calls) * 613) % span
    for i in range(span):
        port = LOWEST_PORT + (start + i) % span
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise RuntimeError(f"no free loopback TCP port in {LOWEST_PORT}..{low - 1}")
