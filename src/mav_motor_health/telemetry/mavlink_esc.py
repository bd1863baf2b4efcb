"""What MAVLink and ArduPilot logs say about motors, in SI units: shared by the log readers and the live link.

(The rules that turn MAVLink messages into motor samples, for the .tlog reader and the live agent, are
:mod:`.mavlink_messages`; this module holds the units and mappings they and the DataFlash reader use.)

* ``ESC_TELEMETRY_1_TO_4`` (11030), ``_5_TO_8`` (11031), ``_9_TO_12`` (11032) — ArduPilot dialect:
  per ESC ``temperature`` [°C], ``voltage`` [cV], ``current`` [cA], ``totalcurrent`` [mAh], ``rpm``
  [1/min, mechanical: ArduPilot divides eRPM by the pole pairs itself], ``count``.
* ``SERVO_OUTPUT_RAW``: ``servoN_raw`` [µs], the per-output command.
* ArduPilot numbers ESC telemetry by servo output, so ESC slot ``j`` (0-based) is output ``j+1`` and
  the motor is ``SERVO{j+1}_FUNCTION − 32`` (functions 33–44 are Motor1–Motor12). Without parameters,
  output ``n`` drives motor ``n`` (ArduPilot's default for a hexacopter).
* PX4 numbers ESCs by ``esc_status.esc[i]``; each report's ``actuator_function`` says what it drives:
  101–112 are Motor1–Motor12 (motor = function − 100; 0 means "not set": ESC ``i`` is then motor ``i+1``).
* The number of motors follows from the ``SERVOn_FUNCTION`` parameters, or else from ``FRAME_CLASS``
  (1 quad, 2 hexa, 3 octa, 4 octa-quad, 5 Y6, 7 tri, 12 dodeca-hexa, 14 deca).
* Throttle is ``(pwm − MOT_PWM_MIN) / (MOT_PWM_MAX − MOT_PWM_MIN)``, clipped to 0..1. ArduPilot uses the
  throttle channel's range when MOT_PWM_MIN/MAX are 0; the defaults here are 1000 and 2000 µs.
* What the motor sees (:func:`motor_inputs`): the ESC chops the bus voltage, so the motor's effective
  voltage is ``throttle × bus_voltage_v`` and, power being conserved across the ESC, the motor current is
  ``esc_current_a / throttle``. Below ``min_throttle`` the division is meaningless (current NaN).
* PX4's ``ESC_STATUS`` (291) carries per ESC ``rpm`` [1/min], ``voltage`` [V] and ``current`` [A] as
  floats, four ESCs per message from ``index``; ESC slot ``j`` is motor ``j+1`` by default.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..model.esc import DEFAULT_MIN_DUTY, motor_current_a, motor_voltage_v

__all__ = [
    "ESC_TELEMETRY_MESSAGES",
    "MIN_THROTTLE_FOR_CURRENT",
    "MOTOR_FUNCTION_FIRST",
    "PX4_MOTOR_FUNCTION_FIRST",
    "RPM_TO_RAD_S",
    "esc_fields_to_si",
    "expected_motors",
    "motor_for_output",
    "motor_for_px4_function",
    "motor_inputs",
    "pwm_range",
    "throttle_from_pwm",
]

RPM_TO_RAD_S = 2.0 * math.pi / 60.0
#: ESC telemetry message name → index of its first ESC slot.
ESC_TELEMETRY_MESSAGES = {"ESC_TELEMETRY_1_TO_4": 0, "ESC_TELEMETRY_5_TO_8": 4, "ESC_TELEMETRY_9_TO_12": 8}
#: SERVOn_FUNCTION value of Motor1 (Motor2 = 34 ... Motor12 = 44 in ArduPilot's SRV_Channel list).
MOTOR_FUNCTION_FIRST = 33
#: PX4 ``actuator_function`` value of Motor1 (Motor2 = 102 ...).
PX4_MOTOR_FUNCTION_FIRST = 101
#: ArduPilot ``FRAME_CLASS`` → number of motors.
FRAME_CLASS_MOTORS = {1: 4, 2: 6, 3: 8, 4: 8, 5: 6, 7: 3, 10: 2, 12: 12, 14: 10}
DEFAULT_PWM_MIN_US = 1000.0
DEFAULT_PWM_MAX_US = 2000.0


def motor_for_output(output: int, params: Mapping[str, float] | None = None) -> int | None:
    """Motor number (1-based) driven by servo output ``output`` (1-based), or None if it drives no motor."""
    function = None if params is None else params.get(f"SERVO{output}_FUNCTION")
    if function is None or not math.isfinite(function):
        return output  # ArduPilot's default: output n is motor n (also where the value was damaged)
    function = int(function)
    if MOTOR_FUNCTION_FIRST <= function < MOTOR_FUNCTION_FIRST + 12:
        return function - MOTOR_FUNCTION_FIRST + 1
    return None


def motor_for_px4_function(function: int, esc_index: int) -> int | None:
    """Motor number (1-based) of PX4 ESC ``esc_index`` (0-based) from its ``actuator_function``."""
    if function == 0:
        return esc_index + 1  # not reported: PX4's default order
    if PX4_MOTOR_FUNCTION_FIRST <= function < PX4_MOTOR_FUNCTION_FIRST + 12:
        return function - PX4_MOTOR_FUNCTION_FIRST + 1
    return None


def expected_motors(params: Mapping[str, float] | None = None, outputs: int = 16) -> list[int]:
    """The motor numbers a vehicle has, from its ``SERVOn_FUNCTION`` or ``FRAME_CLASS`` parameters."""
    params = params or {}
    motors = {
        m
        for n in range(1, outputs + 1)
        if f"SERVO{n}_FUNCTION" in params and (m := motor_for_output(n, params)) is not None
    }
    if motors:
        return sorted(motors)
    count = FRAME_CLASS_MOTORS.get(int(params.get("FRAME_CLASS", 0) or 0))
    return list(range(1, count + 1)) if count else []


def pwm_range(params: Mapping[str, float] | None = None) -> tuple[float, float]:
    """The ESC's PWM range [µs] from ``MOT_PWM_MIN``/``MOT_PWM_MAX`` (0 or missing: 1000/2000 µs)."""
    params = params or {}
    low = (
        float(params.get("MOT_PWM_MIN", 0) or 0) or float(params.get("RC3_MIN", 0) or 0) or DEFAULT_PWM_MIN_US
    )
    high = (
        float(params.get("MOT_PWM_MAX", 0) or 0) or float(params.get("RC3_MAX", 0) or 0) or DEFAULT_PWM_MAX_US
    )
    if high <= low:
        return DEFAULT_PWM_MIN_US, DEFAULT_PWM_MAX_US
    return low, high


