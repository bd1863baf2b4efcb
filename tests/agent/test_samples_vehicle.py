"""Messages to motor samples (ArduPilot and PX4), and the autopilot tracker, with real pymavlink messages."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from mav_motor_health.agent.samples import SampleAssembler
from mav_motor_health.agent.vehicle import AutopilotTracker, stream_requests, wanted_params
from mav_motor_health.publish import dialect
from mav_motor_health.telemetry import mavlink_esc

MAV = mavlink2.MAVLink(None, 1, 1)


def decoded(msg):
    """Through the wire and back, as the agent receives it."""
    return mavlink2.MAVLink(None, 0, 0).parse_buffer(msg.pack(MAV))[0]


def servo(pwm: list[int]):
    return decoded(MAV.servo_output_raw_encode(0, 0, *(pwm + [0] * (8 - len(pwm)))))


def test_ardupilot_esc_telemetry_becomes_samples_with_the_servo_function_mapping():
    a = SampleAssembler(motors=6)
    a.feed(decoded(MAV.param_value_encode(b"SERVO1_FUNCTION", 34, 9, 1, 0)), 0.0)  # output 1 drives motor 2
    a.feed(decoded(MAV.param_value_encode(b"SERVO2_FUNCTION", 33, 9, 1, 1)), 0.0)
    a.feed(servo([1600, 1500, 1500, 1500, 1500, 1500]), 0.0)

    def esc(count: int):
        return decoded(
            MAV.esc_telemetry_1_to_4_encode(
                [30] * 4, [1200] * 4, [300, 250, 250, 250], [0] * 4, [6000] * 4, [count] * 4
            )
        )

    samples = {s.motor: s for s in a.feed(esc(1), 0.5)}
    assert set(samples) == {1, 2, 3, 4}
    s2 = samples[2]  # ESC slot 0 = output 1 = motor 2, throttle 0.6
    assert s2.time_s == 0.5 and s2.throttle == pytest.approx(0.6)
    assert s2.omega_rad_s == pytest.approx(6000 * mavlink_esc.RPM_TO_RAD_S)
    assert s2.voltage_v == pytest.approx(0.6 * 12.0) and s2.current_a == pytest.approx(3.0 / 0.6)
    assert samples[1].throttle == pytest.approx(0.5)


def test_a_command_older_than_a_second_is_not_paired_as_in_replay():
    """1.5 s after the last SERVO_OUTPUT_RAW the command stream has stopped: the sample keeps its speed and
    ESC readings, but its command, motor voltage and motor current are unknown (replay's table says the
    same: commands older than assemble.COMMAND_MAX_AGE_S are none)."""
    a = SampleAssembler(motors=6)
    a.feed(servo([1600, 1500, 1500, 1500, 1500, 1500]), 0.0)
    msg = decoded(
        MAV.esc_telemetry_1_to_4_encode(
            [30] * 4, [1200] * 4, [300, 250, 250, 250], [0] * 4, [6000] * 4, [1] * 4
        )
    )
    samples = {s.motor: s for s in a.feed(msg, 1.5)}
    assert set(samples) == {1, 2, 3, 4}
    s1 = samples[1]
    assert s1.time_s == 1.5 and s1.omega_rad_s == pytest.approx(6000 * mavlink_esc.RPM_TO_RAD_S)
    assert s1.esc_current_a == pytest.approx(3.0) and s1.bus_voltage_v == pytest.approx(12.0)
    assert math.isnan(s1.throttle) and math.isnan(s1.voltage_v) and math.isnan(s1.current_a)
    # a fresh command pairs again
    a.feed(servo([1700] * 6), 1.6)
    msg = decoded(
        MAV.esc_telemetry_1_to_4_encode(
            [30] * 4, [1200] * 4, [300, 250, 250, 250], [0] * 4, [6000] * 4, [2] * 4
        )
    )
    (s1, *_) = a.feed(msg, 1.7)
    assert s1.throttle == pytest.approx(0.7) and s1.voltage_v == pytest.approx(0.7 * 12.0)


def test_a_silent_esc_repeating_its_values_and_an_empty_slot_give_no_samples():
    a = SampleAssembler(motors=6)
    a.feed(servo([1500] * 6), 0.0)

    def esc(count3: int):
        return decoded(
            MAV.esc_telemetry_5_to_8_encode(
                [30] * 4,
                [1200, 1200, 0, 0],
                [200, 200, 0, 0],
                [0] * 4,
                [6000, 6000, 0, 0],
                [count3, count3, 0, 0],
            )
        )

    assert {s.motor for s in a.feed(esc(1), 0.0)} == {5, 6}  # slots 7 and 8: never reported
    assert {s.motor for s in a.feed(esc(2), 0.02)} == {5, 6}  # the count moves
    assert a.feed(esc(2), 0.04) == []  # frozen count: repeated values, not a sample
    assert a.repeats == 2


def test_px4_esc_status_and_battery_fallback():
    a = SampleAssembler(motors=6)
    a.feed(decoded(MAV.sys_status_encode(0, 0, 0, 0, 15800, 0, 50, 0, 0, 0, 0, 0, 0)), 0.0)
    a.feed(servo([1500] * 6), 0.0)
    # ESC_STATUS as PX4 sends it (common.xml, id 291; carried by our dialect since pymavlink lacks it)
    generated = dialect.load()
    assert generated.MAVLink_esc_status_message.crc_extra == 10  # common.xml's: real PX4 frames pass the CRC
    dialect.register(mavlink2)
    px4 = generated.MAVLink(None, 1, 1)
    buf = generated.MAVLink_esc_status_message(
        4, 0, [6000, 6100, 0, 0], [0.0] * 4, [2.0, 2.0, 0.0, 0.0]
    ).pack(px4)
    msg = mavlink2.MAVLink(None, 0, 0).parse_buffer(buf)[0]
    assert msg.get_type() == "ESC_STATUS"
    samples = {s.motor: s for s in a.feed(msg, 0.5)}  # the command is 0.5 s old (at most 1 s)
    assert set(samples) == {5, 6}  # ESCs 5-8 in this message; 7 and 8 are beyond the hexacopter
    assert samples[5].bus_voltage_v == pytest.approx(15.8)  # ESC reports no voltage: the battery's
    assert samples[5].current_a == pytest.approx(4.0)


def test_no_command_yet_means_no_voltage_and_no_current():
    a = SampleAssembler(motors=6)
    msg = decoded(
        MAV.esc_telemetry_1_to_4_encode([30] * 4, [1200] * 4, [300] * 4, [0] * 4, [6000] * 4, [1] * 4)
    )
    s = a.feed(msg, 0.0)[0]
    assert math.isnan(s.voltage_v) and math.isnan(s.current_a) and s.omega_rad_s > 0


def heartbeat(autopilot: int, mav_type: int = 13, system: int = 1, component: int = 1):
    mav = mavlink2.MAVLink(None, system, component)
    return mavlink2.MAVLink(None, 0, 0).parse_buffer(
        mav.heartbeat_encode(mav_type, autopilot, 0, 0, 4).pack(mav)
    )[0]


def test_tracker_finds_the_autopilot_loses_it_and_sees_it_reboot():
    tr = AutopilotTracker(heartbeat_timeout_s=3.0)
    assert tr.on_message(heartbeat(8, mav_type=6, system=255, component=190), 0.0) is None  # a GCS
    assert tr.on_message(heartbeat(12), 0.5) == "found" and tr.autopilot == "px4"
    assert tr.check(3.0) is None and tr.check(3.6) == "lost"
    assert tr.on_message(heartbeat(12), 4.0) == "returned"
    mav = mavlink2.MAVLink(None, 1, 1)

    def system_time(ms: int):
        return mavlink2.MAVLink(None, 0, 0).parse_buffer(mav.system_time_encode(0, ms).pack(mav))[0]

    assert tr.on_message(system_time(50_000), 5.0) is None
    assert tr.on_message(system_time(51_000), 6.0) is None
    assert tr.on_message(system_time(800), 7.0) == "rebooted" and tr.reboots == 1


def test_stream_requests_and_parameters_per_autopilot():
    ardupilot = dict(stream_requests("ardupilot", 50.0))
    assert ardupilot[11030] == 50.0 and ardupilot[36] == 50.0 and 291 not in ardupilot
    px4 = dict(stream_requests("px4", 25.0))
    assert px4[291] == 25.0 and 290 in px4 and 11030 not in px4
    assert "MOT_PWM_MIN" in wanted_params("ardupilot", 6) and wanted_params("px4", 6) == []
