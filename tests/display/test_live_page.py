"""The live page in headless Chromium, fed through a real mosquitto WebSocket listener by a real MQTT
client publishing the agent's topic tree (MQTT.md)."""

from __future__ import annotations

import re
import threading
import time
from typing import Any

import pytest

pytestmark = pytest.mark.timeout(60)


def disc(page: Any, motor: int) -> Any:
    return page.locator(f'#hexaview .mmh-hv-motor[data-motor="{motor}"]')


def fill_rgb(page: Any, motor: int) -> tuple[int, int, int]:
    """The colour Chromium actually paints the motor's disc with."""
    css = page.eval_on_selector(
        f'#hexaview .mmh-hv-motor[data-motor="{motor}"] .mmh-hv-disc', "e => getComputedStyle(e).fill"
    )
    r, g, b = (int(x) for x in re.findall(r"\d+", css)[:3])
    return r, g, b


def is_red(rgb: tuple[int, int, int]) -> bool:
    r, g, b = rgb
    return r > 150 and g < 90 and b < 90


def is_green(rgb: tuple[int, int, int]) -> bool:
    r, g, b = rgb
    return g > 100 and r < 100 and b < 100


def is_grey(rgb: tuple[int, int, int]) -> bool:
    return max(rgb) - min(rgb) < 20 and 100 < rgb[0] < 220


def healthy_vehicle(agent: Any, t_s: float = 10.0) -> None:
    agent.announce()
    for m in range(1, 7):
        agent.state(m, "NORMAL", since_s_ago=60)
    for k in range(5):
        agent.tick(t_s + 0.2 * k)


def test_motor_4_fault_changes_colour_and_is_named(
    page: Any, display: Any, agent_like: Any, open_display: Any
) -> None:
    server = display()
    open_display(page, server)
    uav = agent_like("uav1")
    healthy_vehicle(uav)
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="4"][data-kind="ok"]')
    before = fill_rgb(page, 4)
    assert is_green(before), before
    assert "F3.1" not in disc(page, 4).text_content()

    uav.faults[4] = "F3.1"
    uav.state(4, "F3.1", since_s_ago=3)
    uav.event(4, "F3.1", "NORMAL", t_s=11.2)
    uav.tick(11.4)
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="4"][data-state="F3.1"]')

    after = fill_rgb(page, 4)
    assert after != before and is_red(after), (before, after)
    assert "F3.1" in disc(page, 4).text_content()
    assert re.search(r"for [34] s", disc(page, 4).text_content()), disc(page, 4).text_content()
    card = page.locator('.motor-card[data-motor="4"]')
    assert "propeller damage" in card.inner_text()
    assert "since" in card.inner_text()
    # the event comes on its own MQTT topic, not necessarily before the state the page waited for
    page.wait_for_function(
        "() => document.querySelector('#event-log').innerText.includes('NORMAL → F3.1')", timeout=10_000
    )
    assert "NORMAL → F3.1" in page.locator("#event-log").inner_text()
    assert page.title().startswith("FAULT uav1")
    # one vehicle: no picker, its name in the bar instead
    page.wait_for_timeout(300)
    assert page.locator('#vehicle-picker button[data-vehicle="uav1"]').count() == 1
    assert page.locator("#vehicle-picker").is_hidden()
    assert page.locator("#vehicle-name").inner_text() == "uav1"
    # the other five stay green
    for m in (1, 2, 3, 5, 6):
        assert is_green(fill_rgb(page, m)), m
    # and the charts got the samples (measured and model lines drawn: some non-white pixels)
    painted = page.eval_on_selector(
        '.motor-card[data-motor="4"] canvas.chart-speed',
        """c => { const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
                  let n = 0; for (let i = 0; i < d.length; i += 4) { if (d[i + 3] > 0 && d[i + 2] > 150 && d[i] < 60) n++; }
                  return n; }""",
    )
    assert painted > 20


