"""The motor model: parameters, steady-state equations and their estimation."""

from .equations import SteadyState, current_from_speed, steady_state, voltage_from_current_speed
from .estimation import FitResult, estimate
from .lsq import LeastSquaresFit, accuracy_pct, fit_least_squares, fit_linear
from .params import PARAMETER_UNITS, MotorParams

__all__ = [
    "PARAMETER_UNITS",
    "FitResult",
    "LeastSquaresFit",
    "MotorParams",
    "SteadyState",
    "accuracy_pct",
    "current_from_speed",
    "estimate",
    "fit_least_squares",
    "fit_linear",
    "steady_state",
    "voltage_from_current_speed",
]
