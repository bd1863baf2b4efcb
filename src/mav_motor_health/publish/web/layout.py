"""Where each motor sits on the airframe, as the autopilot numbers them (pure data, no I/O).

ArduPilot ``AP_MotorsMatrix::setup_hexa_matrix`` for ``MOTOR_FRAME_TYPE_X`` (FRAME_CLASS 2, FRAME_TYPE 1)
adds the motors as ``{angle, yaw factor, testing order}``::

    motor 1   90°  CW       motor 4  150°  CCW
    motor 2  -90°  CCW      motor 5   30°  CCW
    motor 3  -30°  CW       motor 6 -150°  CW

The angle is measured from the nose, positive towards the right wing (clockwise seen from above);
``AP_MOTORS_MATRIX_YAW_FACTOR_CW`` marks a propeller that turns clockwise seen from above.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

__all__ = ["FRAMES", "HEXA_X", "MotorPosition"]


@dataclass(frozen=True)
class MotorPosition:
    """One motor: its number (1-based, as in SERVOn_FUNCTION 33+n-1), bearing from the nose and spin."""

    number: int
    angle_deg: float
    spin: Literal["CW", "CCW"]
    testing_order: int

    @property
    def right_forward(self) -> tuple[float, float]:
        """Unit position (right, forward) of the motor seen from above."""
        a = math.radians(self.angle_deg)
        return math.sin(a), math.cos(a)

    def to_dict(self) -> dict[str, object]:
        return {
            "motor": self.number,
            "angle_deg": self.angle_deg,
            "spin": self.spin,
            "testing_order": self.testing_order,
        }


#: ArduPilot hexa-X (AP_MotorsMatrix, MOTOR_FRAME_HEXA / MOTOR_FRAME_TYPE_X).
HEXA_X: tuple[MotorPosition, ...] = (
    MotorPosition(1, 90.0, "CW", 2),
    MotorPosition(2, -90.0, "CCW", 5),
    MotorPosition(3, -30.0, "CW", 6),
    MotorPosition(4, 150.0, "CCW", 3),
    MotorPosition(5, 30.0, "CCW", 1),
    MotorPosition(6, -150.0, "CW", 4),
)

#: Frame names as the agent announces them in ``mmh/<vehicle>/info`` → layout.
FRAMES: dict[str, tuple[MotorPosition, ...]] = {"hexa-x": HEXA_X}