def test_event_log_shows_an_event_delivered_twice_once(
    page: Any, display: Any, agent_like: Any, open_display: Any
) -> None:
    """QoS 1 may deliver an event twice (same run_id and seq): the log shows it once. A restarted agent
    (new run_id, seq from 1 again) is news, not a repeat."""
    server = display()
    open_display(page, server)
    uav = agent_like("twice")
    healthy_vehicle(uav)
    first = uav.event(4, "F3.1", "NORMAL", t_s=11.2)
    uav.pub.publish(f"{uav.base}/events", first, qos=1)  # the same event again, as after a broker restart
    uav.event(4, "NORMAL", "F3.1", t_s=12.0)
    uav.run_id, uav.seq = "run-twice-restarted", 0
    uav.event(2, "F1.1", "NORMAL", t_s=0.5)
    rows = page.locator("#event-log tbody tr")
    page.wait_for_function("() => document.querySelectorAll('#event-log tbody tr').length >= 3")
    page.wait_for_timeout(300)  # a fourth row would be drawn by now
    assert rows.count() == 3, page.locator("#event-log").inner_text()
    log = page.locator("#event-log").inner_text()
    assert log.count("NORMAL → F3.1") == 1 and "F3.1 → NORMAL" in log and "NORMAL → F1.1" in log


def test_retained_state_reaches_a_late_viewer(
    page: Any, display: Any, agent_like: Any, open_display: Any
) -> None:
    uav = agent_like("late")
    uav.announce()
    for m in range(1, 7):
        uav.state(m, "F1.1" if m == 2 else "NORMAL", since_s_ago=125)
    server = display()
    open_display(page, server)
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="2"][data-state="F1.1"]')
    assert is_red(fill_rgb(page, 2))
    assert "2 min 05 s" in disc(page, 2).text_content() or "2 min 06 s" in disc(page, 2).text_content()
    assert "bearing friction" in page.locator('.motor-card[data-motor="2"]').inner_text()


def test_two_vehicles_publishing_at_once(
    page: Any, display: Any, agent_like: Any, make_publisher: Any, open_display: Any
) -> None:
    server = display()
    open_display(page, server)
    second = make_publisher("test-agent-b")
    a = agent_like("alpha", seed=1)
    b = agent_like("bravo", seed=2, pub=second)
    healthy_vehicle(a)
    healthy_vehicle(b)
    b.faults[2] = "F4.1"
    b.state(2, "F4.1", since_s_ago=1)
    stop = threading.Event()

    def fly(agent: Any) -> None:
        t = 12.0
        while not stop.is_set():
            agent.tick(t)
            t += 0.2
            time.sleep(0.2)

    threads = [threading.Thread(target=fly, args=(v,), daemon=True) for v in (a, b)]
    for th in threads:
        th.start()
    try:
        picker = page.locator("#vehicle-picker")
        page.wait_for_selector('#vehicle-picker button[data-vehicle="bravo"]')
        assert picker.is_visible()
        assert picker.locator("button").all_inner_texts() == ["alpha", "bravo"]
        # the picker flags the vehicle with a fault without selecting it
        page.wait_for_selector('#vehicle-picker button[data-vehicle="bravo"].kind-fault')
        page.wait_for_selector('#vehicle-picker button[data-vehicle="alpha"].kind-ok')

        page.click('#vehicle-picker button[data-vehicle="bravo"]')
        page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="2"][data-state="F4.1"]')
        assert is_red(fill_rgb(page, 2))
        assert "transistor open" in page.locator('.motor-card[data-motor="2"]').inner_text()
        assert page.locator("#vehicle-summary").inner_text().startswith("bravo")

        page.click('#vehicle-picker button[data-vehicle="alpha"]')
        page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="2"][data-state="NORMAL"]')
        assert is_green(fill_rgb(page, 2))
        assert page.locator("#vehicle-summary").inner_text().startswith("alpha")
    finally:
        stop.set()
        for th in threads:
            th.join()


