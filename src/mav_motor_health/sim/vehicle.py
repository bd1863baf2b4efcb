"""The hexacopter airframe: ArduPilot's hexa-X motor layout and a rigid body in NED.

Layout from ArduPilot ``AP_MotorsMatrix.cpp`` (``MOTOR_FRAME_HEXA``, ``MOTOR_FRAME_TYPE_X``): motor,
angle from the nose (positive to the right) and spin direction::

    motor 1   +90°  CW      motor 2   −90°  CCW
    motor 3   −30°  CW      motor 4  +150°  CCW
    motor 5   +30°  CCW     motor 6  −150°  CW

Body axes are forward-right-down. A motor at angle ``a`` sits at ``(x, y) = arm·(cos a, sin a)``; its
thrust ``T`` gives roll torque ``−y·T`` and pitch torque ``x·T``; its propeller's drag torque ``Q`` turns
the body against the propeller, so yaw torque is ``yaw_factor·Q`` (ArduPilot's factors: CW −1, CCW +1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["HEXA_X", "Airframe", "RigidBody"]

#: (angle from the nose [deg], ArduPilot yaw factor: CW −1, CCW +1) per motor 1..6
HEXA_X: tuple[tuple[float, float], ...] = (
    (90.0, -1.0),
    (-90.0, 1.0),
    (-30.0, -1.0),
    (150.0, 1.0),
    (30.0, 1.0),
    (-150.0, -1.0),
)
GRAVITY_M_S2 = 9.80665


@dataclass(frozen=True)
class Airframe:
    mass_kg: float = 2.0
    arm_m: float = 0.275
    inertia_kg_m2: tuple[float, float, float] = (0.035, 0.035, 0.06)
    #: thrust = thrust_coeff·ω² per propeller [N/(rad/s)²] (DJI 9450: ≈ 4 N at 680 rad/s)
    thrust_coeff: float = 9.0e-6
    #: linear air drag of the body [N/(m/s)] and rotational damping [N·m/(rad/s)]
    drag_n_s_m: float = 0.35
    rot_damping_nm_s: float = 0.002
    layout: tuple[tuple[float, float], ...] = HEXA_X

    @property
    def n_motors(self) -> int:
        return len(self.layout)

    def geometry(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Motor x [m], y [m] and yaw factor arrays."""
        angles = np.radians([a for a, _ in self.layout])
        return (
            self.arm_m * np.cos(angles),
            self.arm_m * np.sin(angles),
            np.array([f for _, f in self.layout]),
        )


class RigidBody:
    """Position/velocity in NED [m, m/s], Euler angles [rad], body rates [rad/s]."""

    def __init__(self, frame: Airframe, alt_m: float = 10.0) -> None:
        self.frame = frame
        self.pos = [0.0, 0.0, -alt_m]
        self.vel = [0.0, 0.0, 0.0]
        self.att = [0.0, 0.0, 0.0]
        self.rates = [0.0, 0.0, 0.0]
        self.accel = [0.0, 0.0, 0.0]
        x, y, yaw = frame.geometry()
        self._x, self._y, self._yawf = x, y, yaw
        self.on_ground = False

    def step(
        self,
        thrust_n: NDArray[np.float64],
        prop_torque_nm: NDArray[np.float64],
        wind_ned: tuple[float, float, float],
        torque_disturbance: tuple[float, float, float],
        dt: float,
    ) -> None:
        f = self.frame
        total = float(thrust_n.sum())
        tau_x = float(-(self._y @ thrust_n)) + torque_disturbance[0]
        tau_y = float(self._x @ thrust_n) + torque_disturbance[1]
        tau_z = float(self._yawf @ prop_torque_nm) + torque_disturbance[2]
        phi, theta, psi = self.att
        cf, sf = math.cos(phi), math.sin(phi)
        ct, st = math.cos(theta), math.sin(theta)
        cp, sp = math.cos(psi), math.sin(psi)
        # Third column of the body-to-NED rotation: where the body's z axis points.
        zx = cf * st * cp + sf * sp
        zy = cf * st * sp - sf * cp
        zz = cf * ct
        m = f.mass_kg
        ax = (-total * zx - f.drag_n_s_m * (self.vel[0] - wind_ned[0])) / m
        ay = (-total * zy - f.drag_n_s_m * (self.vel[1] - wind_ned[1])) / m
        az = (-total * zz - f.drag_n_s_m * (self.vel[2] - wind_ned[2])) / m + GRAVITY_M_S2
        self.accel = [ax, ay, az]
        for k, a in enumerate((ax, ay, az)):
            self.vel[k] += a * dt
            self.pos[k] += self.vel[k] * dt
        if self.pos[2] > 0.0:  # the ground
            self.pos[2] = 0.0
            self.vel = [0.0, 0.0, min(self.vel[2], 0.0)]
            self.on_ground = True
        else:
            self.on_ground = False
        ix, iy, iz = f.inertia_kg_m2
        p, q, r = self.rates
        d = f.rot_damping_nm_s
        dp = (tau_x - d * p - (iz - iy) * q * r) / ix
        dq = (tau_y - d * q - (ix - iz) * p * r) / iy
        dr = (tau_z - 10 * d * r - (iy - ix) * p * q) / iz
        p, q, r = p + dp * dt, q + dq * dt, r + dr * dt
        self.rates = [p, q, r]
        tt = st / ct
        phi += (p + (q * sf + r * cf) * tt) * dt
        theta += (q * cf - r * sf) * dt
        psi += ((q * sf + r * cf) / ct) * dt
        self.att = [phi, theta, (psi + math.pi) % (2 * math.pi) - math.pi]

    @property
    def alt_m(self) -> float:
        return -self.pos[2]

    @property
    def climb_m_s(self) -> float:
        return -self.vel[2]