def throttle_from_pwm(pwm_us: ArrayLike, low_us: float, high_us: float) -> NDArray[np.float64]:
    """Normalised command 0..1 from a PWM pulse width; 0 µs (output off) gives 0."""
    pwm = np.asarray(pwm_us, dtype=float)
    return np.minimum(np.maximum((pwm - low_us) / (high_us - low_us), 0.0), 1.0)  # np.clip, less overhead


def esc_fields_to_si(
    temperature_c: ArrayLike, voltage_cv: ArrayLike, current_ca: ArrayLike, rpm: ArrayLike
) -> dict[str, NDArray[np.float64]]:
    """ESC_TELEMETRY raw fields to table columns (``bus_voltage_v`` is the ESC's input voltage)."""
    return {
        "esc_temp_c": np.asarray(temperature_c, dtype=float),
        "bus_voltage_v": np.asarray(voltage_cv, dtype=float) / 100.0,
        "esc_current_a": np.asarray(current_ca, dtype=float) / 100.0,
        "omega_rad_s": np.asarray(rpm, dtype=float) * RPM_TO_RAD_S,
    }


#: Below this command the ESC current says nothing about the motor current (see :func:`motor_inputs`).
MIN_THROTTLE_FOR_CURRENT = DEFAULT_MIN_DUTY


def motor_inputs(
    throttle: ArrayLike,
    bus_voltage_v: ArrayLike,
    esc_current_a: ArrayLike,
    min_throttle: float = MIN_THROTTLE_FOR_CURRENT,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Effective motor voltage [V] and motor current [A] from the command, bus voltage and ESC current.

    The ESC as an ideal PWM stage (:mod:`..model.esc`): ``voltage_v = throttle × bus_voltage_v``;
    ``current_a = esc_current_a / throttle`` (NaN where the throttle is below ``min_throttle`` or unknown).
    """
    return motor_voltage_v(throttle, bus_voltage_v), motor_current_a(esc_current_a, throttle, min_throttle)
