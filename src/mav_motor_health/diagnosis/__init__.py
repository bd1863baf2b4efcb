"""Diagnosis: steady-state rule, the fault decision tree, persistence and profiles."""

from .pipeline import (
    DIAGNOSIS_COLUMNS,
    MotorBatch,
    MotorCarry,
    StreamingDiagnoser,
    diagnose,
    diagnose_motor,
    diagnose_motors,
)
from .profile import PersistenceRule, SteadyRule, ThresholdProfile
from .states import MotorState, state_names
from .tree import classify

__all__ = [
    "DIAGNOSIS_COLUMNS",
    "MotorBatch",
    "MotorCarry",
    "MotorState",
    "PersistenceRule",
    "SteadyRule",
    "StreamingDiagnoser",
    "ThresholdProfile",
    "classify",
    "diagnose",
    "diagnose_motor",
    "diagnose_motors",
    "state_names",
]
