"""Diagnosis: the rules (comparison with the model, sensors, the fault decision tree, the sequential test,
persistence) behind one hook (:mod:`.rules`), the pipeline that loops over them, and profiles."""

from .pipeline import (
    DIAGNOSIS_COLUMNS,
    MotorBatch,
    MotorCarry,
    StreamingDiagnoser,
    diagnose,
    diagnose_motor,
    diagnose_motors,
)
from .profile import PersistenceRule, ThresholdProfile
from .rules import BalanceRule, CompareRule, DynamicRule, Rule, StepRule, compare_rule
from .states import MotorState, state_names
from .tree import classify

__all__ = [
    "DIAGNOSIS_COLUMNS",
    "BalanceRule",
    "CompareRule",
    "DynamicRule",
    "MotorBatch",
    "MotorCarry",
    "MotorState",
    "PersistenceRule",
    "Rule",
    "StepRule",
    "StreamingDiagnoser",
    "ThresholdProfile",
    "classify",
    "compare_rule",
    "diagnose",
    "diagnose_motor",
    "diagnose_motors",
    "state_names",
]
