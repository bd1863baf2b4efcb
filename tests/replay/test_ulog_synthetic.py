"""A ULog written here byte by byte (the format's spec: header, definitions, subscriptions, data), read by
pyulog and by our reader: six ESCs in the esc_status array, each with its ``actuator_function``, and
actuator_motors whose trailing padding the logger leaves out."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pytest
from pyulog import ULog as PyULog

from mav_motor_health.telemetry.ulog import read_ulog, read_ulog_topics

ESC_REPORT = (
    "esc_report:uint64_t timestamp;uint32_t esc_errorcount;int32_t esc_rpm;float esc_voltage;float esc_current;"
    "float esc_temperature;uint16_t failures;int8_t esc_power;uint8_t esc_address;uint8_t esc_cmdcount;"
    "uint8_t esc_state;uint8_t actuator_function;uint8_t[5] _padding0;"
)
ESC_STATUS = (
    "esc_status:uint64_t timestamp;uint16_t counter;uint8_t esc_count;uint8_t esc_connectiontype;"
    "uint8_t esc_online_flags;uint8_t esc_armed_flags;uint8_t[2] _padding0;esc_report[8] esc;"
)
ACTUATOR_MOTORS = (
    "actuator_motors:uint64_t timestamp;uint64_t timestamp_sample;float[12] control;uint16_t reversible_flags;"
    "uint8_t[6] _padding0;"
)
#: ESC slot j drives this motor (PX4 actuator_function 101 = Motor1).
FUNCTIONS = [103, 101, 102, 106, 104, 105]


def _msg(kind: str, body: bytes) -> bytes:
    return struct.pack("<HB", len(body), ord(kind)) + body


def _esc_report(t_us: int, rpm: int, volts: float, amps: float, temp_c: float, function: int) -> bytes:
    return struct.pack("<QIifffHbBBBB5x", t_us, 0, rpm, volts, amps, temp_c, 0, 0, 0, 0, 0, function)


@pytest.fixture
def synthetic_ulg(tmp_path: Path) -> Path:
    out = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", 1_000_000))
    out += _msg("B", bytes(40))
    for fmt in (ESC_REPORT, ESC_STATUS, ACTUATOR_MOTORS):
        out += _msg("F", fmt.encode())
    out += _msg(
        "P", bytes([len("int32_t CA_ROTOR_COUNT")]) + b"int32_t CA_ROTOR_COUNT" + struct.pack("<i", 6)
    )
    out += _msg("A", struct.pack("<BH", 0, 1) + b"esc_status")
    out += _msg("A", struct.pack("<BH", 0, 2) + b"actuator_motors")
    for k in range(40):
        t_us = 2_000_000 + k * 100_000
        reports = b"".join(
            _esc_report(t_us, 1000 * (m + 1) + k, 16.0, 0.5 * (m + 1), 30.0 + m, FUNCTIONS[m])
            for m in range(6)
        )
        reports += bytes(2 * 40)  # slots 6 and 7: not present (40 bytes per esc_report)
        status = struct.pack("<QHBBBB2x", t_us, k, 6, 1, 0x3F, 0x3F) + reports
        out += _msg("D", struct.pack("<H", 1) + status)
        controls = [0.1 * (i + 1) for i in range(6)] + [math.nan] * 6
        motors = struct.pack("<QQ12fH", t_us - 50_000, t_us - 50_000, *controls, 0)  # no trailing padding
        out += _msg("D", struct.pack("<H", 2) + motors)
    path = tmp_path / "synthetic.ulg"
    path.write_bytes(bytes(out))
    return path


def test_pyulog_and_our_reader_agree_on_the_synthetic_log(synthetic_ulg: Path) -> None:
    theirs = PyULog(str(synthetic_ulg))
    ours = read_ulog_topics(synthetic_ulg, ["esc_status", "actuator_motors"])
    assert not ours.damage
    esc = theirs.get_dataset("esc_status").data
    arr = ours.get("esc_status")
    assert arr is not None
    for j in range(8):
        np.testing.assert_array_equal(arr["esc"][:, j]["esc_rpm"], esc[f"esc[{j}].esc_rpm"])
        np.testing.assert_array_equal(
            arr["esc"][:, j]["actuator_function"], esc[f"esc[{j}].actuator_function"]
        )
    motors = ours.get("actuator_motors")
    assert motors is not None
    np.testing.assert_array_equal(
        motors["control"][:, 2], theirs.get_dataset("actuator_motors").data["control[2]"]
    )
    assert ours.params == {"CA_ROTOR_COUNT": 6.0}


def test_actuator_function_maps_esc_slots_to_motors_and_commands_follow_the_motor(
    synthetic_ulg: Path,
) -> None:
    table = read_ulog(synthetic_ulg)
    assert table.motors() == [1, 2, 3, 4, 5, 6]
    assert table.meta["motors"] == [1, 2, 3, 4, 5, 6]
    for slot, function in enumerate(FUNCTIONS):
        motor = function - 100
        rows = table.for_motor(motor)
        assert len(rows) == 40
        np.testing.assert_allclose(
            rows["omega_rad_s"], (1000 * (slot + 1) + np.arange(40)) * 2 * math.pi / 60
        )
        np.testing.assert_allclose(rows["esc_current_a"], 0.5 * (slot + 1))
        np.testing.assert_allclose(rows["esc_temp_c"], 30.0 + slot)  # plain °C: not converted
        np.testing.assert_allclose(rows["throttle"], 0.1 * motor, rtol=1e-6)  # control[i] is Motor i+1
        np.testing.assert_allclose(rows["time_s"], 1.0 + 0.1 * np.arange(40))  # from the header's timestamp
    assert table.meta["esc_temperature_kelvin"] is False
