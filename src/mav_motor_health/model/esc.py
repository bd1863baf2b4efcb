"""The ESC as an ideal PWM stage: what the motor sees, from what ESC telemetry reports.

ESC telemetry reports the ESC's *input* (DC bus) voltage and current, not the motor's. With the ESC
switching the bus at duty d (the normalised motor command, 0..1):

* effective motor voltage  V_m = d · V_bus
* motor current            i_m = i_esc / d      (power balance of a lossless stage: V_bus·i_esc = V_m·i_m)

Assumptions and limits, which docs/flight.md discusses: the command maps linearly to duty (true of
BLHeli/AM32 with calibrated endpoints and of DShot; not of ESCs with a throttle curve or active braking
set up differently); switching and conduction losses are neglected (a few per cent, absorbed by the fitted
R); below ``min_duty`` the division amplifies the current sensor's offset and noise without bound, so
the motor current is left undefined (NaN) there; and an ESC reports its input current *averaged*, the
mean of duty × current, so where the command zigzags between control steps the quotient with the
sample's duty reads high (duty and current rise together). The flight rule therefore never divides: it
weights the model by the duty (:mod:`.balance`); the quotient serves display, the stall current and the
testbed rules.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["DEFAULT_MIN_DUTY", "motor_current_a", "motor_voltage_v"]

DEFAULT_MIN_DUTY = 0.05


def motor_voltage_v(duty: ArrayLike, bus_voltage_v: ArrayLike) -> NDArray[np.float64]:
    """Effective motor voltage [V] = duty × bus voltage (duty clipped to 0..1)."""
    return np.clip(np.asarray(duty, dtype=float), 0.0, 1.0) * np.asarray(bus_voltage_v, dtype=float)


def motor_current_a(
    esc_current_a: ArrayLike, duty: ArrayLike, min_duty: float = DEFAULT_MIN_DUTY
) -> NDArray[np.float64]:
    """Motor current [A] = ESC input current / duty; NaN where the duty is below ``min_duty``."""
    d = np.clip(np.asarray(duty, dtype=float), 0.0, 1.0)
    i = np.asarray(esc_current_a, dtype=float)
    safe = np.where(d >= min_duty, d, np.nan)
    return i / safe
