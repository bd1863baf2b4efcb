"""STATUSTEXT wording, severity and rate limit; NAMED_VALUE names; the MOTOR_HEALTH dialect."""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.publish import dialect
from mav_motor_health.publish.mavlink_health import (
    MAV_SEVERITY_CRITICAL,
    MAV_SEVERITY_INFO,
    MAV_SEVERITY_WARNING,
    StatustextGate,
    TokenBucket,
    motor_health_message,
    named_value_messages,
    severity_for,
    statustext_for,
    statustext_message,
)


def test_statustext_lines_fit_mavlink_and_name_the_fault():
    assert statustext_for(3, MotorState.F3_1) == "Motor 3: propeller damage (F3.1)"
    for motor in range(1, 13):
        for state in MotorState:
            text = statustext_for(motor, state)
            assert len(text) <= 50, text
            assert text.startswith(f"Motor {motor}: ")
            assert text.isascii()


def test_severity_stopped_motor_critical_degraded_warning_normal_info():
    assert severity_for(MotorState.F2_1) == severity_for(MotorState.F4_2) == MAV_SEVERITY_CRITICAL
    for state in (MotorState.F1_1, MotorState.F3_1, MotorState.F4_1, MotorState.UNKNOWN, MotorState.NO_DATA):
        assert severity_for(state) == MAV_SEVERITY_WARNING
    assert severity_for(MotorState.NORMAL) == MAV_SEVERITY_INFO


def test_statustext_round_trips_through_pymavlink():
    mav = mavlink2.MAVLink(None, 1, 191)
    buf = statustext_message(mav, statustext_for(5, MotorState.F4_2), MAV_SEVERITY_CRITICAL).pack(mav)
    msg = mavlink2.MAVLink(None, 0, 0).parse_buffer(buf)[0]
    assert (msg.text, msg.severity, msg.get_srcComponent()) == (
        "Motor 5: back-EMF signal error (F4.2)",
        2,
        191,
    )


def test_token_bucket_allows_a_burst_then_the_refill_rate():
    bucket = TokenBucket(capacity=3, rate_per_s=0.5)
    assert [bucket.take(0.0) for _ in range(4)] == [True, True, True, False]
    assert not bucket.take(1.0)
    assert bucket.take(2.01)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 0.5), st.sampled_from(list(MotorState))), min_size=1, max_size=300))
def test_a_flapping_motor_cannot_flood_the_link_and_its_last_state_is_told(steps):
    gate = StatustextGate(burst=3, interval_s=5.0)
    now, sent, last = 0.0, [], None
    for dt, state in steps:
        now += dt
        last = state
        if gate.offer(1, state, now):
            sent.append((now, state))
        sent.extend((now, s) for _, s in gate.due(now))
    # at most burst + elapsed/interval lines
    assert len(sent) <= 3 + now / 5.0 + 1e-9
    # nobody is told the same state twice in a row
    assert all(a[1] != b[1] for a, b in zip(sent, sent[1:]))
    # once the flapping stops, the latest state goes out within one interval
    gate.due(now + 5.0)
    assert gate.last_sent[1] == last and not gate.pending


def test_named_values_have_short_names_and_carry_code_and_model_error():
    mav = mavlink2.MAVLink(None, 1, 191)
    row = {"omega_rad_s": 700.0, "omega_model_rad_s": 650.0, "current_a": 1.0, "current_model_a": 7.0}
    msgs = named_value_messages(mav, 1234, 3, MotorState.F3_1, row)
    parser = mavlink2.MAVLink(None, 0, 0)
    decoded = [parser.parse_buffer(m.pack(mav))[0] for m in msgs]
    by_name = {m.name: m.value for m in decoded}
    assert by_name["MH_M3"] == 3
    assert by_name["MH_W3"] == pytest.approx(50.0)
    assert by_name["MH_I3"] == pytest.approx(-6.0)
    assert all(len(name) <= 10 for name in by_name)


def test_the_dialect_xml_is_valid_and_its_states_are_the_motor_states():
    tree = ET.parse(dialect.XML_PATH)
    entries = {
        int(e.get("value")): e.get("name")
        for e in tree.getroot().iter("entry")
        if e.get("name", "").startswith("MOTOR_HEALTH_STATE_")
    }
    assert entries == {int(s): "MOTOR_HEALTH_STATE_" + s.name for s in MotorState}
    message = tree.getroot().find("messages/message[@name='MOTOR_HEALTH']")
    assert message is not None and int(message.get("id")) == dialect.MOTOR_HEALTH_ID
    assert re.fullmatch(r"[A-Z_]+", message.get("name"))


def test_pymavlink_generates_encodes_and_decodes_motor_health():
    generated = dialect.load()
    mav = mavlink2.MAVLink(None, 7, 191)
    row = {
        "omega_rad_s": 700.0,
        "omega_model_rad_s": 650.0,
        "current_a": 1.0,
        "current_model_a": 7.0,
        "voltage_v": 7.2,
        "state": 3,
        "steady": True,
    }
    buf = motor_health_message(generated, 5000, 3, MotorState.F3_1, 1.5, True, row).pack(mav)
    assert buf[0] == 0xFD  # MAVLink 2: the id does not fit MAVLink 1
    # a receiver on the generated dialect alone ...
    msg = generated.MAVLink(None, 0, 0).parse_buffer(buf)[0]
    assert (msg.motor, msg.state, msg.raw_state, msg.flags) == (3, 3, 3, 3)
    assert msg.omega == pytest.approx(700.0) and msg.since == pytest.approx(1.5)
    # ... and one that keeps ardupilotmega and registers MOTOR_HEALTH
    dialect.register(mavlink2)
    msg2 = mavlink2.MAVLink(None, 0, 0).parse_buffer(buf)[0]
    assert msg2.get_type() == "MOTOR_HEALTH" and msg2.get_srcSystem() == 7
    assert math.isclose(msg2.current_model, 7.0)
