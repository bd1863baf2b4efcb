"""The .tlog reader on frames pymavlink itself encodes: MAVLink 1, MAVLink 2 (trailing zeros truncated),
signed MAVLink 2, a ground station's own messages, SERVOn_FUNCTION mapping and stale ESC samples."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v10 import ardupilotmega as mav1
from pymavlink.dialects.v20 import ardupilotmega as mav2

from mav_motor_health.telemetry.tlog import read_messages, read_tlog

T0_US = 1_700_000_000_000_000


def _record(t_s: float, frame: bytes) -> bytes:
    return struct.pack(">Q", T0_US + int(t_s * 1e6)) + frame


@pytest.fixture
def synthetic_tlog(tmp_path: Path) -> Path:
    v1 = mav1.MAVLink(None, srcSystem=1, srcComponent=1)
    v2 = mav2.MAVLink(None, srcSystem=1, srcComponent=1)
    signed = mav2.MAVLink(None, srcSystem=1, srcComponent=1)
    signed.signing.secret_key = bytes(range(32))
    signed.signing.link_id = 1
    signed.signing.timestamp = 1
    signed.signing.sign_outgoing = True
    gcs = mav2.MAVLink(None, srcSystem=255, srcComponent=190)
    out = bytearray()
    out += _record(0.0, gcs.heartbeat_encode(6, 8, 0, 0, 4).pack(gcs))  # a ground station: ignored
    out += _record(0.01, v2.heartbeat_encode(13, 3, 128 | 1, 0, 4).pack(v2))
    # Output 1 drives motor 3 and output 3 motor 1 (swapped); output 2 is a servo, not a motor.
    for name, value in (
        ("SERVO1_FUNCTION", 35),
        ("SERVO2_FUNCTION", 4),
        ("SERVO3_FUNCTION", 33),
        ("SERVO4_FUNCTION", 36),
    ):
        out += _record(0.02, v2.param_value_encode(name.encode(), value, 2, 100, 0).pack(v2))
    for k in range(30):
        t = 0.1 + 0.1 * k
        servo = (v1, v2)[k % 2]  # ids above 255 exist in MAVLink 2 only; SERVO_OUTPUT_RAW comes in both
        out += _record(
            t, servo.servo_output_raw_encode(int(t * 1e6), 0, 1100, 1500, 1300, 1400, 0, 0, 0, 0).pack(servo)
        )
        count = k // 2  # every other message repeats the previous sample: stale
        rpm = [1000 + 10 * k, 0, 3000 + 10 * k, 4000]
        enc = (v2, signed)[k % 2]
        msg = enc.esc_telemetry_1_to_4_encode(
            [30, 0, 32, 0],
            [1600, 0, 1610, 1620],
            [120, 0, 300, 0],
            [1, 0, 2, 3],
            rpm,
            [count, 0, count, count],
        )
        out += _record(t + 0.001, msg.pack(enc))
    path = tmp_path / "synthetic.tlog"
    path.write_bytes(bytes(out))
    return path


def test_mavlink1_mavlink2_and_signed_frames_decode_alike(synthetic_tlog: Path) -> None:
    msgs = read_messages(
        synthetic_tlog, ["ESC_TELEMETRY_1_TO_4", "HEARTBEAT", "PARAM_VALUE", "SERVO_OUTPUT_RAW"], warn=False
    )
    assert msgs["SERVO_OUTPUT_RAW"]["servo3_raw"].tolist() == [1300] * 30  # MAVLink 1 and 2 frames
    esc = msgs["ESC_TELEMETRY_1_TO_4"]
    assert len(esc) == 30
    assert esc["rpm"][:, 0].tolist() == [1000 + 10 * k for k in range(30)]
    assert esc["temperature"][:, 2].tolist() == [32] * 30  # MAVLink 2 payloads end in zeros: padded back
    assert msgs.sysid["HEARTBEAT"].tolist() == [255, 1]
    names = [p.split(b"\0")[0] for p in msgs["PARAM_VALUE"]["param_id"].tolist()]
    assert names == [b"SERVO1_FUNCTION", b"SERVO2_FUNCTION", b"SERVO3_FUNCTION", b"SERVO4_FUNCTION"]
    assert not msgs.damage


def test_servo_functions_map_outputs_to_motors_and_repeats_are_stale(synthetic_tlog: Path) -> None:
    table = read_tlog(synthetic_tlog)
    assert table.meta["vehicle"]["sysid"] == 1
    assert table.meta["vehicle"]["mav_type"] == 13
    # slot 0 (output 1) is motor 3, slot 2 (output 3) is motor 1, slot 1 (output 2, a servo) is no motor,
    # slot 3 (output 4) is motor 4.
    assert table.motors() == [1, 3, 4]
    m3, m1 = table.for_motor(3), table.for_motor(1)
    # every other message repeats the previous packet: stale once the count has been seen to move (as the
    # live agent reads it); the second message, before that, cannot be told from a new packet
    fresh = (np.arange(30) % 2 == 0) | (np.arange(30) == 1)
    np.testing.assert_allclose(
        m3["omega_rad_s"][fresh], (1000 + 10 * np.arange(30))[fresh] * 2 * math.pi / 60
    )
    np.testing.assert_allclose(
        m1["omega_rad_s"][fresh], (3000 + 10 * np.arange(30))[fresh] * 2 * math.pi / 60
    )
    assert np.isnan(m3["omega_rad_s"][~fresh]).all() and np.isnan(m3["current_a"][~fresh]).all()
    np.testing.assert_allclose(m3["throttle"], 0.1)  # output 1: 1100 µs
    np.testing.assert_allclose(m1["throttle"], 0.3)  # output 3: 1300 µs
    np.testing.assert_allclose(m1["esc_current_a"][fresh], 3.0)
    np.testing.assert_allclose(m1["current_a"][fresh], 3.0 / 0.3)  # motor current: ESC current / duty
    np.testing.assert_allclose(m1["voltage_v"], 0.3 * 16.1)
    np.testing.assert_allclose(m1["bus_voltage_v"], 16.1)
    assert (table["armed"] == 1).all()


def test_px4_esc_status_frames_from_pymavlink_generated_dialect(tmp_path: Path) -> None:
    """ESC_STATUS (291) encoded by pymavlink's own generator from common.xml's definition (the project's
    dialect carries it): PX4's per-ESC rpm, voltage and current as floats, four per message from ``index``."""
    from mav_motor_health.publish import dialect

    gen = dialect.load()
    px4 = gen.MAVLink(None, srcSystem=1, srcComponent=1)
    out = bytearray()
    out += _record(0.0, mav2.MAVLink(None, 1, 1).heartbeat_encode(13, 12, 128, 0, 4).pack(px4))
    for k in range(10):
        t = 0.1 * (k + 1)
        for index in (0, 4):
            rpm = [2000 + 100 * (index + i) + k for i in range(4)]
            msg = gen.MAVLink_esc_status_message(
                index, int(t * 1e6), rpm, [22.0] * 4, [1.5 + index + i for i in range(4)]
            )
            out += _record(t + 0.001 * index, msg.pack(px4))
    path = tmp_path / "px4.tlog"
    path.write_bytes(bytes(out))
    table = read_tlog(path)
    assert table.motors() == [1, 2, 3, 4, 5, 6, 7, 8]
    for motor in (1, 6):
        rows = table.for_motor(motor)
        np.testing.assert_allclose(
            rows["omega_rad_s"], (2000 + 100 * (motor - 1) + np.arange(10)) * 2 * math.pi / 60
        )
        np.testing.assert_allclose(rows["esc_current_a"], 1.5 + motor - 1)
        np.testing.assert_allclose(rows["bus_voltage_v"], 22.0)
    assert table.meta["vehicle"]["autopilot"] == 12  # MAV_AUTOPILOT_PX4


