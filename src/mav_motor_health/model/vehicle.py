"""A vehicle as identification knows it: its motor type, each motor's departure from it, its ESCs' command
→ duty map and how they report current, and the noise the healthy flight showed.

The diagnosis core works in the motor's own terms: the duty the ESC applies, the voltage the motor sees
(duty × bus voltage) and the ESC's input current in amperes. A log holds the autopilot's *command* and the
ESC's *reading*. :func:`calibrate_columns` turns one into the other with what identification found, in
one place, for replay (whole arrays) and the live agent (one motor's batch) alike:

* ``throttle`` becomes the duty, ``d = clip((c − c₀)/(1 − c₀), 0, 1)``; the command is kept as
  ``command``;
* ``voltage_v = d × bus_voltage_v``;
* the reading is divided by the sensor's gain; a *motor*-side (phase) reading is turned into the ESC's
  input current ``d × i`` the flight rule expects, an *input*-side reading is kept as it is; both give
  ``current_a`` (the motor current) as before; an *unusable* reading (constant, zero, not following the
  load) becomes NaN, so the diagnosis judges from the speed alone.

A motor-only params file (a bench fit) has no ESC map: :attr:`VehicleParams.esc` is None and the columns
pass unchanged, the command taken as the duty, as the project did before identification.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..telemetry.table import TelemetryTable
from .esc import DEFAULT_MIN_DUTY, motor_current_a
from .identify import CurrentReading, EscMap, Identification
from .params import MotorParams

__all__ = ["CURRENT_SIDES", "VehicleParams", "calibrate_columns", "esc_sum_checked"]

#: how an ESC's current reading relates to the motor: see :class:`~.identify.CurrentReading`
CURRENT_SIDES = ("input", "motor", "unusable")


@dataclass(frozen=True)
class VehicleParams:
    """What the diagnosis needs to know of one vehicle.

    ``motor`` is the motor type (with ``J_kg_m2`` for the flight rules); ``per_motor`` each motor's own
    model where identification measured it (R and k_e per motor, the rest the type's); ``esc`` and
    ``current`` the ESC map and current convention, None where unknown (a bench fit, a bundled motor);
    ``noise`` per motor the identification's residual RMS (``voltage_v`` of the electrical balance,
    ``torque_nm`` of the mechanical one); ``source`` free-form provenance (log, time span).
    """

    motor: MotorParams
    per_motor: Mapping[int, MotorParams] = field(default_factory=dict)
    esc: EscMap | None = None
    current: CurrentReading | None = None
    noise: Mapping[int, Mapping[str, float]] = field(default_factory=dict)
    source: Mapping[str, str] = field(default_factory=dict)

    @classmethod
    def identified(cls, found: Identification, source: Mapping[str, str] | None = None) -> VehicleParams:
        return cls(
            motor=found.params,
            per_motor=dict(found.per_motor),
            esc=found.esc,
            current=found.current,
            noise={m: dict(v) for m, v in found.noise.items()},
            source=dict(source or {}),
        )

    def models(self, motors: range | None = None) -> MotorParams | dict[int, MotorParams]:
        """The per-motor models the diagnosis takes: one model, or one per motor number (a motor the
        identification did not see gets the type)."""
        if not self.per_motor:
            return self.motor
        numbers = list(motors) if motors is not None else sorted(self.per_motor)
        return {n: self.per_motor.get(n, self.motor) for n in numbers}

    def calibrate(self, table: TelemetryTable) -> TelemetryTable:
        """The table in the motor's terms (:func:`calibrate_columns`); the same table where there is no
        ESC map. Its meta says whether the ESCs' sum may be checked against the battery monitor
        (``esc_sum_checked``, :func:`esc_sum_checked`)."""
        if self.esc is None:
            return table
        columns = calibrate_columns(table.columns, self.esc, self.current)
        meta = {**table.meta, "esc_sum_checked": esc_sum_checked(self.current)}
        return TelemetryTable(columns, source=table.source, meta=meta)

    def missing_for_flight(self) -> list[str]:
        """The keys the flight rules need that this file lacks (each named as in the TOML)."""
        missing = []
        if self.motor.J_kg_m2 is None:
            missing.append("motor.J_kg_m2 (the flight rules drop J·dω/dt without it)")
        if self.esc is None:
            missing.append("esc.idle_offset (the command is taken as the ESC's duty without it)")
        return missing


def esc_sum_checked(current: CurrentReading | None) -> bool:
    """Whether the ESC-sum plausibility check applies to this vehicle: yes where nothing is known (no
    vehicle file) and where identification related the ESCs' sum to the battery monitor (the gain from the
    battery); no where it could not (the gain assumed): the check would compare two currents this vehicle
    does not relate and flag every sample, setting a good current aside. (The check compares the sum with
    the whole battery current, not less the offset identification found: an offset is the least certain
    part of that fit, and a large one would excuse a sum that does not add up.)"""
    return current is None or current.gain_from == "battery"


def calibrate_columns(
    columns: Mapping[str, NDArray[np.float64]],
    esc: EscMap | None,
    current: CurrentReading | None,
    min_duty: float = DEFAULT_MIN_DUTY,
) -> dict[str, NDArray[np.float64]]:
    """The columns in the motor's terms (module docstring); unchanged where there is no ESC map or no
    command column. Works on any number of rows."""
    out = dict(columns)
    command = columns.get("throttle")
    bus = columns.get("bus_voltage_v")
    if esc is None or command is None or bus is None:
        return out
    command = np.asarray(command, dtype=float)
    duty = esc.duty(command)
    out["command"] = command
    out["throttle"] = duty
    out["voltage_v"] = duty * np.asarray(bus, dtype=float)
    excursion = columns.get("input_excursion_v")
    if excursion is not None:  # in the command's volts: in the duty's, the map's slope times that
        out["input_excursion_v"] = np.asarray(excursion, dtype=float) / (1.0 - esc.idle_offset)
    reading = columns.get("esc_current_a")
    if reading is None or current is None:
        return out
    reading = np.asarray(reading, dtype=float)
    if current.side == "unusable":
        out["esc_current_a"] = np.full(reading.shape, np.nan)
        out["current_a"] = np.full(reading.shape, np.nan)
        return out
    gain = current.gain if math.isfinite(current.gain) and current.gain > 0 else 1.0
    true = reading / gain
    if current.side == "motor":
        out["esc_current_a"] = duty * true
        out["current_a"] = np.where(duty >= min_duty, true, np.nan)
    else:
        out["esc_current_a"] = true
        out["current_a"] = motor_current_a(true, duty, min_duty)
    return out
