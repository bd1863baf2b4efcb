"""The screenshot in docs/display.png, taken from a scene published as the agent would.

    MMH_DISPLAY_PNG=docs/display.png PYTHONPATH=src /tmp/venv0/bin/python -m pytest tests/display -k screenshot

Without MMH_DISPLAY_PNG the test still renders the scene and checks it, into a temporary file.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.timeout(60)


def publish_scene(agent_like: Any, make_publisher: Any) -> None:
    """Two hexacopters; on the first, motor 4 lost part of a blade (F3.1) 18 s ago."""
    first = agent_like("hexa-01", seed=7)
    second = agent_like("hexa-02", seed=8, pub=make_publisher("agent-hexa-02"))
    for v in (first, second):
        v.announce()
        for m in range(1, 7):
            v.state(m, "NORMAL", since_s_ago=600)
    fault_at = 42.0
    for k in range(300):  # 60 s of vehicle time at 5 Hz
        t = 0.2 * k
        if t >= fault_at and 4 not in first.faults:
            first.faults[4] = "F3.1"
        first.tick(t)
        second.tick(t)
    first.state(4, "F3.1", since_s_ago=60.0 - fault_at)
    first.event(4, "F3.1", "NORMAL", t_s=fault_at + 0.6, ago_s=60.0 - fault_at - 0.6)


def test_screenshot(
    page: Any, display: Any, agent_like: Any, make_publisher: Any, open_display: Any, tmp_path: Path
) -> None:
    server = display(stale_after_s=30.0)
    open_display(page, server)
    publish_scene(agent_like, make_publisher)
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="4"][data-state="F3.1"]')
    page.wait_for_selector('#vehicle-picker button[data-vehicle="hexa-02"]')
    page.wait_for_timeout(500)  # one more render tick for the charts
    out = Path(os.environ.get("MMH_DISPLAY_PNG", tmp_path / "display.png"))
    page.screenshot(path=str(out), full_page=True)
    assert out.stat().st_size > 20_000
    assert "F3.1" in page.locator('.motor-card[data-motor="4"]').inner_text()
