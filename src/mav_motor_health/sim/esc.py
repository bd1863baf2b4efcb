"""The ESC as a PWM switch: the motor sees duty × bus voltage; the ESC draws about duty × motor current.

ArduPilot sends each ESC a pulse width between ``MOT_PWM_MIN`` and ``MOT_PWM_MAX``; the ESC maps it
linearly to a duty cycle. Averaged over a PWM period the motor sees ``duty·V_bus`` and, by power balance
of an ideal switch, the ESC's input current is ``duty·i_motor`` (plus a small quiescent current). This is
what a real ESC's telemetry reports as its current (sim/sensors.py: filtered, unsigned).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["PWM_MAX_US", "PWM_MIN_US", "duty_from_pwm", "esc_input_current_a", "pwm_from_duty"]

PWM_MIN_US = 1000.0
PWM_MAX_US = 2000.0
#: the ESC's own consumption [A]
QUIESCENT_A = 0.02


def duty_from_pwm(
    pwm_us: ArrayLike, low_us: float = PWM_MIN_US, high_us: float = PWM_MAX_US
) -> NDArray[np.float64]:
    return np.clip((np.asarray(pwm_us, dtype=float) - low_us) / (high_us - low_us), 0.0, 1.0)


def pwm_from_duty(
    duty: ArrayLike, low_us: float = PWM_MIN_US, high_us: float = PWM_MAX_US
) -> NDArray[np.float64]:
    return low_us + np.clip(np.asarray(duty, dtype=float), 0.0, 1.0) * (high_us - low_us)


def esc_input_current_a(duty: ArrayLike, motor_current_a: ArrayLike) -> NDArray[np.float64]:
    """Battery-side current of one ESC: ``duty × motor current`` plus its own consumption; negative while
    the motor brakes (the simulated motor's current turns negative when its back-EMF exceeds its input,
    as with the complementary PWM of BLHeli/AM32 ESCs, and flows back to the bus)."""
    return np.asarray(duty, dtype=float) * np.asarray(motor_current_a, dtype=float) + QUIESCENT_A
