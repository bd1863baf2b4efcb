"""Where each motor sits on the airframe, as the autopilot numbers them (pure data, no I/O).

ArduPilot ``AP_MotorsMatrix::setup_hexa_matrix`` for ``MOTOR_FRAME_TYPE_X`` (FRAME_CLASS 2, FRAME_TYPE 1)
adds the motors as ``{angle, yaw factor, testing order}``::

    motor 1   90°  CW       motor 4  150°  CCW
    motor 2  -90°  CCW      motor 5   30°  CCW
    motor 3  -30°  CW       motor 6 -150°  CW

The angle is measured from the nose, positive towards the right wing (clockwise seen from above);
``AP_MOTORS_MATRIX_YAW_FACTOR_CW`` marks a propeller that turns clockwise seen from above. Hexa-plus
(FRAME_TYPE 0, what ArduPilot SITL's ``--model hexa`` flies) and quad-X come from the same source; PX4's
quad-X numbering is the same as ArduPilot's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

__all__ = ["ARDUPILOT_FRAMES", "FRAMES", "HEXA_PLUS", "HEXA_X", "QUAD_X", "MotorPosition", "layout_for_log"]


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

#: ArduPilot hexa-plus (MOTOR_FRAME_HEXA / MOTOR_FRAME_TYPE_PLUS).
HEXA_PLUS: tuple[MotorPosition, ...] = (
    MotorPosition(1, 0.0, "CW", 1),
    MotorPosition(2, 180.0, "CCW", 4),
    MotorPosition(3, -120.0, "CW", 5),
    MotorPosition(4, 60.0, "CCW", 2),
    MotorPosition(5, -60.0, "CCW", 6),
    MotorPosition(6, 120.0, "CW", 3),
)

#: ArduPilot quad-X (MOTOR_FRAME_QUAD / MOTOR_FRAME_TYPE_X).
QUAD_X: tuple[MotorPosition, ...] = (
    MotorPosition(1, 45.0, "CCW", 1),
    MotorPosition(2, -135.0, "CCW", 3),
    MotorPosition(3, -45.0, "CW", 4),
    MotorPosition(4, 135.0, "CW", 2),
)

#: Frame names as the agent announces them in ``mmh/<vehicle>/info`` → layout.
FRAMES: dict[str, tuple[MotorPosition, ...]] = {"hexa-x": HEXA_X, "hexa-plus": HEXA_PLUS, "quad-x": QUAD_X}

#: ArduPilot (FRAME_CLASS, FRAME_TYPE) → frame name.
ARDUPILOT_FRAMES: dict[tuple[int, int], str] = {(2, 1): "hexa-x", (2, 0): "hexa-plus", (1, 1): "quad-x"}


def layout_for_log(meta: Mapping[str, Any], motors: Sequence[int]) -> tuple[str | None, str]:
    """The frame to draw a log's motors on, and a note when it is a guess (or none fits).

    ArduPilot logs say their frame (``FRAME_CLASS``/``FRAME_TYPE`` parameters in ``meta["params"]``);
    otherwise six motors are drawn as hexa-X and four as quad-X, and the note says so.
    """
    params = meta.get("params") or {}
    vehicle = meta.get("vehicle") or {}
    frame_class = params.get("FRAME_CLASS", vehicle.get("frame_class"))
    frame_type = params.get("FRAME_TYPE", vehicle.get("frame_type"))
    if frame_class is not None and frame_type is not None:
        try:
            key = (int(frame_class), int(frame_type))
        except (TypeError, ValueError):
            key = (-1, -1)
        name = ARDUPILOT_FRAMES.get(key)
        if name is not None and set(motors) <= {m.number for m in FRAMES[name]}:
            return name, ""
        return None, f"FRAME_CLASS {frame_class} / FRAME_TYPE {frame_type} has no top view here"
    count = max(motors, default=0)
    if count in (5, 6):
        return "hexa-x", "the log does not name its frame: drawn as ArduPilot hexa-X"
    if count in (3, 4):
        return "quad-x", "the log does not name its frame: drawn as quad-X"
    return None, f"no top view for a vehicle with {count} motors"