def test_empty_slots_and_counts_that_never_move_are_read_as_the_agent_reads_them(tmp_path: Path) -> None:
    """Before an ESC's first packet ArduPilot sends its slot as zeros: no sample (not a stopped motor). An
    ESC whose packet count never moves is read in every message, as the agent reads it."""
    from mav_motor_health.agent.samples import SampleAssembler

    v2 = mav2.MAVLink(None, srcSystem=1, srcComponent=1)
    out = bytearray(_record(0.0, v2.heartbeat_encode(13, 3, 128 | 1, 0, 4).pack(v2)))
    frames = []
    for k in range(20):
        t = 0.05 * (k + 1)
        servo = v2.servo_output_raw_encode(int(t * 1e6), 0, 1500, 1500, 1500, 1500, 0, 0, 0, 0)
        started = k >= 5  # slot 0 reports from the sixth message on
        esc = v2.esc_telemetry_1_to_4_encode(
            [30 if started else 0, 31, 0, 0],
            [1600 if started else 0, 1600, 0, 0],
            [200 if started else 0, 210 + k, 0, 0],
            [(k - 4) if started else 0, 0, 0, 0],  # slot 1's count never moves
            [5000 + 10 * k if started else 0, 5100 + 10 * k, 0, 0],
            [1 + (k - 5) // 2 if started else 0, 0, 0, 0],  # slot 0: every packet sent twice
        )
        frames += [(t, servo), (t + 0.001, esc)]
    for t, msg in frames:
        out += _record(t, msg.pack(v2))
    path = tmp_path / "slots.tlog"
    path.write_bytes(bytes(out))
    table = read_tlog(path)
    m1, m2 = table.for_motor(1), table.for_motor(2)
    assert np.isnan(m1["omega_rad_s"][:5]).all()  # no packet yet: not a stopped motor
    # the first packet's repeat cannot be told from a new one (the count has not moved yet); after that
    # every repeat is stale
    fresh = [5, 6, *range(7, 20, 2)]
    assert np.flatnonzero(np.isfinite(m1["omega_rad_s"])).tolist() == fresh
    assert np.isfinite(m2["omega_rad_s"]).all()  # count stuck at 0, values moving: every message is read
    # the agent's assembler gives the same samples
    assembler = SampleAssembler(motors=4)
    agent: dict[int, list[float]] = {1: [], 2: []}
    for t, msg in frames:
        decoded = v2.decode(bytearray(msg.pack(v2)))
        for sample in assembler.feed(decoded, t):
            if sample.motor in agent:
                agent[sample.motor].append(sample.omega_rad_s)
    np.testing.assert_allclose(agent[1], m1["omega_rad_s"][fresh])
    np.testing.assert_allclose(agent[2], m2["omega_rad_s"])
