"""Shared fixtures: the paper's motor, the profiles, paths to the real logs."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.diagnosis.profile import ThresholdProfile
from mav_motor_health.model.params import MotorParams

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))  # shared helpers (loopback.py) for every folder
#: ``shared/real_logs`` beside the clone (CI), or beside any folder above it (a git worktree)
SHARED_LOGS = next(
    (p / "shared" / "real_logs" for p in REPO.parents if (p / "shared" / "real_logs").is_dir()),
    REPO.parent / "shared" / "real_logs",
)


@pytest.fixture(scope="session")
def paper_motor() -> MotorParams:
    return load_motor_params("paper_x2212")


@pytest.fixture(scope="session")
def testbed_profile() -> ThresholdProfile:
    return load_profile("testbed")


@pytest.fixture(scope="session")
def real_logs() -> Path:
    if not SHARED_LOGS.is_dir():
        pytest.fail(f"the shared real logs are missing: expected them at {SHARED_LOGS}")
    return SHARED_LOGS