def test_silent_vehicle_shows_no_data(page: Any, display: Any, agent_like: Any, open_display: Any) -> None:
    server = display(stale_after_s=1.5)
    open_display(page, server)
    uav = agent_like("quiet")
    healthy_vehicle(uav)
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="1"][data-kind="ok"]')
    overlay = page.locator("#hexaview .mmh-hv-overlay")
    assert overlay.get_attribute("visibility") == "hidden"
    # nothing more is published: after 1.5 s the page must say so
    page.wait_for_selector('#hexaview .mmh-hv-overlay[visibility="visible"]', timeout=6000)
    assert "NO DATA" in overlay.text_content()
    assert "silent" in overlay.text_content()
    for m in range(1, 7):
        assert is_grey(fill_rgb(page, m)), m
    assert "NO DATA" in page.locator('.motor-card[data-motor="3"]').inner_text()

    # it talks again: live; then its agent's last will says offline
    uav.tick(20.0)
    page.wait_for_selector('#hexaview .mmh-hv-overlay[visibility="hidden"]', state="attached")
    assert is_green(fill_rgb(page, 1))
    uav.offline()
    page.wait_for_selector('#hexaview .mmh-hv-overlay[visibility="visible"]')
    assert "offline" in overlay.text_content()


def test_silent_motor_and_no_data_state(page: Any, display: Any, agent_like: Any, open_display: Any) -> None:
    server = display(stale_after_s=1.5)
    open_display(page, server)
    uav = agent_like("partial")
    healthy_vehicle(uav)
    uav.state(6, "NO_DATA", since_s_ago=2)
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="6"][data-state="NO_DATA"]')
    assert is_grey(fill_rgb(page, 6))
    assert "NO DATA" in disc(page, 6).text_content()
    # motor 5's telemetry stops while the others keep talking
    deadline = time.monotonic() + 3.0
    t = 20.0
    while time.monotonic() < deadline:
        uav.tick(t, motors=(1, 2, 3, 4))
        t += 0.2
        time.sleep(0.2)
    assert disc(page, 5).get_attribute("data-kind") == "nodata"
    assert is_grey(fill_rgb(page, 5))
    assert "silent" in disc(page, 5).text_content()
    assert disc(page, 1).get_attribute("data-kind") == "ok"
    assert page.locator("#hexaview .mmh-hv-overlay").get_attribute("visibility") == "hidden"


def test_layout_is_ardupilot_hexa_x_on_screen(page: Any, display: Any, open_display: Any) -> None:
    """Nose up: 1 right, 2 left, 3 front-left, 5 front-right, 4 rear-right, 6 rear-left; spins as AP."""
    server = display()
    open_display(page, server)
    centre = page.locator("#hexaview .mmh-hv-body").bounding_box()
    cx, cy = centre["x"] + centre["width"] / 2, centre["y"] + centre["height"] / 2
    pos = {}
    for m in range(1, 7):
        box = page.locator(f'#hexaview .mmh-hv-motor[data-motor="{m}"] .mmh-hv-disc').bounding_box()
        pos[m] = (box["x"] + box["width"] / 2 - cx, box["y"] + box["height"] / 2 - cy)
    r = abs(pos[1][0])
    assert pos[1][0] > 0.9 * r and abs(pos[1][1]) < 0.05 * r  # right
    assert pos[2][0] < -0.9 * r and abs(pos[2][1]) < 0.05 * r  # left
    assert pos[3][0] < 0 and pos[3][1] < -0.8 * r  # front-left (screen up is negative y)
    assert pos[5][0] > 0 and pos[5][1] < -0.8 * r  # front-right
    assert pos[4][0] > 0 and pos[4][1] > 0.8 * r  # rear-right
    assert pos[6][0] < 0 and pos[6][1] > 0.8 * r  # rear-left
    spins = {
        m: page.locator(f'#hexaview .mmh-hv-motor[data-motor="{m}"] .mmh-hv-spin').get_attribute("data-spin")
        for m in range(1, 7)
    }
    assert spins == {1: "CW", 2: "CCW", 3: "CW", 4: "CCW", 5: "CCW", 6: "CW"}
    assert page.locator("#vehicle-picker").is_hidden()  # no vehicles yet: no picker


