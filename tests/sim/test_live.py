"""The live simulated vehicle on real sockets: pymavlink as a ground station, and MAVProxy (PyPI) between
the vehicle and a ground station, as in the field."""

from __future__ import annotations

import asyncio
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mav_motor_health.sim.live import SimVehicle, mavlink2_connection
from mav_motor_health.sim.scenario import load_scenario

pytestmark = pytest.mark.timeout(120)
RPM_STOPPED = 100.0 * 60 / (2 * 3.141592653589793)  # the paper's stop speed, 100 rad/s, in rpm


def free_port(kind: int = socket.SOCK_DGRAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def esc_rpms(gcs, seconds: float) -> dict[int, list[int]]:
    """rpm per motor from ESC_TELEMETRY received within ``seconds`` (fresh reports only)."""
    while gcs.recv_match(blocking=False) is not None:  # drop what was queued before
        pass
    rpms: dict[int, list[int]] = {m: [] for m in range(1, 7)}
    last_count = {}
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        msg = gcs.recv_match(
            type=["ESC_TELEMETRY_1_TO_4", "ESC_TELEMETRY_5_TO_8"], blocking=True, timeout=0.5
        )
        if msg is None:
            continue
        first = 0 if msg.get_type().endswith("1_TO_4") else 4
        for k in range(4):
            motor = first + k + 1
            if motor <= 6 and msg.count[k] and msg.count[k] != last_count.get(motor):
                last_count[motor] = msg.count[k]
                rpms[motor].append(msg.rpm[k])
    return rpms


@pytest.fixture
def vehicle_and_gcs():
    port = free_port()
    scenario = load_scenario("flight/healthy_calm")
    with SimVehicle(scenario, f"udpout:127.0.0.1:{port}", speed=2.0) as vehicle:
        gcs = mavlink2_connection(f"udpin:127.0.0.1:{port}", source_system=255)
        try:
            assert gcs.wait_heartbeat(timeout=10) is not None
            yield vehicle, gcs
        finally:
            gcs.close()
    assert not vehicle.running


def test_heartbeat_params_and_message_interval(vehicle_and_gcs):
    vehicle, gcs = vehicle_and_gcs
    hb = gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
    assert hb.type == 13 and hb.autopilot == 3  # MAV_TYPE_HEXAROTOR, MAV_AUTOPILOT_ARDUPILOTMEGA
    gcs.mav.param_request_list_send(1, 1)
    params = {}
    end = time.monotonic() + 5
    while time.monotonic() < end and len(params) < len(vehicle.params):
        msg = gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=1)
        if msg is not None:
            params[msg.param_id] = msg.param_value
    assert params["FRAME_CLASS"] == 2 and params["SERVO1_FUNCTION"] == 33 and "SIM_MOT_FAULT" in params
    gcs.mav.param_request_read_send(1, 1, b"MOT_PWM_MIN", -1)
    assert gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=3).param_value == 1000
    # 25 Hz of simulated time = 50 messages per real second at speed 2
    gcs.mav.command_long_send(1, 1, 511, 0, 11030, 40000, 0, 0, 0, 0, 0)
    ack = gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=3)
    assert ack.command == 511 and ack.result == 0
    assert vehicle.rates_hz["ESC_TELEMETRY"] == pytest.approx(25.0)
    gcs.mav.request_data_stream_send(1, 1, 3, 2, 1)  # RC_CHANNELS stream → SERVO_OUTPUT_RAW at 2 Hz
    time.sleep(0.5)
    assert vehicle.rates_hz["SERVO_OUTPUT_RAW"] == 2.0


