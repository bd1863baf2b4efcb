"""The whole chain with real parts: simulated vehicle (MAVLink over UDP) → agent → mosquitto → the page in
headless Chromium. A fault injected on motor 4 in the simulation turns motor 4 red with its name on the page;
when the agent stops, the page says the vehicle is offline."""

from __future__ import annotations

import asyncio
import threading
from typing import Any

import pytest

from mav_motor_health.agent import Agent, load_agent_config
from mav_motor_health.sim.live import SimVehicle
from mav_motor_health.sim.scenario import load_scenario

pytestmark = pytest.mark.timeout(90)


class VehicleAndAgent:
    """A simulated hexacopter and the agent watching it, on their own asyncio loop in a thread
    (the test's thread drives the browser)."""

    def __init__(self, udp_port: int, mqtt_port: int, vehicle_id: str) -> None:
        self.udp_port, self.mqtt_port, self.vehicle_id = udp_port, mqtt_port, vehicle_id
        self.ready = threading.Event()
        self.error: BaseException | None = None
        self.vehicle: SimVehicle | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread = threading.Thread(target=self._run, name="vehicle+agent", daemon=True)

    def __enter__(self) -> VehicleAndAgent:
        self._thread.start()
        if not self.ready.wait(20) or self.error is not None:
            self.__exit__()
            raise RuntimeError(f"vehicle and agent did not start: {self.error!r}")
        return self

    def __exit__(self, *exc: object) -> None:
        if self._thread.is_alive() and self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(20)

    def stop_agent(self) -> None:
        self.__exit__()
        if self.error is not None:
            raise self.error

    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as exc:
            self.error = exc
            self.ready.set()

    async def _main(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        scenario = load_scenario("flight/healthy_calm")
        with SimVehicle(scenario, f"udpout:127.0.0.1:{self.udp_port}") as vehicle:
            self.vehicle = vehicle
            config = load_agent_config(
                None,
                connect=f"udpin:127.0.0.1:{self.udp_port}",
                mqtt_url=f"mqtt://127.0.0.1:{self.mqtt_port}",
                vehicle_id=self.vehicle_id,
            )
            async with Agent(config):
                self.ready.set()
                await self._stop.wait()


def test_fault_injected_in_the_simulation_reaches_the_page(
    page: Any, display_for: Any, broker: Any, open_display: Any, free_port: Any
) -> None:
    """Two simulated vehicles, each with its own agent, publishing at once; motor 4 of one fails."""
    server = display_for(broker, "mmh", stale_after_s=5.0)
    open_display(page, server)
    motor4 = page.locator('#hexaview .mmh-hv-motor[data-motor="4"]')
    with (
        VehicleAndAgent(free_port(), broker.mqtt_port, "sim-alpha") as alpha,
        VehicleAndAgent(free_port(), broker.mqtt_port, "sim-bravo"),
    ):
        # both agents announce their healthy motors (and publish telemetry) through the broker
        page.wait_for_selector('#vehicle-picker button[data-vehicle="sim-bravo"]', timeout=30_000)
        page.click('#vehicle-picker button[data-vehicle="sim-alpha"]')
        page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="4"][data-state="NORMAL"]', timeout=30_000)
        assert "sim-alpha · hexa-x" in page.locator("#vehicle-summary").inner_text()
        page.wait_for_selector('.motor-card[data-motor="4"] .values:has-text("rad/s")')  # telemetry
        assert alpha.vehicle is not None
        alpha.vehicle.inject("F3.1", 4)
        page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="4"][data-state="F3.1"]', timeout=15_000)
        fill = page.eval_on_selector(
            '#hexaview .mmh-hv-motor[data-motor="4"] .mmh-hv-disc', "e => getComputedStyle(e).fill"
        )
        assert fill == "rgb(198, 40, 40)", fill  # the fault colour
        assert "F3.1" in motor4.text_content()
        assert "propeller damage" in page.locator('.motor-card[data-motor="4"]').inner_text()
        page.wait_for_selector('#event-log td:has-text("→ F3.1")')
        page.wait_for_selector('#vehicle-picker button[data-vehicle="sim-alpha"].kind-fault')
        # the other vehicle's motor 4 is still healthy
        page.click('#vehicle-picker button[data-vehicle="sim-bravo"]')
        page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="4"][data-state="NORMAL"]')
        assert page.locator("#vehicle-summary").inner_text().startswith("sim-bravo")
        page.click('#vehicle-picker button[data-vehicle="sim-alpha"]')
        page.wait_for_selector('#hexaview .mmh-hv-motor[data-motor="4"][data-state="F3.1"]')
        alpha.stop_agent()
        # alpha's agent said goodbye (status offline, retained) while bravo's still talks
        page.wait_for_selector('#hexaview .mmh-hv-overlay[visibility="visible"]', timeout=10_000)
        assert "offline" in page.locator("#hexaview .mmh-hv-overlay").text_content()
        page.click('#vehicle-picker button[data-vehicle="sim-bravo"]')
        page.wait_for_selector('#hexaview .mmh-hv-overlay[visibility="hidden"]', state="attached")