def test_vehicle_announcing_hexa_plus_is_drawn_plus(
    page: Any, display: Any, agent_like: Any, make_publisher: Any, open_display: Any
) -> None:
    server = display()
    open_display(page, server)
    x = agent_like("xframe")
    healthy_vehicle(x)
    plus = agent_like("plusframe", pub=make_publisher("agent-plus"))
    plus.announce()
    plus.pub.publish(
        f"{plus.base}/info",
        {"vehicle_id": "plusframe", "frame": "hexa-plus", "motors": 6, "autopilot": "ardupilot"},
        retain=True,
        qos=1,
    )
    plus.state(1, "F2.1", since_s_ago=5)
    page.wait_for_selector('#vehicle-picker button[data-vehicle="plusframe"].kind-fault')

    def motor1_offset() -> tuple[float, float]:
        centre = page.locator("#hexaview .mmh-hv-body").bounding_box()
        box = page.locator('#hexaview .mmh-hv-motor[data-motor="1"] .mmh-hv-disc').bounding_box()
        return (
            box["x"] + box["width"] / 2 - centre["x"] - centre["width"] / 2,
            box["y"] + box["height"] / 2 - centre["y"] - centre["height"] / 2,
        )

    page.click('#vehicle-picker button[data-vehicle="xframe"]')
    page.wait_for_selector('#hexaview[data-frame="hexa-x"]', state="attached")
    dx, dy = motor1_offset()
    assert dx > 100 and abs(dy) < 5  # hexa-X: motor 1 on the right
    page.click('#vehicle-picker button[data-vehicle="plusframe"]')
    page.wait_for_selector(
        '#hexaview[data-frame="hexa-plus"] .mmh-hv-motor[data-motor="1"][data-state="F2.1"]'
    )
    dx, dy = motor1_offset()
    assert abs(dx) < 5 and dy < -100  # hexa-plus: motor 1 on the nose
    assert "phase open" in page.locator('.motor-card[data-motor="1"]').inner_text()
    assert page.locator(".motor-card").count() == 6


def test_page_reconnects_after_the_broker_restarts(
    page: Any, display_for: Any, mosquitto_factory: Any, make_publisher: Any, open_display: Any, prefix: str
) -> None:
    broker = mosquitto_factory("allow_anonymous true\n")
    server = display_for(broker, prefix, stale_after_s=30.0)
    open_display(page, server)
    broker.stop()
    page.wait_for_selector('#broker-status[data-state="disconnected"]')
    restarted = mosquitto_factory("allow_anonymous true\n", ports=(broker.mqtt_port, broker.ws_port))
    page.wait_for_selector('#broker-status[data-state="connected"]', timeout=15_000)
    agent = make_publisher("agent-after-restart", port=restarted.mqtt_port)
    agent.publish(
        f"{prefix}/again/motor/3/state",
        {
            "motor": 3,
            "state": "F1.1",
            "code": 1,
            "description": "bearing friction",
            "since_utc": "2026-01-01T00:00:00Z",
        },
        retain=True,
        qos=1,
    )
    page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="3"][data-state="F1.1"]')


def test_keepalive_pings_keep_the_connection(
    page: Any, display_for: Any, mosquitto_factory: Any, prefix: str
) -> None:
    """With a 2 s keep-alive the broker would drop a silent client after 3 s: the page pings instead."""
    broker = mosquitto_factory("allow_anonymous true\n")
    server = display_for(broker, prefix, keepalive_s=2)
    page.goto(server.url)
    page.wait_for_selector('#broker-status[data-state="connected"]')
    page.wait_for_timeout(4500)
    log = (broker.workdir / "mosquitto.log").read_text()
    assert re.search(r"Received PINGREQ from mmh-display-", log), log[-2000:]
    assert "exceeded timeout" not in log
    assert page.locator("#broker-status").get_attribute("data-state") == "connected"
    assert len(re.findall(r"New client connected .* as mmh-display-", log)) == 1  # never reconnected
