"""Steady-state measurements as the paper's testbed took them: fixed input voltages, noisy sensors.

The noise follows section III.B: speed about ±10 rad/s; current from ±0.15 A at the lowest input to
±1.0 A at the highest, growing linearly with the input voltage. "±a" is read as a uniform spread of
half-width a (a bound, as the paper uses it to set its bands at twice the noise).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..model.equations import steady_state
from ..model.params import MotorParams

__all__ = ["PAPER_VOLTAGES_V", "SensorNoise", "steady_measurements"]

#: The paper's 11 equally spaced estimation points over 4–11 V (section II.B).
PAPER_VOLTAGES_V = np.linspace(4.0, 11.0, 11)


@dataclass(frozen=True)
class SensorNoise:
    """Half-widths of uniform sensor noise; current noise grows linearly with input voltage."""

    speed_rad_s: float = 10.0
    current_low_a: float = 0.15
    current_high_a: float = 1.0
    voltage_low_v: float = 4.0
    voltage_high_v: float = 11.0

    def current_halfwidth_a(self, voltage_v: ArrayLike) -> NDArray[np.float64]:
        return np.interp(
            np.asarray(voltage_v, dtype=float),
            [self.voltage_low_v, self.voltage_high_v],
            [self.current_low_a, self.current_high_a],
        )


def steady_measurements(
    params: MotorParams,
    voltages_v: ArrayLike,
    samples_per_point: int,
    rng: np.random.Generator,
    noise: SensorNoise | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``samples_per_point`` noisy (voltage, current, speed) samples at each input voltage."""
    noise = noise or SensorNoise()
    v = np.repeat(np.asarray(voltages_v, dtype=float), samples_per_point)
    truth = steady_state(params, v)
    omega = truth.omega_rad_s + rng.uniform(-noise.speed_rad_s, noise.speed_rad_s, v.shape)
    half = noise.current_halfwidth_a(v)
    current = truth.current_a + rng.uniform(-1.0, 1.0, v.shape) * half
    return v, current, omega


def faulty_steady_state(
    params: MotorParams, fault: str, voltage_v: ArrayLike, severity: float = 1.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Steady speed and current of a motor with a fault, as the paper observed them (section III.B).

    A steady-state sketch for bench-style data; the dynamic simulator models the faults in full.
    ``severity`` scales the fault (1.0: as on the paper's testbed).
    """
    v = np.asarray(voltage_v, dtype=float)
    if fault == "NORMAL":
        s = steady_state(params, v)
    elif fault == "F1.1":  # a rubbing bar adds friction torque
        s = steady_state(params.replace(T_f=params.T_f + 0.05 * severity), v)
    elif fault == "F3.1":  # blades trimmed: the propeller load falls
        s = steady_state(params.replace(C_p=params.C_p * max(1.0 - 0.9 * severity, 0.05)), v)
    elif fault == "F4.1":  # one switch open: two phases share the current, a larger drop at high current
        s = steady_state(params.replace(R_ohm=params.R_ohm * (1.0 + 2.0 * severity)), v)
    elif fault == "F2.1":  # the motor stops; about 3 A flows
        return np.zeros_like(v), np.full_like(v, 3.0)
    elif fault == "F4.2":  # the ESC loses position; the motor stalls drawing about 8 A
        return np.zeros_like(v), np.full_like(v, 8.0)
    else:
        raise ValueError(f"unknown fault {fault!r}; expected NORMAL, F1.1, F2.1, F3.1, F4.1 or F4.2")
    return s.omega_rad_s, s.current_a


def testbed_run(
    params: MotorParams,
    fault: str,
    voltage_v: float,
    rng: np.random.Generator,
    *,
    duration_s: float = 20.0,
    fault_at_s: float = 10.0,
    rate_hz: float = 40.0,
    time_constant_s: float = 0.1,
    severity: float = 1.0,
    motor: int = 1,
    noise: SensorNoise | None = None,
) -> dict[str, NDArray[np.float64]]:
    """One testbed experiment as in section IV.A: constant voltage, fault injected at ``fault_at_s``.

    Speed and current move from the healthy to the faulty steady state with a first-order response;
    returns telemetry-table columns.
    """
    noise = noise or SensorNoise()
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    v = np.full_like(t, voltage_v)
    healthy = steady_state(params, [voltage_v])
    w_fault, i_fault = faulty_steady_state(params, fault, [voltage_v], severity)
    blend = np.where(t < fault_at_s, 0.0, 1.0 - np.exp(-(t - fault_at_s) / time_constant_s))
    omega = healthy.omega_rad_s[0] + blend * (w_fault[0] - healthy.omega_rad_s[0])
    current = healthy.current_a[0] + blend * (i_fault[0] - healthy.current_a[0])
    omega = np.abs(
        omega + rng.uniform(-noise.speed_rad_s, noise.speed_rad_s, t.shape)
    )  # an RPM sensor reads >= 0
    current = current + rng.uniform(-1.0, 1.0, t.shape) * noise.current_halfwidth_a(v)
    return {
        "time_s": t,
        "motor": np.full(t.shape, motor),
        "omega_rad_s": omega,
        "current_a": current,
        "voltage_v": v,
    }
