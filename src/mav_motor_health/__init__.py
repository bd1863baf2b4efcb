"""mav-motor-health: which hexacopter motor is failing, and how.

The pure core (model, estimation, diagnosis) takes numpy arrays and frozen dataclasses; sources and
sinks around it do the I/O.
"""

from .config import load_motor_params, load_profile
from .diagnosis import MotorState, StreamingDiagnoser, ThresholdProfile, classify, diagnose
from .errors import ConfigError, DataError, FitError, LinkError, LogFormatError, MotorHealthError
from .model import FitResult, MotorParams, accuracy_pct, estimate, steady_state
from .telemetry import TelemetryTable, read_csv

__version__ = "0.1.0"

__all__ = [
    "ConfigError",
    "DataError",
    "FitError",
    "FitResult",
    "LinkError",
    "LogFormatError",
    "MotorHealthError",
    "MotorParams",
    "MotorState",
    "StreamingDiagnoser",
    "TelemetryTable",
    "ThresholdProfile",
    "__version__",
    "accuracy_pct",
    "classify",
    "diagnose",
    "estimate",
    "load_motor_params",
    "load_profile",
    "read_csv",
    "steady_state",
]
