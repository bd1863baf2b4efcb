"""Fixtures for the agent's tests: a real Mosquitto broker and MAVProxy, started and stopped per test."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the helpers next to this file

from agent_parts import MAVPROXY, MOSQUITTO, Broker, MavproxyGcs, MavproxyRouter


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    if not os.path.exists(MOSQUITTO):
        pytest.fail(f"mosquitto is not installed at {MOSQUITTO} (Debian package mosquitto)")
    folder = tmp_path / "broker"
    folder.mkdir(exist_ok=True)
    b = Broker(folder)
    b.start()
    yield b
    b.stop()


@pytest.fixture
def mavproxy(tmp_path: Path) -> Iterator[MavproxyGcs]:
    if not os.path.exists(MAVPROXY):
        pytest.fail(f"MAVProxy is not installed at {MAVPROXY}")
    gcs = MavproxyGcs(tmp_path)
    yield gcs
    gcs.close()


@pytest.fixture
def mavproxy_router(tmp_path: Path) -> Iterator[MavproxyRouter]:
    if not os.path.exists(MAVPROXY):
        pytest.fail(f"MAVProxy is not installed at {MAVPROXY}")
    router = MavproxyRouter(tmp_path)
    yield router
    router.close()
