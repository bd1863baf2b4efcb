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


@pytest.fixture(scope="session")
def real_logs() -> Path:
    """The shared real logs: ``shared/real_logs`` next to the repository or next to a worktree folder."""
    for parent in REPO.parents:
        candidate = parent / "shared" / "real_logs"
        if candidate.is_dir():
            return candidate
    pytest.fail(f"the shared real logs are missing: looked for shared/real_logs above {REPO}")
