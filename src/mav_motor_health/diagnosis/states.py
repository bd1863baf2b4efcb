"""The motor states the diagnosis names (paper section III, Fig. 7), with stable integer codes."""

from __future__ import annotations

import enum

import numpy as np
from numpy.typing import NDArray

__all__ = ["Code", "MotorState", "state_names"]


class MotorState(enum.IntEnum):
    """States of one motor. Integer codes are stable (they go into MAVLink NAMED_VALUE_INT and files)."""

    NORMAL = 0
    F1_1 = 1  # bearing friction increase
    F2_1 = 2  # phase open
    F3_1 = 3  # propeller damage
    F4_1 = 4  # transistor open
    F4_2 = 5  # back-EMF signal error
    UNKNOWN = 6  # a combination the tree does not name
    NO_DATA = 7  # telemetry missing or stale
    SENSOR_FAULT = 8  # a signal is implausible: the sensor, not the motor, is suspect
    SLOW = 9  # speed only (no trusted current): slower than the command should give: F1.1 or F4.1
    STALLED = 10  # speed only: stopped although commanded: F2.1 or F4.2
    FAST = 11  # speed only: faster than the command should give: F3.1
    UNCALIBRATED = 12  # the motor model does not describe this vehicle: no fault can be named

    @property
    def label(self) -> str:
        """The paper's name: ``F3.1``, ``NORMAL``..."""
        return _LABELS[self]

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]

    @property
    def is_fault(self) -> bool:
        return self in _FAULTS

    @classmethod
    def from_label(cls, label: str) -> MotorState:
        try:
            return _BY_LABEL[label.strip().upper()]
        except KeyError:
            raise ValueError(
                f"unknown motor state {label!r}; expected one of {', '.join(_BY_LABEL)}"
            ) from None


_LABELS = {
    MotorState.NORMAL: "NORMAL",
    MotorState.F1_1: "F1.1",
    MotorState.F2_1: "F2.1",
    MotorState.F3_1: "F3.1",
    MotorState.F4_1: "F4.1",
    MotorState.F4_2: "F4.2",
    MotorState.UNKNOWN: "UNKNOWN",
    MotorState.NO_DATA: "NO_DATA",
    MotorState.SENSOR_FAULT: "SENSOR_FAULT",
    MotorState.SLOW: "SLOW",
    MotorState.STALLED: "STALLED",
    MotorState.FAST: "FAST",
    MotorState.UNCALIBRATED: "UNCALIBRATED",
}
_DESCRIPTIONS = {
    MotorState.NORMAL: "normal",
    MotorState.F1_1: "bearing friction",
    MotorState.F2_1: "phase open",
    MotorState.F3_1: "propeller damage",
    MotorState.F4_1: "transistor open",
    MotorState.F4_2: "back-EMF signal error",
    MotorState.UNKNOWN: "unknown fault",
    MotorState.NO_DATA: "no telemetry",
    MotorState.SENSOR_FAULT: "sensor implausible",
    MotorState.SLOW: "slow (F1.1 or F4.1)",
    MotorState.STALLED: "stalled (F2.1 or F4.2)",
    MotorState.FAST: "fast (F3.1)",
    MotorState.UNCALIBRATED: "model does not fit this vehicle",
}
_BY_LABEL = {label: state for state, label in _LABELS.items()}
_FAULTS = frozenset(
    {
        MotorState.F1_1,
        MotorState.F2_1,
        MotorState.F3_1,
        MotorState.F4_1,
        MotorState.F4_2,
        MotorState.UNKNOWN,
        MotorState.SLOW,
        MotorState.STALLED,
        MotorState.FAST,
    }
)


class Code:
    """Each :class:`MotorState`'s code as a plain ``int``, for numpy expressions on the core's hot paths.

    An enum member as a numpy operand (``state == MotorState.F1_1``, ``np.where(..., MotorState.NORMAL,
    ...)``) costs about 1.5–2.5 µs more than an int on Python 3.11: numpy looks up ``__array_ufunc__`` and
    ``__array_function__`` on its type, and the enum's metaclass answers each miss by raising
    AttributeError. A core call of the live agent made about a hundred such lookups (issue 18)."""

    # (in the enum's order: tests/test_arrays.py checks each name's code)
    (
        NORMAL,
        F1_1,
        F2_1,
        F3_1,
        F4_1,
        F4_2,
        UNKNOWN,
        NO_DATA,
        SENSOR_FAULT,
        SLOW,
        STALLED,
        FAST,
        UNCALIBRATED,
    ) = map(int, MotorState)


def state_names(codes: NDArray[np.integer]) -> NDArray[np.str_]:
    """Labels (``"F3.1"``...) for an array of state codes."""
    table = np.array([_LABELS[s] for s in MotorState])
    return table[np.asarray(codes, dtype=np.int64)]
