"""The .tlog reader against pymavlink's own message loop on the same real ArduPilot SITL log."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink import mavutil

from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.tlog import USED_MESSAGES, read_messages, read_tlog

RPM_TO_RAD_S = 2 * math.pi / 60


@pytest.fixture(scope="module")
def pymavlink_messages(sitl_tlog: Path) -> dict[str, list[Any]]:
    """Every used message as pymavlink decodes it (its CRC-checked mavutil loop)."""
    conn = mavutil.mavlink_connection(str(sitl_tlog), dialect="ardupilotmega")
    found: dict[str, list[Any]] = defaultdict(list)
    try:
        while (msg := conn.recv_match(type=list(USED_MESSAGES))) is not None:
            found[msg.get_type()].append(msg)
    finally:
        conn.close()
    return found


def _field(values: np.ndarray) -> list[Any]:
    if values.dtype.kind == "S":
        return [v.split(b"\0", 1)[0].decode() for v in values.tolist()]
    return values.tolist()


@pytest.mark.parametrize(
    "name",
    [
        "ESC_TELEMETRY_1_TO_4",
        "ESC_TELEMETRY_5_TO_8",
        "SERVO_OUTPUT_RAW",
        "SYS_STATUS",
        "BATTERY_STATUS",
        "VFR_HUD",
        "GLOBAL_POSITION_INT",
        "SCALED_PRESSURE",
        "HEARTBEAT",
        "PARAM_VALUE",
    ],
)
def test_every_field_of_every_message_equals_pymavlink(
    sitl_tlog: Path, pymavlink_messages: dict[str, list[Any]], name: str
) -> None:
    ours = read_messages(sitl_tlog)
    theirs = pymavlink_messages[name]
    assert len(theirs) > 0
    assert len(ours[name]) == len(theirs)
    for field in ours[name].dtype.names or ():
        got = _field(ours[name][field])
        want = [getattr(m, field) for m in theirs]
        if field == "param_id":
            want = [w.split("\0", 1)[0] for w in want]
        assert got == want, f"{name}.{field}"
    stamps = ours.time_us[name] / 1e6
    np.testing.assert_allclose(stamps, [m._timestamp for m in theirs], rtol=0, atol=2e-6)
    assert ours.sysid[name].tolist() == [m.get_srcSystem() for m in theirs]


def test_table_rows_are_the_esc_slots_in_si_units(
    sitl_tlog: Path, pymavlink_messages: dict[str, list[Any]]
) -> None:
    table = sources.read(sitl_tlog)
    esc14 = pymavlink_messages["ESC_TELEMETRY_1_TO_4"]
    esc58 = pymavlink_messages["ESC_TELEMETRY_5_TO_8"]
    assert table.motors() == [1, 2, 3, 4, 5, 6]  # slots 7 and 8 never report: no rows
    assert table.meta["motors"] == [1, 2, 3, 4, 5, 6]  # FRAME_CLASS 2: hexa
    for motor in range(1, 7):
        rows = table.for_motor(motor)
        msgs = esc14 if motor <= 4 else esc58
        slot = (motor - 1) % 4
        assert len(rows) == len(msgs)
        rpm = np.array([m.rpm[slot] for m in msgs], dtype=float)
        count = np.array([m.count[slot] for m in msgs])
        fresh = np.ones(len(count), dtype=bool)
        fresh[1:] = np.diff(count) != 0
        np.testing.assert_allclose(rows["omega_rad_s"][fresh], rpm[fresh] * RPM_TO_RAD_S)
        assert np.isnan(rows["omega_rad_s"][~fresh]).all()  # repeated values: stale, not a measurement
        np.testing.assert_allclose(rows["bus_voltage_v"], [m.voltage[slot] / 100 for m in msgs])
        np.testing.assert_allclose(rows["esc_temp_c"], [m.temperature[slot] for m in msgs])
        esc_current = np.array([m.current[slot] / 100 for m in msgs])
        np.testing.assert_allclose(rows["esc_current_a"][fresh], esc_current[fresh])
        # the motor's current and voltage: the ESC as an ideal PWM stage, as the live agent computes them
        moving = fresh & (rows["throttle"] >= 0.05)
        np.testing.assert_allclose(rows["current_a"][moving], esc_current[moving] / rows["throttle"][moving])
        assert np.isnan(rows["current_a"][rows["throttle"] < 0.05]).all()
        np.testing.assert_allclose(rows["voltage_v"], rows["throttle"] * rows["bus_voltage_v"])


def test_throttle_is_the_servo_output_held_to_each_esc_sample(
    sitl_tlog: Path, pymavlink_messages: dict[str, list[Any]]
) -> None:
    table = read_tlog(sitl_tlog)
    servo = pymavlink_messages["SERVO_OUTPUT_RAW"]
    t_servo = np.array([m._timestamp for m in servo]) - table.meta["time_origin_unix_s"]
    for motor in (1, 2):
        rows = table.for_motor(motor)
        pwm = np.array([getattr(m, f"servo{motor}_raw") for m in servo], dtype=float)
        idx = np.searchsorted(t_servo, rows["time_s"] + 1e-7, side="right") - 1
        ok = idx >= 0
        expected = np.clip((pwm[idx[ok]] - 1000) / 1000, 0, 1)
        np.testing.assert_allclose(rows["throttle"][ok], expected)
    # During the SIM_ENGINE_MUL 0.5 fault (110-130 s) the autopilot drives motor 1 harder than motor 3.
    m1, m3 = table.for_motor(1), table.for_motor(3)
    window1 = (m1["time_s"] > 112) & (m1["time_s"] < 128)
    window3 = (m3["time_s"] > 112) & (m3["time_s"] < 128)
    assert np.nanmean(m1["throttle"][window1]) > np.nanmean(m3["throttle"][window3]) + 0.1
    assert np.nanmean(m1["omega_rad_s"][window1]) < 0.7 * np.nanmean(m3["omega_rad_s"][window3])


def test_context_and_meta(sitl_tlog: Path) -> None:
    table = read_tlog(sitl_tlog)
    meta = table.meta
    assert meta["params"]["FRAME_CLASS"] == 2
    assert meta["vehicle"]["mav_type"] == 13  # MAV_TYPE_HEXAROTOR
    hover = (table["time_s"] > 60) & (table["time_s"] < 100)
    assert np.nanmedian(table["alt_m"][hover]) == pytest.approx(10, abs=0.5)
    assert (table["armed"][hover] == 1).all()
    assert np.nanmedian(table["air_temp_c"]) > 0
    assert np.nanmedian(table["battery_voltage_v"]) == pytest.approx(12.6, abs=0.5)
    assert not meta["damage"]["breaks"]
