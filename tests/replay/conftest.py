"""Fixtures for the replay tests: the real public logs in ../shared/real_logs (see its MANIFEST.md)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def sitl_tlog(real_logs: Path) -> Path:
    return real_logs / "ardupilot_sitl" / "hexa_motor1_half.tlog"


@pytest.fixture(scope="session")
def sitl_bin(real_logs: Path) -> Path:
    return real_logs / "ardupilot_sitl" / "hexa_motor1_half.bin"


@pytest.fixture(scope="session")
def px4_esc_ulg(real_logs: Path) -> Path:
    return real_logs / "px4" / "esc_status_log.ulg"


@pytest.fixture(scope="session")
def px4_no_esc_ulg(real_logs: Path) -> Path:
    return real_logs / "px4" / "quadrotor_local.ulg"
