"""Flight control, in the shape of ArduPilot's: position → velocity → attitude → rate → mixer → PWM.

* velocity and altitude PI loops give a desired acceleration; it becomes a lean angle and a collective
  thrust;
* attitude P → body-rate PID → torque demand (times the inertia);
* the mixer splits collective thrust and torques over the six motors (pseudo-inverse of the hexa-X
  allocation), clips each motor to its range and turns thrust into a duty cycle through the motor model
  (ArduPilot's thrust linearisation and battery-voltage compensation do the same job).

When a motor fails the attitude loop asks it for more and more: its command saturates at full throttle
and the integrators shift the load to the others.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..model.equations import current_from_speed, steady_state
from ..model.params import MotorParams
from .vehicle import GRAVITY_M_S2, Airframe, RigidBody

__all__ = ["BALANCE_TAU_S", "FlightController", "Gains"]

#: time constant of the thrust demand's filter for the balance check [s] (AP_MotorsMatrix: 1/(0.5·loop rate))
BALANCE_TAU_S = 0.5


@dataclass(frozen=True)
class Gains:
    pos_p: float = 0.8
    vel_p: float = 2.0
    vel_i: float = 0.5
    alt_vel_p: float = 4.0
    alt_vel_i: float = 2.0
    att_p: float = 7.0
    yaw_p: float = 3.0
    rate_p: float = 9.0
    rate_i: float = 4.0
    rate_d: float = 0.12
    #: the yaw rate loop's gains; the mixer gives its torque twice, so in effect 6.0 and 1.0 (update())
    yaw_rate_p: float = 3.0
    yaw_rate_i: float = 0.5
    max_lean_rad: float = math.radians(30.0)
    max_speed_m_s: float = 8.0
    spin_min: float = 0.12
    spin_max: float = 1.0
    lost_after_s: float = 0.25
    #: a saturated motor is declared lost only where its thrust demand (filtered over
    #: :data:`BALANCE_TAU_S`) is at least this many times the working motors' mean, as ArduPilot's thrust
    #: balance (1.5) does; 0: saturation alone. A vehicle with little thrust to spare saturates its
    #: healthy motors in a hard manoeuvre, all of them high: the balance tells that from a failed motor.
    loss_balance: float = 0.0


class FlightController:
    def __init__(self, frame: Airframe, motor: MotorParams, gains: Gains | None = None) -> None:
        self.frame, self.motor = frame, motor
        self.g = gains or Gains()
        x, y, yawf = frame.geometry()
        # Yaw torque per newton of thrust: Q/T = C_p·ω^k / (c_T·ω²) at a typical hover speed.
        hover_w = math.sqrt(frame.mass_kg * GRAVITY_M_S2 / frame.n_motors / frame.thrust_coeff)
        kappa = motor.C_p * hover_w ** (motor.k - 2.0) / frame.thrust_coeff
        self._alloc = np.vstack([np.ones_like(x), -y, x, yawf * kappa])
        self.lost = np.zeros(frame.n_motors, dtype=bool)
        self._saturated_since = np.full(frame.n_motors, np.inf)
        self._set_mixer()
        self.pos_sp = [0.0, 0.0, 0.0]
        self.vel_ff = [0.0, 0.0, 0.0]
        self.yaw_sp = 0.0
        self._vel_i = [0.0, 0.0, 0.0]
        self._rate_i = [0.0, 0.0, 0.0]
        self._last_rates = [0.0, 0.0, 0.0]
        self.saturated = np.zeros(frame.n_motors, dtype=bool)
        self.duty = np.zeros(frame.n_motors)
        self.att_sp = [0.0, 0.0, 0.0]
        #: the roll, pitch and yaw torques the rate loops asked for at the last update [N·m]
        self.torque_demand_nm = (0.0, 0.0, 0.0)
        self.gyro_noise_rad_s = 0.0
        self.rng: np.random.Generator | None = None
        self._max_thrust_cache: dict[int, float] = {}
        self._demand_filt: NDArray[np.float64] | None = None

    def _set_mixer(self) -> None:
        """Pseudo-inverse of the allocation over the motors still working (ArduPilot's thrust boost)."""
        alloc = self._alloc * ~self.lost
        mix = np.linalg.pinv(alloc)  # (n, 4): [thrust, τx, τy, τz] → thrust per motor
        self.mix_rpt, self.mix_yaw = mix[:, :3], mix[:, 3]

    def _check_lost(self, time_s: float) -> None:
        """A motor held at full command for ``lost_after_s`` is declared lost (AP_MotorsMatrix's
        ``check_for_failed_motor``): the mixer then balances the vehicle on the others."""
        now_sat = self.saturated & ~self.lost
        self._saturated_since = np.where(now_sat, np.minimum(self._saturated_since, time_s), np.inf)
        newly = (time_s - self._saturated_since) >= self.g.lost_after_s
        if newly.any() and self.g.loss_balance > 0 and self._demand_filt is not None:
            mean = float(self._demand_filt[~self.lost].mean())
            newly &= self._demand_filt >= self.g.loss_balance * max(mean, 1e-9)
        if newly.any() and (self.lost | newly).sum() <= 1:
            self.lost |= newly
            self._set_mixer()

    def hold(self, body: RigidBody) -> None:
        self.pos_sp = list(body.pos)
        self.yaw_sp = body.att[2]

    def update(
        self, body: RigidBody, bus_voltage_v: float, dt: float, time_s: float = 0.0
    ) -> NDArray[np.float64]:
        """Duty cycle per motor for the next step."""
        g, f = self.g, self.frame
        self._check_lost(time_s)
        # Guidance: the setpoint moves with the feed-forward velocity.
        for k in range(3):
            self.pos_sp[k] += self.vel_ff[k] * dt
        acc = [0.0, 0.0, 0.0]
        sat = bool(self.saturated.any())
        for k in range(3):
            v_sp = self.vel_ff[k] + g.pos_p * (self.pos_sp[k] - body.pos[k])
            v_sp = max(-g.max_speed_m_s, min(g.max_speed_m_s, v_sp))
            err = v_sp - body.vel[k]
            kp, ki = (g.alt_vel_p, g.alt_vel_i) if k == 2 else (g.vel_p, g.vel_i)
            if not sat:
                self._vel_i[k] = max(-5.0, min(5.0, self._vel_i[k] + ki * err * dt))
            acc[k] = kp * err + self._vel_i[k]
        psi = body.att[2]
        cp, sp = math.cos(psi), math.sin(psi)
        a_fwd = cp * acc[0] + sp * acc[1]
        a_right = -sp * acc[0] + cp * acc[1]
        lean = g.max_lean_rad
        pitch_sp = max(-lean, min(lean, -math.atan2(a_fwd, GRAVITY_M_S2)))
        roll_sp = max(-lean, min(lean, math.atan2(a_right * math.cos(pitch_sp), GRAVITY_M_S2)))
        phi, theta, _ = body.att
        tilt = max(math.cos(phi) * math.cos(theta), 0.5)
        collective = f.mass_kg * (GRAVITY_M_S2 - acc[2]) / tilt
        collective = max(0.0, min(collective, 0.95 * self.max_thrust_n(bus_voltage_v) * f.n_motors))
        yaw_err = (self.yaw_sp - psi + math.pi) % (2 * math.pi) - math.pi
        self.att_sp = [roll_sp, pitch_sp, self.yaw_sp]
        rate_sp = [g.att_p * (roll_sp - phi), g.att_p * (pitch_sp - theta), g.yaw_p * yaw_err]
        torques = [0.0, 0.0, 0.0]
        rates = list(body.rates)
        if self.gyro_noise_rad_s > 0 and self.rng is not None:
            noise = self.rng.standard_normal(3) * self.gyro_noise_rad_s
            rates = [rates[k] + float(noise[k]) for k in range(3)]
        for k in range(3):
            err = rate_sp[k] - rates[k]
            kp, ki = (g.yaw_rate_p, g.yaw_rate_i) if k == 2 else (g.rate_p, g.rate_i)
            # The rate integrators keep integrating when a motor saturates: that is how the others
            # take over the load of a failed motor.
            self._rate_i[k] = max(-25.0, min(25.0, self._rate_i[k] + ki * err * dt))
            # The D term works on the measured rate through a filter (ArduPilot: ~20 Hz): the noise is
            # left out of it here.
            d_term = 0.0 if k == 2 else -g.rate_d * (body.rates[k] - self._last_rates[k]) / dt
            torques[k] = f.inertia_kg_m2[k] * (kp * err + self._rate_i[k] + d_term)
        self._last_rates = list(body.rates)
        self.torque_demand_nm = (torques[0], torques[1], torques[2])
        # Attitude before altitude (as ArduPilot's output_armed_stabilizing): fit roll and pitch into
        # the motors' range first, then yaw as far as there is room, then the collective.
        t_max = self.max_thrust_n(bus_voltage_v)
        working = ~self.lost
        unit = self.mix_rpt[:, 0]
        rp = self.mix_rpt[:, 1:] @ np.array([torques[0], torques[1]])
        span = float(rp[working].max() - rp[working].min())
        if span > t_max:
            rp = rp * (t_max / span)
        # With a motor lost the vehicle gives up its heading (it spins slowly, as real hexacopters do).
        yaw = self.mix_yaw * (0.0 if self.lost.any() else torques[2])
        # The yaw share is given twice (``rpy`` holds one, the demand adds the second): the torque given
        # is twice the rate loop's, i.e. yaw rate gains of twice ``yaw_rate_p`` and ``yaw_rate_i``, as every
        # simulated flight has flown. Both shares are fitted into the motors' range: until 7 December 2026
        # only the first was, and near the top of the range the second was clipped and took roll and pitch
        # authority with it (heavy vehicles fell: docs/simulator.md, "The mixer gives the yaw twice").
        rpy, full, scale = rp, rp, 0.0
        for trial_scale in (1.0, 0.5, 0.25, 0.1):
            trial = rp + trial_scale * yaw
            trial_full = trial + trial_scale * yaw
            if float(trial_full[working].max() - trial_full[working].min()) <= t_max:
                rpy, full, scale = trial, trial_full, trial_scale
                break
        lifts = working & (unit > 1e-6)  # a motor opposite a lost one may carry no collective at all
        u = unit[lifts]
        lower = float(np.max(-full[lifts] / u))
        upper = float(np.min((t_max - full[lifts]) / u))
        c = 0.5 * (lower + upper) if lower > upper else min(max(collective, lower), upper)
        base = unit * c + rpy
        demand = base + scale * yaw
        if g.loss_balance > 0:
            share = demand / t_max
            if self._demand_filt is None:
                self._demand_filt = share
            else:
                self._demand_filt = self._demand_filt + (share - self._demand_filt) * (
                    dt / (BALANCE_TAU_S + dt)
                )
        duty = self.duty_for_thrust(demand, bus_voltage_v)
        # a motor the mixer puts at the top of its range is saturated too: its thrust is t_max, worked out
        # on a 50 mV grid of the bus voltage, whose duty comes out a hair either side of full command
        self.saturated |= demand >= t_max * (1.0 - 1e-9)
        # A lost motor is still asked for everything: its command stays saturated.
        return np.where(self.lost, g.spin_max, duty)

    def max_thrust_n(self, bus_voltage_v: float) -> float:
        """Thrust of one motor at full command (cached: the bus voltage moves slowly)."""
        key = round(bus_voltage_v * 20.0)  # 50 mV grid
        cached = self._max_thrust_cache.get(key)
        if cached is None:
            w = float(steady_state(self.motor, [self.g.spin_max * key / 20.0]).omega_rad_s[0])
            cached = self._max_thrust_cache[key] = self.frame.thrust_coeff * w * w
        return cached

    def duty_for_thrust(self, thrust_n: NDArray[np.float64], bus_voltage_v: float) -> NDArray[np.float64]:
        """Thrust linearisation: the duty whose steady state gives each thrust (motor model, eq. 9–10)."""
        m = self.motor
        w = np.sqrt(np.maximum(thrust_n, 0.0) / self.frame.thrust_coeff)
        volts = m.R_ohm * current_from_speed(m, w) + m.k_e * w
        raw = volts / max(bus_voltage_v, 1.0)
        duty = np.minimum(np.maximum(raw, self.g.spin_min), self.g.spin_max)
        self.saturated = (raw >= self.g.spin_max) | self.lost
        self.duty = duty
        return duty
