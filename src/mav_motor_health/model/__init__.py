"""The motor model: parameters, steady-state equations and their estimation."""

from .equations import SteadyState, current_from_speed, steady_state, voltage_from_current_speed
from .estimation import EquationFit, FitResult, accuracy_pct, estimate
from .params import PARAMETER_UNITS, MotorParams

__all__ = [
    "PARAMETER_UNITS",
    "EquationFit",
    "FitResult",
    "MotorParams",
    "SteadyState",
    "accuracy_pct",
    "current_from_speed",
    "estimate",
    "steady_state",
    "voltage_from_current_speed",
]
