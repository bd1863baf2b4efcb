"""Diagnosis: steady-state rule, the fault decision tree, persistence and profiles."""

from .pipeline import DIAGNOSIS_COLUMNS, MotorCarry, StreamingDiagnoser, diagnose, diagnose_motor
from .profile import PersistenceRule, SteadyRule, ThresholdProfile
from .states import MotorState, state_names
from .tree import classify

__all__ = [
    "DIAGNOSIS_COLUMNS",
    "MotorCarry",
    "MotorState",
    "PersistenceRule",
    "SteadyRule",
    "StreamingDiagnoser",
    "ThresholdProfile",
    "classify",
    "diagnose",
    "diagnose_motor",
    "state_names",
]
