"""The diagnosis pipeline for one motor: model → steady rule → tree → persistence.

:func:`diagnose_motor` is the single implementation. Replay calls it once per motor with whole arrays;
the live agent calls it with each new sample and the carry from the previous call (see
:class:`StreamingDiagnoser`). Both therefore announce exactly the same states.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..model.equations import steady_state
from ..model.params import MotorParams
from ..model.predict import predict_steady
from ..telemetry.table import TelemetryTable
from .persistence import PersistenceCarry, announce
from .profile import ThresholdProfile
from .states import MotorState
from .steady import SteadyCarry, steady_mask
from .tree import classify

__all__ = ["DIAGNOSIS_COLUMNS", "MotorCarry", "StreamingDiagnoser", "diagnose", "diagnose_motor"]

#: Columns every diagnosis result has, in this order (replay's ``diagnosis.csv``).
DIAGNOSIS_COLUMNS = (
    "time_s",
    "motor",
    "state",
    "announced",
    "steady",
    "omega_rad_s",
    "omega_model_rad_s",
    "current_a",
    "current_model_a",
    "voltage_v",
)


@dataclass(frozen=True)
class MotorCarry:
    """Everything the pipeline remembers about one motor between calls."""

    steady: SteadyCarry = field(default_factory=SteadyCarry)
    persistence: PersistenceCarry = field(default_factory=PersistenceCarry)


def diagnose_motor(
    params: MotorParams,
    profile: ThresholdProfile,
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    omega_rad_s: NDArray[np.float64],
    current_a: NDArray[np.float64],
    bus_voltage_v: NDArray[np.float64] | None = None,
    carry: MotorCarry | None = None,
    context: Mapping[str, NDArray[np.float64]] | None = None,
) -> tuple[dict[str, NDArray], MotorCarry]:
    """Diagnose one motor's samples (increasing time); returns result columns and the new carry.

    ``context`` holds the samples' other columns (temperatures, throttle, altitude...), which a model
    with fitted effects (``params.effects``) reads; the base model ignores it.
    """
    carry = carry or MotorCarry()
    model = predict_steady(params, voltage_v, context) if params.effects else steady_state(params, voltage_v)
    state = classify(
        profile,
        omega_rad_s=omega_rad_s,
        omega_model_rad_s=model.omega_rad_s,
        current_a=current_a,
        current_model_a=model.current_a,
        voltage_v=voltage_v,
        bus_voltage_v=bus_voltage_v,
    )
    steady, steady_carry = steady_mask(profile.steady, time_s, voltage_v, carry.steady)
    transient_ok = np.isin(state, [MotorState.F2_1, MotorState.F4_2])  # a stalled motor needs no steady input
    eligible = (steady | transient_ok) & (state != MotorState.NO_DATA)
    announced, persistence_carry = announce(
        profile.persistence.hold_s(), time_s, state, eligible, carry.persistence
    )
    columns = {
        "state": state,
        "announced": announced,
        "steady": steady,
        "omega_model_rad_s": model.omega_rad_s,
        "current_model_a": model.current_a,
    }
    return columns, MotorCarry(steady=steady_carry, persistence=persistence_carry)


def diagnose(
    table: TelemetryTable, params: MotorParams | dict[int, MotorParams], profile: ThresholdProfile
) -> TelemetryTable:
    """Diagnose every motor of a telemetry table; returns a table with :data:`DIAGNOSIS_COLUMNS` first.

    ``params`` is one motor model for all motors, or a model per motor number.
    """
    ordered = table.sorted_by_motor_time()
    voltage = ordered.voltage_v()
    bus = ordered.get("bus_voltage_v")
    out: dict[str, NDArray] = {
        "state": np.zeros(len(ordered), dtype=np.int8),
        "announced": np.zeros(len(ordered), dtype=np.int8),
        "steady": np.zeros(len(ordered), dtype=bool),
        "omega_model_rad_s": np.full(len(ordered), np.nan),
        "current_model_a": np.full(len(ordered), np.nan),
    }
    motors = ordered["motor"]
    for motor in ordered.motors():
        sel = np.flatnonzero(motors == motor)
        motor_params = params[motor] if isinstance(params, dict) else params
        context = None
        if motor_params.effects:
            context = {
                name: np.asarray(ordered[name][sel], dtype=float)
                for name in ordered.names
                if ordered[name].dtype.kind in "biuf"
            }
        cols, _ = diagnose_motor(
            motor_params,
            profile,
            ordered["time_s"][sel],
            voltage[sel],
            ordered["omega_rad_s"][sel],
            ordered["current_a"][sel],
            None if bus is None else bus[sel],
            context=context,
        )
        for name, values in cols.items():
            out[name][sel] = values
    result = {name: ordered[name] for name in ("time_s", "motor")}
    result.update(
        state=out["state"],
        announced=out["announced"],
        steady=out["steady"],
        omega_rad_s=ordered["omega_rad_s"],
        omega_model_rad_s=out["omega_model_rad_s"],
        current_a=ordered["current_a"],
        current_model_a=out["current_model_a"],
        voltage_v=voltage,
    )
    for name in ordered.names:
        result.setdefault(name, ordered[name])
    return TelemetryTable(result, source=table.source, meta=table.meta)


class StreamingDiagnoser:
    """Sample-by-sample diagnosis for the live agent: the same :func:`diagnose_motor`, carried per motor."""

    def __init__(self, params: MotorParams | dict[int, MotorParams], profile: ThresholdProfile) -> None:
        self.params = params
        self.profile = profile
        self.carries: dict[int, MotorCarry] = {}

    def update(
        self,
        motor: int,
        time_s: float,
        voltage_v: float,
        omega_rad_s: float,
        current_a: float,
        bus_voltage_v: float | None = None,
        context: Mapping[str, float] | None = None,
    ) -> dict[str, object]:
        """Diagnose one new sample of one motor; returns the result row (state codes as ints).

        ``context`` gives the sample's other variables for a model with effects.
        """
        motor_params = self.params[motor] if isinstance(self.params, dict) else self.params
        t = np.array([time_s])
        cols, self.carries[motor] = diagnose_motor(
            motor_params,
            self.profile,
            t,
            np.array([voltage_v]),
            np.array([omega_rad_s]),
            np.array([current_a]),
            None if bus_voltage_v is None else np.array([bus_voltage_v]),
            self.carries.get(motor),
            None if context is None else {k: np.array([v], dtype=float) for k, v in context.items()},
        )
        return {
            "time_s": time_s,
            "motor": motor,
            "omega_rad_s": omega_rad_s,
            "current_a": current_a,
            "voltage_v": voltage_v,
            **{k: v[0].item() for k, v in cols.items()},
        }

    def announced(self, motor: int) -> MotorState:
        carry = self.carries.get(motor)
        return MotorState(carry.persistence.announced if carry else MotorState.NORMAL)
