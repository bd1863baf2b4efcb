"""Randomised worlds: a seed picks a vehicle unlike the project's own, and how its ESCs report.

:func:`draw_world` draws a few physical quantities and derives the rest with simple scaling laws, so a
world is consistent by construction rather than a set of independent random numbers:

* **vehicle** — take-off mass *m* log-uniform in 1–25 kg; the pack's cell count follows the mass (4S for
  1–2 kg, up to 12S near 25 kg); disk loading 30–115 N/m² (heavier vehicles load their discs more) sets
  the propeller diameter ``D = √(4·T_h/(π·DL))`` with ``T_h = m·g/6``; the propeller's thrust and torque
  coefficients (``C_T`` 0.09–0.12, ``C_Q/C_T`` 0.045–0.075) give the airframe's thrust coefficient
  ``c_T = C_T·ρ·D⁴/(4π²)`` [N/(rad/s)²] and the hover torque ``Q_h = (C_Q/C_T)·D·T_h``;
* **motor** — the hover speed is ``ω_h = √(T_h/c_T)``; the propeller load ``C_p = Q_h/ω_h³`` (k = 3, the
  paper's law, exact at hover); bearing and iron losses ``B·ω_h + T_f`` are 0.5–4 % of ``Q_h``; the hover
  *command* is drawn (0.35–0.65), the ESC's idle offset too, so the hover duty and voltage ``V_h`` follow;
  the back-EMF takes 86–95 % of ``V_h`` (``k_e = η·V_h/ω_h``, i.e. the KV) and the copper the rest
  (``R = (V_h − k_e·ω_h)/i_h``): a big slow motor gets a low KV and a small R, a small fast one the
  opposite. Rotor + propeller inertia ``J`` grows as ``D^4.5`` (propeller mass ∝ D^2.5, radius² ∝ D²);
* **feasibility** — the thrust-to-weight ratio at full command (steady state at the sagging pack's
  voltage) must be ≥ 1.8 and the hover duty ≥ 0.25; otherwise the world is drawn again from the same
  generator (deterministic: :attr:`World.attempts` says how often);
* **ESC** — ``duty = clip((command − c₀)/(1 − c₀), 0, 1)`` with the idle offset ``c₀`` 0–0.06 (the
  identification's :class:`~mav_motor_health.model.esc.EscMap`). The flight controller does not know
  ``c₀`` (its thrust linearisation assumes duty = command, as ArduPilot's does): its integrators close the
  loop around it. Its gains are the default airframe's, with ArduPilot's thrust-balance test before a
  saturated motor is declared lost (:meth:`World.gains`);
* **current reporting** — input side (duty × motor current, 45 %), motor (phase) side (35 %) or unusable
  (a constant reading, 20 %); averaged over the report interval or filtered (5–50 ms); gain 0.75–1.1,
  offset ±0.3 A. The battery monitor has a small gain error (±3 %);
* **telemetry** — ESC report rate 10 Hz (ArduPilot's BLHeli default, a third of the worlds) or
  log-uniform 10–200 Hz; speed noise 0.8–3 % of the hover speed, current noise 2–6 % of the hover current
  at low voltage growing to 13–40 % at full voltage (the paper's ±0.15 A at 4 V and ±1 A at 11 V on a
  3.8 A hover, scaled). The tlog streams ESC_TELEMETRY at the report rate (at most 50 Hz), commands at
  10–50 Hz;
* **flight** — turbulence calm/moderate/gusty (gust torques scaled by weight × arm, the gyro noise by the
  roll authority: :attr:`World.gyro_noise_scale`), the pack's resistance from its capacity (12–35 mΩ·Ah
  per cell), and a default plan of 150 s: take-off climb, hovers, translations at 2–6 m/s, climbs and
  descents, yaw turns (:func:`flight_plan`).

:meth:`World.truth` is the ground truth as JSON-ready data (written in the ``.truth.json`` sidecar as
``world``); :meth:`World.vehicle_params` the same in the identification's own terms, so a benchmark
compares what :func:`~mav_motor_health.model.identify.identify` finds with it field by field.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..model.equations import steady_state
from ..model.esc import EscMap
from ..model.identify import CurrentReading
from ..model.params import MotorParams
from ..model.vehicle import CURRENT_SIDES, VehicleParams
from .battery import BatterySpec, cell_open_circuit_v
from .control import Gains
from .faults import FaultScale
from .motor import MotorDynamics
from .scenario import TURBULENCE, FlightSpec, Scenario, Segment
from .sensors import CurrentSensing, SensorSpec
from .vehicle import GRAVITY_M_S2, Airframe

__all__ = [
    "CELL_COUNTS",
    "MIN_THRUST_TO_WEIGHT",
    "World",
    "draw_world",
    "flight_plan",
    "plan_altitude_m",
]

RHO_AIR_KG_M3 = 1.225
#: packs the vehicles carry
CELL_COUNTS = (4, 6, 8, 10, 12)
MIN_THRUST_TO_WEIGHT = 1.8
MIN_HOVER_DUTY = 0.25
#: the paper's X2212 at the default airframe's hover (2 kg): torque [N·m], speed [rad/s], current [A],
#: the reference of the fault constants (faults.FaultScale)
PAPER_HOVER_TORQUE_NM = 0.0372
PAPER_HOVER_SPEED_RAD_S = 603.5
PAPER_HOVER_CURRENT_A = 3.82
#: the default airframe (mass [kg], arm [m], roll inertia [kg·m²]): the reference of the turbulence's
#: torque disturbances and of the body's rotational damping
REFERENCE_MASS_KG = 2.0
REFERENCE_ARM_M = 0.275
REFERENCE_ROLL_INERTIA_KG_M2 = 0.035
#: the default airframe's roll authority with the X2212 on a full 3S pack (thrust/weight 2.69) [rad/s²]
REFERENCE_ROLL_AUTHORITY_RAD_S2 = 43.4
MAX_DRAWS = 200


@dataclass(frozen=True)
class World:
    """One randomised vehicle and its telemetry; every field is truth (SI units in the names)."""

    seed: int
    # -- drawn physical quantities
    mass_kg: float
    cells: int
    capacity_mah: float
    initial_soc: float
    prop_diameter_m: float
    disk_loading_n_m2: float
    thrust_coefficient: float  # C_T, per (rev/s)² ρ D⁴
    torque_ratio: float  # C_Q / C_T
    hover_command: float  # as designed; the flight's own hover command settles near it
    voltage_efficiency: float  # back-EMF share of the hover voltage
    loss_share: float  # (B·ω_h + T_f) / Q_h
    # -- the vehicle
    motor: MotorParams  # with J_kg_m2
    motor_poles: int
    airframe: Airframe
    battery: BatterySpec
    avionics_current_a: float
    # -- ESC and telemetry
    esc: EscMap
    current: CurrentSensing
    rate_hz: float
    speed_noise_rad_s: float
    current_noise_a: tuple[float, float]
    current_noise_voltage_v: tuple[float, float]
    esc_stream_hz: float
    log_hz: float
    # -- flight
    turbulence: str
    plan: tuple[Segment, ...]
    # -- the design point and its check
    hover_omega_rad_s: float
    hover_current_a: float
    hover_duty: float
    hover_bus_voltage_v: float
    thrust_to_weight: float
    attempts: int = 1

    # -- views ------------------------------------------------------------------------------------
    @property
    def kv_rpm_per_v(self) -> float:
        return 60.0 / (2.0 * math.pi * self.motor.k_e)

    @property
    def max_dt_s(self) -> float:
        """The longest physics step that lets every ESC report at its rate."""
        return max(
            dt for dt in (0.01, 0.005, 0.0025, 0.002, 0.001) if dt * self.rate_hz <= 0.5 or dt == 0.001
        )

    def dynamics(self) -> MotorDynamics:
        """The motor's dynamics: its inertia, and the thermal and stall constants scaled to its size."""
        scale = self.fault_scale()
        power = scale.torque * scale.speed  # mechanical power at hover relative to the X2212's
        base = MotorDynamics(self.motor)
        assert self.motor.J_kg_m2 is not None
        return dataclasses.replace(
            base,
            inertia_kg_m2=self.motor.J_kg_m2,
            heat_capacity_j_k=base.heat_capacity_j_k * power,
            thermal_resistance_still_k_w=base.thermal_resistance_still_k_w / power,
            thermal_resistance_fast_k_w=base.thermal_resistance_fast_k_w / power,
            esc_resistance_ohm=base.esc_resistance_ohm / scale.current,
            esc_heat_capacity_j_k=base.esc_heat_capacity_j_k * power,
            esc_thermal_resistance_k_w=base.esc_thermal_resistance_k_w / power,
            hold_drag_nm_s=base.hold_drag_nm_s * scale.torque / scale.speed,
            restart_kick_nm=base.restart_kick_nm * scale.torque,
            stall_current_scale=scale.current,
        )

    @property
    def authority_ratio(self) -> float:
        """Roll authority relative to the default airframe's, at most 1."""
        return min(1.0, self.roll_authority_rad_s2 / REFERENCE_ROLL_AUTHORITY_RAD_S2)

    def gains(self) -> Gains:
        """The flight controller's gains: the default airframe's (the loops scale with the inertia, and
        slowing them for a big vehicle costs it its recovery from a lost motor), with ArduPilot's
        thrust-balance test before a saturated motor is declared lost: a vehicle with little thrust to
        spare saturates its healthy motors in a hard manoeuvre, all of them high."""
        return Gains(loss_balance=1.5)

    def fault_scale(self) -> FaultScale:
        return FaultScale(
            torque=self.motor.C_p * self.hover_omega_rad_s**3 / PAPER_HOVER_TORQUE_NM,
            speed=self.hover_omega_rad_s / PAPER_HOVER_SPEED_RAD_S,
            current=self.hover_current_a / PAPER_HOVER_CURRENT_A,
        )

    @property
    def torque_disturbance_scale(self) -> float:
        """Factor on the turbulence's torque disturbances: a gust's torque is an uneven share of the
        rotors' lift over the arms, so it grows with weight × arm (as the control authority does)."""
        return (self.mass_kg * self.airframe.arm_m) / (REFERENCE_MASS_KG * REFERENCE_ARM_M)

    @property
    def roll_authority_rad_s2(self) -> float:
        """Roll acceleration one motor's thrust to spare gives at its arm (a measure of authority)."""
        spare_n = (self.thrust_to_weight - 1.0) * self.mass_kg * GRAVITY_M_S2 / self.airframe.n_motors
        return spare_n * self.airframe.arm_m / self.airframe.inertia_kg_m2[0]

    @property
    def gyro_noise_scale(self) -> float:
        """Factor on the gyro noise the rate loop sees, √(authority ratio). The default gains ask the
        default airframe for up to 30 rad/s²; a big hexa has a fraction of that authority (a 20-kg one an
        eighth), and the default noise through the default gains would drive its motors from limit to
        limit. A real one is tuned and its gyros filtered for its own loop; scaling the noise stands in
        for that without retuning the loops."""
        return math.sqrt(self.authority_ratio)

    def sensor_spec(self, base: SensorSpec) -> SensorSpec:
        """``base`` (its dropouts, clock error, jitter) with this world's rates, noise and current sensing."""
        return dataclasses.replace(
            base,
            rate_hz=(self.rate_hz, self.rate_hz),
            speed_noise_rad_s=self.speed_noise_rad_s,
            current_noise_low_a=self.current_noise_a[0],
            current_noise_high_a=self.current_noise_a[1],
            current_noise_voltage_v=self.current_noise_voltage_v,
            current_filter_s=self.current.filter_s,
            current_sensing=self.current,
        )

    def apply(self, scenario: Scenario) -> Scenario:
        """``scenario`` flown in this world: the world's vehicle, battery, turbulence, telemetry and step
        (at most :attr:`max_dt_s`); its own plan where the scenario has no segments; stall currents in
        this motor's amperes. Idempotent."""
        if scenario.mode != "flight":
            raise ValueError(f"scenario {scenario.name!r}: a world is a flying vehicle (mode 'flight')")
        scale = self.fault_scale()
        flight = FlightSpec(
            turbulence=self.turbulence,
            start_alt_m=scenario.flight.start_alt_m,
            mass_kg=self.mass_kg,
            battery_cells=self.cells,
            battery_capacity_mah=self.capacity_mah,
            battery_resistance_ohm=self.battery.resistance_ohm,
            segments=scenario.flight.segments or self.plan,
        )
        return dataclasses.replace(
            scenario,
            dt_s=min(scenario.dt_s, self.max_dt_s),
            flight=flight,
            faults=tuple(scale.resolve(f) for f in scenario.faults),
            sensors=self.sensor_spec(scenario.sensors),
            esc_stream_hz=self.esc_stream_hz,
            log_hz=self.log_hz,
            world=self.seed,
        )

    def ardupilot_params(self) -> dict[str, float]:
        """The parameters of this vehicle a ground station would see that differ from the default's."""
        return {
            "MOT_BAT_VOLT_MAX": round(4.2 * self.cells, 2),
            "MOT_BAT_VOLT_MIN": round(3.3 * self.cells, 2),
            "MOT_THST_HOVER": round(self.hover_command, 3),
            "BATT_CAPACITY": float(self.capacity_mah),
            "SERVO_BLH_TRATE": float(round(self.rate_hz)),
            "SERVO_BLH_POLES": float(self.motor_poles),
        }

    def vehicle_params(self) -> VehicleParams:
        """The truth in the identification's terms (``current.gain_from`` is "truth")."""
        return VehicleParams(
            motor=self.motor,
            esc=self.esc,
            current=CurrentReading(
                side=self.current.side,
                gain=self.current.gain if self.current.side != "unusable" else math.nan,
                gain_from="truth",
                offset_a=self.current.offset_a if self.current.side != "unusable" else math.nan,
            ),
            source={"world": str(self.seed)},
        )

    def truth(self) -> dict[str, Any]:
        """Everything a benchmark compares against, JSON-ready (SI units in the keys)."""
        m = self.motor
        fr = self.airframe
        return {
            "seed": self.seed,
            "attempts": self.attempts,
            "vehicle": {
                "mass_kg": self.mass_kg,
                "motors": fr.n_motors,
                "arm_m": fr.arm_m,
                "inertia_kg_m2": list(fr.inertia_kg_m2),
                "thrust_coeff_n_s2": fr.thrust_coeff,
                "prop_diameter_m": self.prop_diameter_m,
                "disk_loading_n_m2": self.disk_loading_n_m2,
                "thrust_to_weight": self.thrust_to_weight,
                "hover_command": self.hover_command,
                "hover_duty": self.hover_duty,
                "hover_omega_rad_s": self.hover_omega_rad_s,
                "hover_current_a": self.hover_current_a,
                "hover_bus_voltage_v": self.hover_bus_voltage_v,
            },
            "motor": {
                "R_ohm": m.R_ohm,
                "k_e": m.k_e,
                "C_p": m.C_p,
                "B": m.B,
                "T_f": m.T_f,
                "k": m.k,
                "J_kg_m2": m.J_kg_m2,
                "kv_rpm_per_v": self.kv_rpm_per_v,
                "poles": self.motor_poles,
            },
            "esc": {"idle_offset": self.esc.idle_offset},
            "current": {
                "side": self.current.side,
                "averaging": self.current.averaging,
                "filter_s": self.current.filter_s if self.current.averaging == "filter" else None,
                "gain": self.current.gain,
                "offset_a": self.current.offset_a,
                "constant_a": self.current.constant_a if self.current.side == "unusable" else None,
            },
            "battery": {
                "cells": self.cells,
                "capacity_mah": self.capacity_mah,
                "resistance_ohm": self.battery.resistance_ohm,
                "initial_soc": self.initial_soc,
                "monitor_gain": self.battery.monitor_gain,
            },
            "telemetry": {
                "esc_rate_hz": self.rate_hz,
                "speed_noise_rad_s": self.speed_noise_rad_s,
                "current_noise_a": list(self.current_noise_a),
                "current_noise_voltage_v": list(self.current_noise_voltage_v),
                "esc_stream_hz": self.esc_stream_hz,
                "log_hz": self.log_hz,
            },
            "flight": {
                "turbulence": self.turbulence,
                "plan": [dataclasses.asdict(s) for s in self.plan],
            },
        }

    def report(self) -> str:
        """The world in a few lines, for a person."""
        m, fr, c = self.motor, self.airframe, self.current
        inch = self.prop_diameter_m / 0.0254
        sensing = (
            f"constant {c.constant_a:.2f} A (no per-motor current)"
            if c.side == "unusable"
            else f"{c.side} side, "
            + (
                "averaged over the report interval"
                if c.averaging == "interval"
                else f"filtered {1e3 * c.filter_s:.0f} ms"
            )
            + f", gain {c.gain:.3f}, offset {c.offset_a:+.2f} A"
        )
        duration = sum(s.duration_s for s in self.plan)
        kinds = sorted({s.kind for s in self.plan})
        return "\n".join(
            [
                f"world {self.seed}: {self.mass_kg:.2f} kg hexa-X, {self.cells}S {self.capacity_mah:.0f} mAh, "
                f'{inch:.1f}" propellers, arm {fr.arm_m:.2f} m'
                + (f" (drawn {self.attempts} times)" if self.attempts > 1 else ""),
                f"  motor: KV {self.kv_rpm_per_v:.0f} (k_e {m.k_e:.5g} V·s/rad), R {m.R_ohm:.4g} ohm, "
                f"C_p {m.C_p:.4g}, B {m.B:.3g}, T_f {m.T_f:.3g}, k {m.k:g}, J {m.J_kg_m2:.3g} kg·m², "
                f"{self.motor_poles} poles",
                f"  hover: command {self.hover_command:.3f} (duty {self.hover_duty:.3f} at "
                f"{self.hover_bus_voltage_v:.1f} V), {self.hover_omega_rad_s:.0f} rad/s, "
                f"{self.hover_current_a:.2f} A per motor; thrust/weight {self.thrust_to_weight:.2f} at full command",
                f"  ESC: idle offset {self.esc.idle_offset:.4f}; current {sensing}",
                f"  telemetry: ESC reports {self.rate_hz:.0f} Hz, speed noise ±{self.speed_noise_rad_s:.1f} rad/s, "
                f"current noise ±{self.current_noise_a[0]:.2f}-{self.current_noise_a[1]:.2f} A; "
                f"tlog ESC stream {self.esc_stream_hz:.0f} Hz, commands {self.log_hz:.0f} Hz",
                f"  battery: {self.battery.resistance_ohm * 1e3:.1f} mOhm, starts at {100 * self.initial_soc:.0f} %, "
                f"monitor gain {self.battery.monitor_gain:.3f}",
                f"  flight: {self.turbulence} air; plan {duration:.0f} s of {', '.join(kinds)}",
            ]
        )


