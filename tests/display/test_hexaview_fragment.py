"""The hexacopter view as a report fragment: timelines from the real diagnosis, a slider in real Chromium."""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest

from mav_motor_health.diagnosis.pipeline import diagnose
from mav_motor_health.errors import DataError
from mav_motor_health.publish.web import HEXA_X, hexaview_fragment, state_timelines
from mav_motor_health.sim.steady import testbed_run as simulated_testbed_run
from mav_motor_health.telemetry.table import TelemetryTable

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def diagnosed_flight(paper_motor: Any, testbed_profile: Any) -> TelemetryTable:
    """Six motors on the simulated testbed at 7.6 V; motor 4's propeller is damaged at t = 10 s."""
    rng = np.random.default_rng(2021)
    runs = [
        TelemetryTable(simulated_testbed_run(paper_motor, "F3.1" if m == 4 else "NORMAL", 7.6, rng, motor=m))
        for m in range(1, 7)
    ]
    return diagnose(TelemetryTable.concat(runs), paper_motor, testbed_profile)


def test_state_timelines_are_the_change_points(diagnosed_flight: TelemetryTable) -> None:
    timelines = state_timelines(diagnosed_flight)
    assert sorted(timelines) == [1, 2, 3, 4, 5, 6]
    for m in (1, 2, 3, 5, 6):
        assert [label for _, label in timelines[m]] == ["NORMAL"], timelines[m]
    labels = [label for _, label in timelines[4]]
    assert labels[0] == "NORMAL" and labels[-1] == "F3.1", timelines[4]
    onset = next(t for t, label in timelines[4] if label == "F3.1")
    assert 10.0 < onset < 13.0
    # change points only: consecutive labels differ
    assert all(a[1] != b[1] for a, b in zip(timelines[4], timelines[4][1:]))


def test_state_timelines_do_not_depend_on_the_row_order(diagnosed_flight: TelemetryTable) -> None:
    # the diagnosis' result (grouped by motor, in time order) is read in one pass, any other order per motor
    shuffled = diagnosed_flight.select(np.random.default_rng(3).permutation(len(diagnosed_flight)))
    assert state_timelines(shuffled) == state_timelines(diagnosed_flight)
    assert list(state_timelines(shuffled)) == list(state_timelines(diagnosed_flight)) == [1, 2, 3, 4, 5, 6]


def test_state_timelines_needs_the_state_column() -> None:
    table = TelemetryTable.from_columns(time_s=[0.0], motor=[1], omega_rad_s=[1.0], current_a=[1.0])
    with pytest.raises(DataError, match="announced"):
        state_timelines(table)


def test_fragment_is_self_contained_and_script_safe() -> None:
    html = hexaview_fragment({1: [(0.0, "NORMAL")]}, title="a </script><b>", element_id="x1")
    assert (
        "<script src" not in html
        and "<link" not in html
        and "http" not in html.replace("http://www.w3.org", "")
    )
    assert "&lt;/script&gt;&lt;b&gt;" in html  # the title is escaped
    assert "MmhHexaView" in html and "mmh-hv-disc" in html  # the view's JS and CSS are inlined
    with pytest.raises(ValueError, match="unknown motor state"):
        hexaview_fragment({1: [(0.0, "F9.9")]})
    with pytest.raises(ValueError, match="element_id"):
        hexaview_fragment({1: [(0.0, "NORMAL")]}, element_id='x"><script>')


def fill_of(page: Any, motor: int) -> str:
    return page.eval_on_selector(
        f'.mmh-replay .mmh-hv-motor[data-motor="{motor}"] .mmh-hv-disc', "e => getComputedStyle(e).fill"
    )


def test_slider_moves_through_the_flight_and_motor_4_turns_red(
    page: Any, diagnosed_flight: TelemetryTable
) -> None:
    timelines = state_timelines(diagnosed_flight)
    t0, t1 = float(diagnosed_flight["time_s"].min()), float(diagnosed_flight["time_s"].max())
    fragment = hexaview_fragment(timelines, t_start_s=t0, t_end_s=t1, layout=HEXA_X)
    page.set_content(f"<!doctype html><html><body>{fragment}</body></html>")
    motor4 = page.locator('.mmh-replay .mmh-hv-motor[data-motor="4"]')
    assert motor4.get_attribute("data-state") == "NORMAL"
    healthy = fill_of(page, 4)

    # drag the slider as a user would: press on its knob at the left, release near the right end
    slider = page.locator(".mmh-replay-slider").bounding_box()
    y = slider["y"] + slider["height"] / 2
    page.mouse.move(slider["x"] + 4, y)
    page.mouse.down()
    page.mouse.move(slider["x"] + slider["width"] * 0.95, y, steps=8)
    page.mouse.up()
    assert motor4.get_attribute("data-state") == "F3.1"
    faulty = fill_of(page, 4)
    assert faulty != healthy
    r, g, b = (int(x) for x in re.findall(r"\d+", faulty)[:3])
    assert r > 150 and g < 90 and b < 90
    assert "F3.1" in motor4.text_content()
    time_shown = float(page.locator(".mmh-replay").get_attribute("data-time"))
    assert time_shown > 15.0
    item = page.locator('.mmh-replay-motors li[data-motor="4"]').inner_text()
    assert "propeller damage" in item and "since t = 1" in item
    assert page.locator('.mmh-replay .mmh-hv-motor[data-motor="1"]').get_attribute("data-state") == "NORMAL"

    # keyboard works too, and the buttons jump between changes
    page.locator(".mmh-replay-slider").press("Home")
    assert motor4.get_attribute("data-state") == "NORMAL"
    page.click(".mmh-replay-next")
    onset = next(t for t, label in timelines[4] if label == "F3.1")
    changes = sorted(t for rows in timelines.values() for t, _ in rows if t > t0)
    assert float(page.locator(".mmh-replay").get_attribute("data-time")) == pytest.approx(
        changes[0], abs=1e-3
    )
    while float(page.locator(".mmh-replay").get_attribute("data-time")) < onset - 1e-3:
        page.click(".mmh-replay-next")
    assert motor4.get_attribute("data-state") == "F3.1"


def test_two_fragments_on_one_page_are_independent(page: Any) -> None:
    a = hexaview_fragment({2: [(0.0, "NORMAL"), (5.0, "F1.1")]}, t_start_s=0, t_end_s=10, element_id="ra")
    b = hexaview_fragment({2: [(0.0, "NORMAL")]}, t_start_s=0, t_end_s=10, element_id="rb", initial_t_s=9)
    page.set_content(f"<!doctype html><html><body>{a}{b}</body></html>")
    page.locator("#ra .mmh-replay-slider").press("End")
    assert page.locator('#ra .mmh-hv-motor[data-motor="2"]').get_attribute("data-state") == "F1.1"
    assert page.locator('#rb .mmh-hv-motor[data-motor="2"]').get_attribute("data-state") == "NORMAL"
    # before its first sample a motor has no data yet
    assert page.locator('#rb .mmh-hv-motor[data-motor="5"]').get_attribute("data-kind") == "waiting"
