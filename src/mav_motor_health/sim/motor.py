"""Electrical and mechanical dynamics of the motors, vectorised over all motors of a vehicle.

Per motor (paper eqs. 1–7 with their dynamic terms kept)::

    L·di/dt = V − R·i − k_e·ω                       (electrical)
    J·dω/dt = k_t·i − (C_p·ω^k + B·ω + T_f)         (mechanical)

At rest (di/dt = dω/dt = 0) these are exactly eqs. 2 and 7, so the steady state of :class:`MotorBank`
is :func:`mav_motor_health.model.equations.steady_state` — the equality is tested.

The electrical time constant L/R (about 0.2 ms for the X2212) is much shorter than any step we take
(1–10 ms), so the current is treated *quasi-statically*: ``i = (V − k_e·ω)/R`` at the new speed. The
mechanical equation is stepped with a linearised implicit Euler step (one Newton step of backward
Euler), which is stable for any step size and whose fixed point is the exact steady state.

Motor temperature follows a first-order thermal model (copper losses R·i² heat a lumped mass that
cools to the air, better when the propeller turns fast); the resistance is held at its calibrated value
so the steady state stays the paper's model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..model.params import MotorParams
from .faults import FaultEffects

__all__ = ["MotorBank", "MotorDynamics"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class MotorDynamics:
    """The steady-state model plus what the dynamics need besides it."""

    params: MotorParams
    #: rotor + propeller inertia [kg·m²] (X2212 rotor ≈ 4e-6, DJI 9450 propeller ≈ 1.6e-5)
    inertia_kg_m2: float = 2.0e-5
    #: phase inductance [H] (only its time constant L/R is reported; the current is quasi-static)
    inductance_h: float = 3.0e-5
    #: thermal mass of the motor [J/K] and thermal resistance to the air at rest / full speed [K/W]
    heat_capacity_j_k: float = 25.0
    thermal_resistance_still_k_w: float = 6.0
    thermal_resistance_fast_k_w: float = 1.5
    #: ESC on-resistance (conduction losses, heats the ESC) [Ω] and its thermal mass/resistance
    esc_resistance_ohm: float = 0.008
    esc_heat_capacity_j_k: float = 8.0
    esc_thermal_resistance_k_w: float = 8.0
    #: F2.1/F4.2: drag of the held rotor [N·m·s/rad], restart kick torque [N·m], retry period [s]
    hold_drag_nm_s: float = 2.5e-4
    restart_kick_nm: float = 0.02
    restart_period_s: float = 0.6
    restart_kick_s: float = 0.2
    #: time constant of the stall current's approach to its level [s]
    stall_current_tau_s: float = 0.05
    #: scale of the stall current's ripple and wander (the paper's amperes; a larger motor's are larger)
    stall_current_scale: float = 1.0

    @property
    def electrical_time_constant_s(self) -> float:
        return self.inductance_h / self.params.R_ohm


class MotorBank:
    """The state of ``n`` motors; :meth:`step` advances them by ``dt`` seconds."""

    def __init__(
        self,
        dynamics: MotorDynamics,
        n: int,
        rng: np.random.Generator,
        *,
        air_temp_c: float = 20.0,
        omega0_rad_s: FloatArray | float = 0.0,
        load_factor: FloatArray | None = None,
    ) -> None:
        self.dyn = dynamics
        self.n = n
        self.rng = rng
        self.air_temp_c = air_temp_c
        self.omega_rad_s = np.broadcast_to(np.asarray(omega0_rad_s, dtype=float), (n,)).copy()
        self.current_a = np.zeros(n)
        self.voltage_v = np.zeros(n)
        self.motor_temp_c = np.full(n, air_temp_c)
        self.esc_temp_c = np.full(n, air_temp_c)
        self.prop_torque_nm = np.zeros(n)
        #: per-motor multiplier of C_p (manufacturing spread; 1.0 = the calibrated motor)
        self.load_factor = np.ones(n) if load_factor is None else np.asarray(load_factor, dtype=float)
        self._stall_time_s = np.zeros(n)
        self._stall_phase_s = rng.uniform(0.0, 1.0, n) * dynamics.restart_period_s
        self._stall_wander_a = np.zeros(n)
        self._heat_dt = 0.0

    def step(self, voltage_v: FloatArray, dt: float, fx: FaultEffects) -> None:
        """Advance by ``dt`` with ``voltage_v`` applied (duty × bus voltage) under fault effects ``fx``."""
        d, p = self.dyn, self.dyn.params
        v = np.maximum(voltage_v, 0.0)
        w_pos = self.omega_rad_s  # never negative
        cp = p.C_p * self.load_factor * fx.load_factor
        g_r = fx.drive_factor / p.R_ohm
        k = p.k
        wk1 = w_pos * w_pos if k == 3.0 else w_pos ** (k - 1.0)
        # Load torque and its slope; friction (T_f, the rubbing bar) only acts on a turning rotor.
        turning = w_pos > 1e-9
        coulomb = p.T_f + fx.rub_torque_nm
        viscous = p.B + fx.rub_viscous_nm_s
        load = (cp * wk1 + viscous) * w_pos + coulomb * turning
        drive = p.k_t * g_r * (v - p.k_e * w_pos)
        slope = g_r * (p.k_t * p.k_e) + k * cp * wk1 + viscous  # −d(drive − load)/dω
        w_new = np.maximum(w_pos + dt * (drive - load) / (d.inertia_kg_m2 + dt * slope), 0.0)
        # Held at rest by friction unless the drive beats it.
        w_new[~turning & (drive <= coulomb)] = 0.0
        i_new = g_r * (v - p.k_e * w_new)

        if fx.any_stalled:
            w_new, i_new = self._stall_step(w_pos, i_new, w_new, cp, dt, fx)
        else:
            self._stall_time_s[:] = 0.0

        self.omega_rad_s = w_new
        self.current_a = i_new
        self.voltage_v = v
        self.prop_torque_nm = cp * np.maximum(w_new, 0.0) ** k
        # Temperatures change over tens of seconds: update them every tenth step.
        self._heat_dt += dt
        if self._heat_dt >= 10 * dt:
            self._heat(self._heat_dt)
            self._heat_dt = 0.0

    def _stall_step(
        self,
        w: FloatArray,
        i_healthy: FloatArray,
        w_healthy: FloatArray,
        cp: FloatArray,
        dt: float,
        fx: FaultEffects,
    ) -> tuple[FloatArray, FloatArray]:
        """F2.1/F4.2: drag of the held rotor, start-up retries, current towards the stall level."""
        d, p = self.dyn, self.dyn.params
        s = fx.stalled
        self._stall_time_s = np.where(s, self._stall_time_s + dt, 0.0)
        phase = (self._stall_time_s + self._stall_phase_s) % d.restart_period_s
        kicking = phase < d.restart_kick_s
        kick = np.where(kicking, d.restart_kick_nm * np.where(fx.back_emf_lost, 0.6, 1.0), 0.0)
        load_slope = p.k * cp * w ** (p.k - 1.0) + p.B + d.hold_drag_nm_s
        torque = kick - d.hold_drag_nm_s * w - (cp * w**p.k + p.B * w + p.T_f)
        w_stall = np.maximum(w + dt * torque / (d.inertia_kg_m2 + dt * load_slope), 0.0)
        # The stall current: its level, a ripple with the retries, and (F4.2) a slow random wander.
        wander_sd_a = 0.6 * d.stall_current_scale
        self._stall_wander_a += -self._stall_wander_a * dt / 1.5 + wander_sd_a * np.sqrt(2 * dt / 1.5) * (
            self.rng.standard_normal(self.n)
        )
        ripple_a = np.where(fx.back_emf_lost, 0.35, 0.8) * d.stall_current_scale
        ripple = ripple_a * np.sin(2 * np.pi * phase / d.restart_period_s)
        wander = np.where(fx.back_emf_lost, self._stall_wander_a, 0.25 * self._stall_wander_a)
        target = fx.stall_current_a * (1.0 + 0.0 * w) + ripple + wander
        blend = 1.0 - np.exp(-dt / d.stall_current_tau_s)
        i_stall = self.current_a + blend * (target - self.current_a)
        return np.where(s, w_stall, w_healthy), np.where(s, i_stall, i_healthy)

    def _heat(self, dt: float) -> None:
        d, p = self.dyn, self.dyn.params
        i2 = self.current_a**2
        speed_share = np.minimum(self.omega_rad_s / 900.0, 1.0)
        r_th = d.thermal_resistance_still_k_w + speed_share * (
            d.thermal_resistance_fast_k_w - d.thermal_resistance_still_k_w
        )
        loss = p.R_ohm * i2 + p.T_f * self.omega_rad_s
        tau = d.heat_capacity_j_k * r_th
        target = self.air_temp_c + loss * r_th
        self.motor_temp_c = target + (self.motor_temp_c - target) * np.exp(-dt / tau)
        esc_target = self.air_temp_c + d.esc_resistance_ohm * i2 * d.esc_thermal_resistance_k_w
        esc_tau = d.esc_heat_capacity_j_k * d.esc_thermal_resistance_k_w
        self.esc_temp_c = esc_target + (self.esc_temp_c - esc_target) * np.exp(-dt / esc_tau)
