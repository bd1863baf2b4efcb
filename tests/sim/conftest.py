"""Fixtures for the simulator tests: the committed sitl_logs folder."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def sitl_logs() -> Path:
    folder = REPO / "sitl_logs"
    if not (folder / "MANIFEST.md").exists():
        pytest.fail(f"the committed simulated logs are missing: expected {folder}/MANIFEST.md")
    return folder
