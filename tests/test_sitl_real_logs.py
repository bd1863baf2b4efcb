"""Real ArduPilot firmware (SITL) logs: motor 1's thrust halved from 110.1 s to 130.2 s (see MANIFEST).

Stock SITL reports 0.80 A for every ESC whatever the load: the current must be reported untrustworthy and
the diagnosis must find motor 1 from speed alone, and no other motor.
"""

from __future__ import annotations

import numpy as np
import pytest

from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.diagnosis import MotorState, diagnose
from mav_motor_health.diagnosis.calibration import calibrate
from mav_motor_health.diagnosis.plausibility import SensorIssue
from mav_motor_health.telemetry import sources

# (file, calibration window: take-off and hover before the fault, fault window) on each file's own clock.
# The .tlog clock runs 2.9 s behind the .bin one (motor 1 command crosses 0.7 at 111.1 s vs 114.0 s).
CASES = [
    ("hexa_motor1_half.bin", (38.0, 108.0), (110.1, 130.2)),
    ("hexa_motor1_half.tlog", (35.0, 105.0), (107.2, 127.3)),
]


@pytest.mark.parametrize(("name", "hover", "fault"), CASES)
def test_motor1_found_from_speed_alone(real_logs, name, hover, fault) -> None:
    table = sources.read(real_logs / "ardupilot_sitl" / name)
    cal = calibrate(table, load_motor_params(), *hover)
    assert cal.speed_only and cal.current_trusted_share < 0.1
    result = diagnose(table, cal.params, load_profile("flight"))
    flying = result["time_s"] > hover[0] + 5.0
    for motor in range(1, 7):
        sel = result["motor"] == motor
        flags = result["sensor_flags"][sel & flying]
        assert np.mean((flags & SensorIssue.CURRENT_STUCK) != 0) > 0.9  # the constant 0.80 A is reported
        announced = result["announced"][sel]
        faults = {MotorState(int(s)) for s in announced if MotorState(int(s)).is_fault}
        t = result["time_s"][sel]
        if motor == 1:
            assert faults == {MotorState.SLOW}
            first = t[announced == MotorState.SLOW].min()
            assert fault[0] < first < fault[0] + 6.0  # while the autopilot is still raising its command
            during = (t >= first) & (t < fault[1])
            assert np.mean(announced[during] == MotorState.SLOW) > 0.95
            assert announced[-1] == MotorState.NORMAL  # cleared after recovery
        else:
            assert faults == set(), f"motor {motor} announced {faults}"
