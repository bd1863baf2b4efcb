"""The monitor lays every motor's samples out as the core's rows in one call (issue 18): the same rows and
changes as the per-motor batches it builds where the motors do not go together (models of different types)."""

from __future__ import annotations

import struct
from itertools import cycle
from pathlib import Path

import pytest
from flightlog import make_fields, write_tlog
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from mav_motor_health.agent.monitor import HealthMonitor
from mav_motor_health.agent.samples import SampleAssembler
from mav_motor_health.config import load_profile
from mav_motor_health.diagnosis.states import MotorState


def tlog_messages(path: Path) -> list[tuple[float, object]]:
    """A .tlog's messages with their times (seconds from the first record), as the agent reads them."""
    data = path.read_bytes()
    parser = mavlink2.MAVLink(None, 0, 0)
    out, pos, origin = [], 0, None
    while pos + 9 <= len(data):
        (stamp,) = struct.unpack_from(">Q", data, pos)
        size = 10 + data[pos + 9] + 2 + (13 if data[pos + 10] & 1 else 0)
        origin = stamp if origin is None else origin
        out += [
            ((stamp - origin) / 1e6, m) for m in parser.parse_buffer(data[pos + 8 : pos + 8 + size]) or []
        ]
        pos += 8 + size
    return out


@pytest.mark.parametrize("profile", ["flight", "testbed"])
def test_all_motors_in_one_call_give_what_per_motor_batches_give(tmp_path, paper_motor, profile, monkeypatch):
    messages = tlog_messages(write_tlog(make_fields(paper_motor), tmp_path / "flight.tlog"))
    prof = load_profile(profile)
    shared = HealthMonitor(paper_motor, prof, 6)  # one model: every motor in one core call, laid out
    # a model per motor (equal, not the same object), the monitor's other path: a batch per motor
    # (update_motors, which lays the batches out itself), as for motors that do not go together
    own = HealthMonitor({m: paper_motor.replace() for m in range(1, 7)}, prof, 6)
    assert shared.diagnoser.together([1, 2, 3]) and own.diagnoser.together([1, 2, 3])  # one type
    monkeypatch.setattr(own.diagnoser, "together", lambda motors: False)
    assembler = SampleAssembler(6)
    rows_shared, rows_own, changes_shared, changes_own = [], [], [], []
    sizes = cycle([1, 7, 23, 60, 3])  # calls of a message or a few (motors missing), and longer ones
    pos, calls = 0, 0
    while pos < len(messages):
        size = next(sizes)
        for t, msg in messages[pos : pos + size]:
            assembler.add(msg, t)
        pos += size
        columns = assembler.take()
        for monitor, rows, changes in ((shared, rows_shared, changes_shared), (own, rows_own, changes_own)):
            got_rows, got_changes = monitor.feed_columns(columns, rows=calls % 2 == 0)
            rows += got_rows
            changes += got_changes
        calls += 1
    assert len(rows_shared) > 1000 and repr(rows_shared) == repr(rows_own)  # NaN: compared as text
    assert repr(changes_shared) == repr(changes_own)
    assert repr({n: s.row for n, s in shared.status.items()}) == repr(
        {n: s.row for n, s in own.status.items()}
    )
    # the flight holds faults, announced: the comparison is not of NORMAL rows alone
    assert {MotorState.F3_1, MotorState.F2_1} <= {c.state for c in changes_shared}
    if profile == "flight":  # the balance rule: each change says which equation the motor departs in
        lost = [c for c in changes_shared if c.state == MotorState.F3_1]
        assert all(set(c.evidence) >= {"torque_residual_nm", "voltage_residual_v"} for c in changes_shared)
        # a lighter propeller: torque the model has too much of
        assert lost[0].evidence["torque_residual_nm"] < 0