def draw_world(seed: int) -> World:
    """The world of ``seed`` (pure: the same seed gives the same world)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"a world's seed is an integer >= 0, not {seed!r}")
    rng = np.random.default_rng([int(seed), 0x5EED])
    for attempt in range(1, MAX_DRAWS + 1):
        world = _draw_once(int(seed), rng, attempt)
        if world is not None:
            return world
    raise RuntimeError(f"world {seed}: no feasible vehicle in {MAX_DRAWS} draws")  # pragma: no cover


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(math.exp(rng.uniform(math.log(low), math.log(high))))


def _draw_once(seed: int, rng: np.random.Generator, attempt: int) -> World | None:
    g = GRAVITY_M_S2
    # -- the drawn quantities (every draw is made whatever the outcome, so the stream stays aligned)
    mass = _log_uniform(rng, 1.0, 25.0)
    size = math.log(mass) / math.log(25.0)  # 0 (1 kg) .. 1 (25 kg)
    cells_target = 3.5 + 9.0 * size + rng.normal(0.0, 0.8)
    cells = min(CELL_COUNTS, key=lambda n: abs(n - cells_target))
    soc0 = float(rng.uniform(0.75, 1.0))
    disk_loading = float(rng.uniform(35.0, 70.0)) * (mass / 2.0) ** 0.2
    c_thrust = float(rng.uniform(0.09, 0.12))
    torque_ratio = float(rng.uniform(0.045, 0.075))
    hover_command = float(rng.uniform(0.35, 0.65))
    idle_offset = float(rng.uniform(0.0, 0.06))
    efficiency = float(rng.uniform(0.86, 0.95))
    loss_share = float(rng.uniform(0.005, 0.04))
    viscous_share = float(rng.uniform(0.3, 1.0))
    inertia_spread = float(rng.uniform(0.7, 1.4))
    endurance_h = float(rng.uniform(0.25, 0.45))
    cell_r_ohm_ah = float(rng.uniform(0.012, 0.035))
    monitor_gain = float(rng.uniform(0.97, 1.03))
    arm_ratio = float(rng.uniform(1.05, 1.25))
    body_inertia_spread = float(rng.uniform(0.8, 1.25))
    side = str(rng.choice(CURRENT_SIDES, p=[0.45, 0.35, 0.20]))
    averaging = "interval" if rng.random() < 0.5 else "filter"
    filter_s = _log_uniform(rng, 0.005, 0.05)
    gain = float(rng.uniform(0.75, 1.1))
    offset = float(rng.uniform(-0.3, 0.3))
    rate = 10.0 if rng.random() < 1.0 / 3.0 else _log_uniform(rng, 10.0, 200.0)
    speed_noise_share = float(rng.uniform(0.008, 0.03))
    current_noise_factor = float(rng.uniform(0.5, 1.5))
    log_hz = float(rng.choice([10.0, 25.0, 50.0]))
    turbulence = str(rng.choice(list(TURBULENCE), p=[0.4, 0.4, 0.2]))
    plan = flight_plan(rng, mass)

    # -- the propeller and the airframe
    hover_thrust = mass * g / 6.0
    diameter = min(max(math.sqrt(4.0 * hover_thrust / (math.pi * disk_loading)), 0.12), 1.0)
    thrust_coeff = c_thrust * RHO_AIR_KG_M3 * diameter**4 / (4.0 * math.pi**2)
    omega_h = math.sqrt(hover_thrust / thrust_coeff)
    torque_h = torque_ratio * diameter * hover_thrust
    c_p = torque_h / omega_h**3
    b_visc = loss_share * viscous_share * torque_h / omega_h
    t_f = loss_share * (1.0 - viscous_share) * torque_h
    arm = diameter * arm_ratio
    roll_inertia = 0.23 * mass * arm**2 * body_inertia_spread
    airframe = Airframe(
        mass_kg=mass,
        arm_m=arm,
        inertia_kg_m2=(roll_inertia, roll_inertia, 1.7 * roll_inertia),
        thrust_coeff=thrust_coeff,
        drag_n_s_m=0.35 * (arm / 0.275) ** 2,
        rot_damping_nm_s=0.002 * roll_inertia / REFERENCE_ROLL_INERTIA_KG_M2,
    )

    # -- the motor, designed for the hover point at the pack's voltage under the hover load
    esc = EscMap(idle_offset=idle_offset)
    hover_duty = float(esc.duty(np.array(hover_command)))
    load_torque_h = torque_h + b_visc * omega_h + t_f
    avionics = 0.4 + 0.05 * mass
    ocv = cells * cell_open_circuit_v(soc0)
    bus = design_bus = ocv
    k_e = r_ohm = i_h = capacity_ah = r_pack = 0.0
    for _ in range(4):  # the hover current, the pack sized for it, its sag: a few fixed-point rounds
        design_bus = bus
        v_h = hover_duty * bus
        k_e = efficiency * v_h / omega_h
        i_h = load_torque_h / k_e
        r_ohm = (v_h - k_e * omega_h) / i_h
        battery_a = 6.0 * hover_duty * i_h + avionics
        capacity_ah = max(round(battery_a * endurance_h / 0.8 * 10.0) / 10.0, 0.5)
        r_pack = cells * cell_r_ohm_ah / capacity_ah
        bus = ocv - r_pack * battery_a
    j_total = inertia_spread * (1.6e-5 * (diameter / 0.24) ** 4.5 + 4.0e-6 * (diameter / 0.24) ** 4)
    motor = MotorParams(
        R_ohm=r_ohm,
        k_e=k_e,
        C_p=c_p,
        B=b_visc,
        T_f=t_f,
        k=3.0,
        name=f"world {seed} motor",
        J_kg_m2=j_total,
    )

    # -- feasibility: thrust to spare at full command on the sagging pack
    full_v = ocv
    omega_max = 0.0
    for _ in range(4):
        state = steady_state(motor, [full_v])
        omega_max = float(state.omega_rad_s[0])
        full_v = max(ocv - r_pack * (6.0 * float(state.current_a[0]) + avionics), 0.5 * ocv)
    thrust_to_weight = 6.0 * thrust_coeff * omega_max**2 / (mass * g)
    if thrust_to_weight < MIN_THRUST_TO_WEIGHT or hover_duty < MIN_HOVER_DUTY:
        return None

    current_noise = (0.04 * i_h * current_noise_factor, 0.26 * i_h * current_noise_factor)
    full_pack_v = 4.2 * cells
    return World(
        seed=seed,
        mass_kg=mass,
        cells=cells,
        capacity_mah=capacity_ah * 1000.0,
        initial_soc=soc0,
        prop_diameter_m=diameter,
        disk_loading_n_m2=disk_loading,
        thrust_coefficient=c_thrust,
        torque_ratio=torque_ratio,
        hover_command=hover_command,
        voltage_efficiency=efficiency,
        loss_share=loss_share,
        motor=motor,
        motor_poles=14 if diameter < 0.45 else 28,
        airframe=airframe,
        battery=BatterySpec(
            cells=cells,
            capacity_mah=capacity_ah * 1000.0,
            resistance_ohm=r_pack,
            initial_soc=soc0,
            monitor_gain=monitor_gain,
        ),
        avionics_current_a=avionics,
        esc=esc,
        current=CurrentSensing(
            side=side,
            averaging=averaging,
            filter_s=filter_s,
            gain=gain,
            offset_a=offset,
            constant_a=0.0,
        ),
        rate_hz=rate,
        speed_noise_rad_s=speed_noise_share * omega_h,
        current_noise_a=current_noise,
        current_noise_voltage_v=(0.32 * full_pack_v, 0.87 * full_pack_v),
        esc_stream_hz=float(min(round(rate), 50)),
        log_hz=log_hz,
        turbulence=turbulence,
        plan=plan,
        hover_omega_rad_s=omega_h,
        hover_current_a=i_h,
        hover_duty=hover_duty,
        hover_bus_voltage_v=design_bus,
        thrust_to_weight=thrust_to_weight,
        attempts=attempt,
    )


def flight_plan(rng: np.random.Generator, mass_kg: float, duration_s: float = 150.0) -> tuple[Segment, ...]:
    """A manoeuvre plan of ``duration_s``: a take-off climb, then translations, yaw turns, climbs and
    descents between hovers, so the commands move over a range while the battery voltage barely does.
    Heavier vehicles translate and climb a little slower. The altitude never falls below the start."""
    pace = 1.0 / (1.0 + 0.25 * math.log(max(mass_kg, 1.0)))  # 1 at 1 kg, 0.55 at 25 kg

    def speed(low: float, high: float) -> float:
        return round(float(rng.uniform(low, high)) * pace, 2)

    def heading() -> float:
        return round(float(rng.uniform(-180.0, 180.0)), 1)

    raw: list[Segment] = [
        Segment("hover", 6.0),
        Segment("climb", 10.0, speed(1.2, 2.5)),  # take-off climb
        Segment("hover", 5.0),
        Segment("translate", 10.0, speed(2.0, 6.0), heading()),
        Segment("yaw", 6.0, 0.0, heading()),
        Segment("translate", 8.0, speed(2.0, 6.0), heading()),
        Segment("descend", 6.0, speed(0.8, 1.5)),
        Segment("hover", 5.0),
        Segment("yaw", 5.0, 0.0, heading()),
        Segment("climb", 6.0, speed(1.5, 3.0)),
        Segment("translate", 10.0, speed(2.0, 6.0), heading()),
        Segment("hover", 4.0),
        Segment("descend", 8.0, speed(0.8, 1.5)),
        Segment("translate", 8.0, speed(2.0, 6.0), heading()),
        Segment("yaw", 6.0, 0.0, heading()),
        Segment("climb", 5.0, speed(1.0, 2.5)),
        Segment("hover", 5.0),
        Segment("descend", 8.0, speed(0.8, 1.5)),
        Segment("translate", 8.0, speed(2.0, 6.0), heading()),
    ]
    # Descents no deeper than the climbs before them (the start altitude is the floor).
    plan: list[Segment] = []
    alt = 0.0
    for seg in raw:
        if seg.kind == "descend":
            seg = dataclasses.replace(seg, duration_s=round(min(seg.duration_s, alt / seg.speed_m_s), 2))
        alt += _climb_rate(seg) * seg.duration_s
        if seg.duration_s > 0:
            plan.append(seg)
    used = sum(s.duration_s for s in plan)
    if used < duration_s:
        plan.append(Segment("hover", round(duration_s - used, 2)))
    return tuple(plan)


def _climb_rate(seg: Segment) -> float:
    return seg.speed_m_s if seg.kind == "climb" else -seg.speed_m_s if seg.kind == "descend" else 0.0


def plan_altitude_m(
    segments: tuple[Segment, ...], start_alt_m: float, time_s: ArrayLike
) -> NDArray[np.float64]:
    """The altitude [m] a plan commands at each time (then holds its last altitude)."""
    t = np.asarray(time_s, dtype=float)
    edges = [0.0]
    alts = [start_alt_m]
    for seg in segments:
        edges.append(edges[-1] + seg.duration_s)
        alts.append(alts[-1] + _climb_rate(seg) * seg.duration_s)
    return np.interp(t, edges, alts)
