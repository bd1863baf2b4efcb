"""The replay report carries the display's hexacopter view with a time slider (real replay, real Chromium)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mav_motor_health.publish.web.layout import layout_for_log
from mav_motor_health.replay import replay_log
from mav_motor_health.sim.steady import testbed_run as simulated_testbed_run
from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.csv import write_csv
from mav_motor_health.telemetry.table import TelemetryTable

pytestmark = pytest.mark.timeout(90)


def rgb(css: str) -> tuple[int, ...]:
    return tuple(int(x) for x in re.findall(r"\d+", css)[:3])


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory, paper_motor: Any, testbed_profile: Any) -> Path:
    """A CSV log of six motors on the simulated testbed, motor 4's propeller damaged at 10 s, replayed."""
    work = tmp_path_factory.mktemp("replay")
    rng = np.random.default_rng(7)
    runs = [
        TelemetryTable(simulated_testbed_run(paper_motor, "F3.1" if m == 4 else "NORMAL", 9.2, rng, motor=m))
        for m in range(1, 7)
    ]
    log = write_csv(TelemetryTable.concat(runs), work / "bench_flight.csv")
    replay_log(log, work / "out", paper_motor, testbed_profile, reissue_warnings=False)
    return work / "out" / "report.html"


def test_report_slider_changes_motor_4_colour(page: Any, report: Path) -> None:
    page.goto(report.as_uri())
    view = page.locator(".mmh-replay")
    assert view.count() == 1
    assert "drawn as ArduPilot hexa-X" in page.locator(".mmh-replay-note").inner_text()
    motor4 = view.locator('.mmh-hv-motor[data-motor="4"]')
    disc4 = '.mmh-replay .mmh-hv-motor[data-motor="4"] .mmh-hv-disc'
    # the slider opens at the first fault: motor 4 is already red there
    assert motor4.get_attribute("data-state") == "F3.1"
    onset = float(view.get_attribute("data-time"))
    assert 10.0 < onset < 13.0

    page.locator(".mmh-replay-slider").press("Home")
    assert motor4.get_attribute("data-state") == "NORMAL"
    green = rgb(page.eval_on_selector(disc4, "e => getComputedStyle(e).fill"))
    assert green[1] > 100 and green[0] < 100

    box = page.locator(".mmh-replay-slider").bounding_box()
    y = box["y"] + box["height"] / 2
    page.mouse.move(box["x"] + 4, y)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] * 0.9, y, steps=6)
    page.mouse.up()
    assert motor4.get_attribute("data-state") == "F3.1"
    red = rgb(page.eval_on_selector(disc4, "e => getComputedStyle(e).fill"))
    assert red != green and red[0] > 150 and red[1] < 90
    assert "F3.1" in motor4.text_content()
    for m in (1, 2, 3, 5, 6):
        assert view.locator(f'.mmh-hv-motor[data-motor="{m}"]').get_attribute("data-state") == "NORMAL"


def test_report_view_is_drawn_on_the_logs_own_frame(real_logs: Path) -> None:
    """ArduPilot SITL's --model hexa flies hexa-plus (FRAME_TYPE 0): the view must not draw it as X."""
    table = sources.read(real_logs / "ardupilot_sitl" / "hexa_motor1_half.bin")
    assert layout_for_log(table.meta, table.motors()) == ("hexa-plus", "")
    assert layout_for_log({}, [1, 2, 3, 4, 5, 6])[0] == "hexa-x"
    assert layout_for_log({"params": {"FRAME_CLASS": 3, "FRAME_TYPE": 1}}, list(range(1, 9)))[0] is None


def test_report_view_png(page: Any, report: Path, tmp_path: Path) -> None:
    """The picture in docs/display.md: the replayed simulated flight's report, its top view at the end."""
    import os

    page.set_viewport_size({"width": 1000, "height": 900})
    page.goto(report.as_uri())
    page.locator(".mmh-replay-slider").press("End")
    assert page.locator('.mmh-replay .mmh-hv-motor[data-motor="4"]').get_attribute("data-state") == "F3.1"
    out = Path(os.environ.get("MMH_REPLAY_PNG", tmp_path / "display-replay.png"))
    page.locator(".mmh-replay-section").screenshot(path=str(out))
    assert out.stat().st_size > 10_000