def test_fault_injection_by_param_and_command_and_messages_recorded(vehicle_and_gcs):
    vehicle, gcs = vehicle_and_gcs
    before = esc_rpms(gcs, 1.0)
    assert all(len(v) > 3 and min(v) > 3000 for v in before.values())
    gcs.mav.param_set_send(1, 1, b"SIM_MOT_FLT_NUM", 4, 9)
    gcs.mav.param_set_send(1, 1, b"SIM_MOT_FAULT", 2, 9)  # F2.1
    gcs.mav.statustext_send(4, b"motor 4: F2.1")
    gcs.mav.named_value_float_send(0, b"MH_M4", 2.1)
    time.sleep(1.5)
    after = esc_rpms(gcs, 1.0)
    assert max(after[4]) < RPM_STOPPED, (
        vehicle.sim.faults,
        vehicle.params["SIM_MOT_FAULT"],
        vehicle.sim_time_s,
    )
    # the others take the load (the one opposite the failed motor is throttled back to balance)
    others = sorted(sum(after[m]) / len(after[m]) for m in (1, 2, 3, 5, 6))
    assert others[1] > sum(before[1]) / len(before[1])
    assert [f.kind for f in vehicle.sim.faults] == ["F2.1"] and vehicle.sim.faults[0].motor == 4
    kinds = {r.type: r for r in vehicle.received}
    assert kinds["STATUSTEXT"].fields["text"] == "motor 4: F2.1"
    assert kinds["NAMED_VALUE_FLOAT"].fields["name"] == "MH_M4"
    gcs.mav.command_long_send(1, 1, 31010, 0, 4, 2, 0.5, 0, 0, 0, 0)  # F4.1 on motor 2 at half severity
    assert gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=3).result == 0
    time.sleep(0.3)
    assert vehicle.sim.faults[-1].kind == "F4.1" and vehicle.sim.faults[-1].severity == 0.5


def test_runs_faster_than_real_time(vehicle_and_gcs):
    vehicle, _ = vehicle_and_gcs
    t0, s0 = time.monotonic(), vehicle.sim_time_s
    time.sleep(1.0)
    ratio = (vehicle.sim_time_s - s0) / (time.monotonic() - t0)
    assert 1.3 < ratio < 2.3


def test_usable_from_asyncio():
    port = free_port()

    async def main() -> float:
        async with SimVehicle(
            load_scenario("flight/healthy_calm"), f"udpout:127.0.0.1:{port}", speed=4.0
        ) as v:
            await asyncio.sleep(0.5)
            return v.sim_time_s

    assert asyncio.run(main()) > 0.5


def test_mavproxy_ground_station_sees_six_escs_and_an_injected_fault(tmp_path: Path):
    vehicle_port, gcs_port = free_port(socket.SOCK_STREAM), free_port()
    mavproxy = Path(sys.executable).with_name("mavproxy.py")
    if not mavproxy.exists():
        pytest.fail(f"MAVProxy is not installed next to {sys.executable}")
    scenario = load_scenario("flight/healthy_calm")
    with SimVehicle(scenario, f"tcpin:127.0.0.1:{vehicle_port}", speed=1.0) as vehicle:
        proc = subprocess.Popen(
            [
                sys.executable,
                str(mavproxy),
                f"--master=tcp:127.0.0.1:{vehicle_port}",
                f"--out=udpout:127.0.0.1:{gcs_port}",
                "--daemon",
                "--non-interactive",
                f"--state-basedir={tmp_path}",
                "--default-modules=",
            ],
            cwd=tmp_path,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        )
        gcs = mavlink2_connection(f"udpin:127.0.0.1:{gcs_port}", source_system=254)
        try:
            assert gcs.wait_heartbeat(timeout=30) is not None, "no heartbeat through MAVProxy"
            rpms = esc_rpms(gcs, 3.0)
            assert all(len(rpms[m]) >= 3 for m in range(1, 7)), {m: len(v) for m, v in rpms.items()}
            gcs.mav.param_set_send(1, 1, b"SIM_MOT_FLT_NUM", 6, 9)
            gcs.mav.param_set_send(1, 1, b"SIM_MOT_FAULT", 5, 9)  # F4.2
            end = time.monotonic() + 10
            while time.monotonic() < end and not vehicle.sim.faults:
                time.sleep(0.1)
            assert vehicle.sim.faults and vehicle.sim.faults[0].kind == "F4.2"
            time.sleep(1.0)
            after = esc_rpms(gcs, 2.0)
            assert after[6] and max(after[6]) < RPM_STOPPED
            assert sum(min(after[m]) > 2000 for m in range(1, 6)) >= 4
        finally:
            gcs.close()
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
