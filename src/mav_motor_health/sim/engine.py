"""The simulation loop: motors, ESCs, battery, airframe, controller, faults and sensors, step by step.

:class:`Simulation` is used both offline (:func:`run_scenario` collects a :class:`SimRecord` for the
file writers) and live (:mod:`.live` steps it in real time and streams MAVLink). It is pure numerics:
no I/O.

A scenario with a ``world`` (:mod:`.worlds`) flies that world's vehicle. There the flight controller's
output is the *command* (what the autopilot logs: SERVO_OUTPUT_RAW, RCOU, the CSV's ``throttle``) and the
ESC turns it into the duty the motor sees through its idle offset; :attr:`Simulation.command` and
:attr:`Simulation.duty` keep both. Without a world the ESC map is the identity and the two are one.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..config import load_motor_params
from ..errors import ConfigError
from ..model.equations import current_from_speed, steady_state
from .battery import Battery, BatterySpec
from .control import FlightController
from .esc import esc_input_current_a, pwm_from_duty
from .faults import FaultEffects, FaultScale, FaultSpec, effects_at
from .motor import MotorBank, MotorDynamics
from .scenario import Scenario
from .sensors import EscSample, EscSensors
from .vehicle import GRAVITY_M_S2, Airframe, RigidBody
from .worlds import World, draw_world

__all__ = ["AVIONICS_CURRENT_A", "SimRecord", "Simulation", "VehicleSnapshot", "run_scenario"]

AVIONICS_CURRENT_A = 0.6
#: home position of the simulated flights (a field near Seoul; the paper's lab is in Korea)
HOME_LAT_DEG = 37.5665
HOME_LON_DEG = 126.9780
EARTH_RADIUS_M = 6_378_137.0


@dataclass(frozen=True)
class VehicleSnapshot:
    time_s: float
    pwm_us: tuple[int, ...]
    duty: tuple[float, ...]
    bus_voltage_v: float
    battery_current_a: float
    consumed_mah: float
    remaining_pct: int
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    lat_deg: float
    lon_deg: float
    alt_m: float
    vel_ned_m_s: tuple[float, float, float]
    climb_m_s: float
    throttle_pct: int
    #: the autopilot's command per motor (equal to ``duty`` without a world's ESC map)
    command: tuple[float, ...] = ()


@dataclass
class SimRecord:
    scenario: Scenario
    esc: list[EscSample] = field(default_factory=list)
    vehicle: list[VehicleSnapshot] = field(default_factory=list)
    params: dict[str, float] = field(default_factory=dict)
    #: the world flown, if any (its truth: :meth:`World.truth`)
    world: World | None = None

    def esc_columns(self) -> dict[str, NDArray[Any]]:
        """ESC samples as telemetry-table columns (the project's CSV format), as a log shows them:
        ``throttle`` is the autopilot's command and ``voltage_v`` the command × the bus voltage, what the
        telemetry readers compute (in a world with an ESC idle offset that is not the motor's voltage;
        the duty is the truth, in :attr:`esc`)."""
        e = self.esc
        esc_ca = np.array([s.esc_current_ca for s in e], dtype=float)
        duty = np.array([s.throttle for s in e], dtype=float)
        bus = np.array([s.voltage_cv for s in e], dtype=float) / 100.0
        return {
            "time_s": np.array([s.time_s for s in e], dtype=float),
            "motor": np.array([s.motor for s in e], dtype=np.int64),
            "rpm": np.array([s.rpm for s in e], dtype=float),
            "omega_rad_s": np.array([s.rpm for s in e], dtype=float) * (2 * math.pi / 60.0),
            "current_a": np.array([s.motor_current_ca for s in e], dtype=float) / 100.0,
            "voltage_v": duty * bus,
            "bus_voltage_v": bus,
            "throttle": duty,
            "esc_current_a": esc_ca / 100.0,
            "esc_temp_c": np.array([s.temp_c for s in e], dtype=float),
            "motor_temp_c": np.array([s.motor_temp_c for s in e], dtype=float),
        }


class Simulation:
    """One vehicle (or one motor on a stand) stepped by ``dt_s``; faults can be added at any time."""

    def __init__(self, scenario: Scenario) -> None:
        #: the world flown (None: the scenario's motor and airframe)
        self.world: World | None = None
        self.fault_scale: FaultScale | None = None
        if scenario.world is not None:
            if scenario.mode != "flight":
                raise ConfigError(
                    "a world is a flying vehicle", key="scenario.world", expected="mode = 'flight'"
                )
            self.world = draw_world(scenario.world)
            if scenario.world_turbulence is not None:  # the same world in other air
                self.world = dataclasses.replace(self.world, turbulence=scenario.world_turbulence)
            self.fault_scale = self.world.fault_scale()
            scenario = self.world.apply(scenario)
        self.scenario = sc = scenario
        self.rng = np.random.default_rng(sc.seed)
        world = self.world
        if world is None:
            self.params = load_motor_params(sc.motor)
            self.dynamics = MotorDynamics(
                self.params, inertia_kg_m2=self.params.J_kg_m2 or MotorDynamics.inertia_kg_m2
            )
        else:
            self.params = world.motor
            self.dynamics = world.dynamics()
        self.faults: list[FaultSpec] = list(sc.faults)
        self.n = sc.n_motors
        self.time_s = 0.0
        self.dt = sc.dt_s
        self._yaw_rate_rad_s = 0.0
        self._yaw_target_rad: float | None = None
        self.sensors = EscSensors(sc.sensors, self.n, self.rng)
        if sc.mode == "testbed":
            self.battery = Battery(BatterySpec(supply_v=sc.supply_v))
            self.frame: Airframe | None = None
            self.body: RigidBody | None = None
            self.ctrl: FlightController | None = None
            duty0 = round(sc.voltage_v / sc.supply_v * 1000.0) / 1000.0
            self.duty = np.full(1, duty0)
            w0 = steady_state(self.params, self.duty * sc.supply_v).omega_rad_s
            # the experiment starts with the motor running at its set voltage
            self.bank = MotorBank(self.dynamics, 1, self.rng, omega0_rad_s=w0)
        else:
            fl = sc.flight
            self.battery = Battery(
                BatterySpec(
                    cells=fl.battery_cells,
                    capacity_mah=fl.battery_capacity_mah,
                    resistance_ohm=fl.battery_resistance_ohm,
                )
                if world is None
                else world.battery
            )
            self.frame = Airframe(mass_kg=fl.mass_kg) if world is None else world.airframe
            self.body = RigidBody(self.frame, fl.start_alt_m)
            self.ctrl = FlightController(self.frame, self.params, None if world is None else world.gains())
            self.ctrl.hold(self.body)
            hover_w = math.sqrt(fl.mass_kg * GRAVITY_M_S2 / 6 / self.frame.thrust_coeff)
            self.bank = MotorBank(self.dynamics, 6, self.rng, omega0_rad_s=hover_w)
            v_hover = (
                self.params.R_ohm * float(current_from_speed(self.params, hover_w))
                + self.params.k_e * hover_w
            )
            self.duty = np.full(6, v_hover / self.battery.voltage_v)
            self.battery.step(float(6 * self.duty[0] * current_from_speed(self.params, hover_w)), 0.0)
            self._wind_sd, self._torque_sd, gyro_sd = fl.turbulence_levels
            if world is not None:
                self._torque_sd *= world.torque_disturbance_scale
                gyro_sd *= world.gyro_noise_scale
            self.ctrl.gyro_noise_rad_s = gyro_sd
            self.ctrl.rng = self.rng
            self._wind = [0.0, 0.0, 0.0]
            self._torque = [0.0, 0.0, 0.0]
            self._segment_index = -1
            self._segment_end_s = 0.0
        self.bank.current_a = (
            self.duty * 0.0 + steady_state(self.params, self.duty * self.battery.voltage_v).current_a
        )
        self.esc_current_a = esc_input_current_a(self.duty, self.bank.current_a)
        #: the autopilot's command per motor; the ESC turns it into :attr:`duty`
        self.command = self.duty if world is None else self._command_for_duty(self.duty)
        self._avionics_a = AVIONICS_CURRENT_A if world is None else world.avionics_current_a
        self._effects_key: tuple[bool, ...] | None = None
        self._effects_now = FaultEffects.healthy(self.n)

    def _command_for_duty(self, duty: NDArray[np.float64]) -> NDArray[np.float64]:
        """The command that gives ``duty`` through the world's ESC map (the map's inverse)."""
        assert self.world is not None
        c0 = self.world.esc.idle_offset
        return c0 + np.asarray(duty, dtype=float) * (1.0 - c0)

    # -- commands ---------------------------------------------------------------------------------
    def inject(self, fault: FaultSpec) -> None:
        """Add a fault (its stall current carried over to a world's motor where it has none of its own)."""
        self.faults.append(fault if self.fault_scale is None else self.fault_scale.resolve(fault))

    def clear_faults(self) -> None:
        self.faults = [
            FaultSpec(f.kind, f.motor, f.onset_s, f.severity, f.stall_current_a, min(f.end_s, self.time_s))
            for f in self.faults
        ]

    # -- stepping ---------------------------------------------------------------------------------
    def step(self) -> list[EscSample]:
        """Advance one step; returns the ESC reports whose clocks ticked."""
        dt, t = self.dt, self.time_s
        fx = self._effects(t)
        bus = self.battery.voltage_v
        if self.ctrl is not None and self.body is not None:
            self._guidance(t)
            if self._yaw_rate_rad_s:
                self.ctrl.yaw_sp = _wrap_rad(self.ctrl.yaw_sp + self._yaw_rate_rad_s * dt)
            self._turbulence(dt)
            command = np.round(self.ctrl.update(self.body, bus, dt, t) * 1000.0) / 1000.0
            if self.world is None:
                self.duty = self.command = command
            else:
                # The ESC's own map; the controller does not know it (its loops close around it).
                self.command = command
                self.duty = self.world.esc.duty(command)
        self.bank.step(self.duty * bus, dt, fx)
        self.esc_current_a = esc_input_current_a(self.duty, self.bank.current_a)
        total = float(self.esc_current_a.sum()) + (self._avionics_a if self.body is not None else 0.0)
        self.battery.step(total, dt)
        if self.body is not None and self.frame is not None:
            w = self.bank.omega_rad_s
            thrust = self.frame.thrust_coeff * fx.thrust_factor * w * w
            self.body.step(thrust, self.bank.prop_torque_nm, tuple(self._wind), tuple(self._torque), dt)  # type: ignore[arg-type]
        self.time_s = t + dt
        return self.sensors.sample(
            self.time_s,
            dt,
            self.bank.omega_rad_s,
            self.bank.current_a,
            self.duty,
            self.battery.voltage_v,
            self.bank.esc_temp_c,
            self.bank.motor_temp_c,
            None if self.world is None else self.command,
        )

    def _effects(self, t: float) -> FaultEffects:
        """Fault effects at ``t``, rebuilt only when a fault starts or ends."""
        key = tuple(f.active(t) for f in self.faults)
        if key != self._effects_key:
            self._effects_key = key
            self._effects_now = effects_at(self.faults, t, self.n, self.fault_scale)
        return self._effects_now

    def _turbulence(self, dt: float) -> None:
        """Ornstein–Uhlenbeck wind (τ 3 s) and torque disturbances (τ 0.3 s)."""
        rng = self.rng
        a_w, a_t = math.exp(-dt / 3.0), math.exp(-dt / 0.3)
        nw = rng.standard_normal(6)
        sw = self._wind_sd * math.sqrt(1 - a_w * a_w)
        st = self._torque_sd * math.sqrt(1 - a_t * a_t)
        for k in range(3):
            self._wind[k] = a_w * self._wind[k] + sw * float(nw[k]) * (0.4 if k == 2 else 1.0)
            self._torque[k] = a_t * self._torque[k] + st * float(nw[3 + k]) * (0.5 if k == 2 else 1.0)

    def _guidance(self, t: float) -> None:
        assert self.ctrl is not None
        segs = self.scenario.flight.segments
        while t >= self._segment_end_s and self._segment_index < len(segs):
            self._segment_index += 1
            if self._yaw_target_rad is not None:  # a turn ends exactly on its heading
                self.ctrl.yaw_sp = self._yaw_target_rad
                self._yaw_target_rad = None
                self._yaw_rate_rad_s = 0.0
            if self._segment_index < len(segs):
                seg = segs[self._segment_index]
                self._segment_end_s += seg.duration_s
                h = math.radians(seg.heading_deg)
                v = seg.speed_m_s
                self.ctrl.vel_ff = {
                    "hover": [0.0, 0.0, 0.0],
                    "climb": [0.0, 0.0, -v],
                    "descend": [0.0, 0.0, v],
                    "translate": [v * math.cos(h), v * math.sin(h), 0.0],
                    "yaw": [0.0, 0.0, 0.0],
                }[seg.kind]
                if seg.kind == "yaw" and seg.duration_s > 0:
                    # the shorter way round, at a constant rate
                    self._yaw_target_rad = _wrap_rad(h)
                    turn = _wrap_rad(h - self.ctrl.yaw_sp)
                    self._yaw_rate_rad_s = turn / seg.duration_s
            else:
                self.ctrl.vel_ff = [0.0, 0.0, 0.0]
                self._segment_end_s = float("inf")

    # -- observation ------------------------------------------------------------------------------
    def snapshot(self) -> VehicleSnapshot:
        b = self.body
        # the PWM the autopilot sends: the command over MOT_PWM_MIN..MAX
        pwm = tuple(int(x) for x in np.round(pwm_from_duty(self.command)))
        zero = [0.0, 0.0, 0.0]
        att, pos, vel = (zero, zero, zero) if b is None else (b.att, b.pos, b.vel)
        climb = 0.0 if b is None else b.climb_m_s
        lat = HOME_LAT_DEG + math.degrees(pos[0] / EARTH_RADIUS_M)
        lon = HOME_LON_DEG + math.degrees(pos[1] / (EARTH_RADIUS_M * math.cos(math.radians(HOME_LAT_DEG))))
        return VehicleSnapshot(
            time_s=self.time_s,
            pwm_us=pwm,
            duty=tuple(float(d) for d in self.duty),
            bus_voltage_v=self.battery.voltage_v,
            battery_current_a=self.battery.monitor_current_a,
            consumed_mah=self.battery.consumed_mah,
            remaining_pct=self.battery.remaining_pct,
            roll_rad=att[0],
            pitch_rad=att[1],
            yaw_rad=att[2],
            lat_deg=lat,
            lon_deg=lon,
            alt_m=-pos[2],
            vel_ned_m_s=(vel[0], vel[1], vel[2]),
            climb_m_s=climb,
            throttle_pct=round(100 * float(np.mean(self.command))),
            command=tuple(float(c) for c in self.command),
        )

    def ardupilot_params(self) -> dict[str, float]:
        """The parameters a ground station would fetch from this vehicle (ArduCopter names)."""
        p: dict[str, float] = {
            "FRAME_CLASS": 2.0,  # hexa
            "FRAME_TYPE": 1.0,  # X
            "MOT_PWM_MIN": 1000.0,
            "MOT_PWM_MAX": 2000.0,
            "MOT_PWM_TYPE": 0.0,
            "MOT_SPIN_ARM": 0.1,
            "MOT_SPIN_MIN": 0.12,
            "MOT_BAT_VOLT_MAX": 12.6,
            "MOT_BAT_VOLT_MIN": 9.9,
            "BATT_MONITOR": 4.0,
            "BATT_CAPACITY": float(self.scenario.flight.battery_capacity_mah),
            "SERIAL5_PROTOCOL": 16.0,  # ESC telemetry
            "SERVO_BLH_TRATE": 10.0,
            "SERVO_BLH_POLES": 14.0,
            "SIM_MOT_FAULT": 0.0,
            "SIM_MOT_FLT_NUM": 0.0,
            "SIM_MOT_FLT_SEV": 1.0,
        }
        for out in range(1, 9):
            p[f"SERVO{out}_FUNCTION"] = float(32 + out) if out <= self.n else 0.0
            p[f"SERVO{out}_MIN"] = 1000.0
            p[f"SERVO{out}_MAX"] = 2000.0
        if self.world is not None:
            p.update(self.world.ardupilot_params())
        return p


def run_scenario(scenario: Scenario, *, collect_esc: bool = True) -> SimRecord:
    """Simulate a whole scenario offline."""
    sim = Simulation(scenario)
    scenario = sim.scenario  # a world's: its step, rates and faults resolved
    record = SimRecord(scenario=scenario, params=sim.ardupilot_params(), world=sim.world)
    steps = round(scenario.duration_s / scenario.dt_s)
    log_every = max(1, round(1.0 / (scenario.log_hz * scenario.dt_s)))
    record.vehicle.append(sim.snapshot())
    esc = record.esc
    for k in range(1, steps + 1):
        samples = sim.step()
        if collect_esc and samples:
            esc.extend(samples)
        if k % log_every == 0:
            record.vehicle.append(sim.snapshot())
    return record


def _wrap_rad(angle_rad: float) -> float:
    return (angle_rad + math.pi) % (2 * math.pi) - math.pi
