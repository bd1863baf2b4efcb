"""Diagnosis rules behind one hook (:class:`.base.Rule`): each a frozen config with a ``judge()`` that
carries its own state. The comparison rules a profile's ``[steady]`` names by ``kind`` are registered
here (:func:`.base.compare_rule`); the pipeline's other rules (sensors, bands, pairing, tree, slow look,
judged, sequential test, persistence) are in their modules and listed by
:meth:`..profile.ThresholdProfile.rules`."""

from .balance import BalanceRule
from .base import COMPARE_RULES, CompareRule, Frame, Rule, compare_rule
from .dynamic import DynamicRule
from .step import StepRule

__all__ = [
    "COMPARE_RULES",
    "BalanceRule",
    "CompareRule",
    "DynamicRule",
    "Frame",
    "Rule",
    "StepRule",
    "compare_rule",
]
