"""The model workbench: compare the model with measurements, explain what is missing, grow the model.

Pure numerics (numpy/scipy) on arrays taken once from a telemetry table; :mod:`.plots` is the only
module that draws (matplotlib, optional).
"""

from .compare import Comparison, ErrorStats, Region, compare
from .data import WorkbenchData, fit_base
from .dependence import VariableScore, distance_correlation, rank_variables
from .explain import EffectTrial, Explanation, explain
from .noise import NoiseFloor, noise_floor
from .steps import EffectSteps, Step, fit_with_effects

__all__ = [
    "Comparison",
    "EffectSteps",
    "EffectTrial",
    "ErrorStats",
    "Explanation",
    "NoiseFloor",
    "Region",
    "Step",
    "VariableScore",
    "WorkbenchData",
    "compare",
    "distance_correlation",
    "explain",
    "fit_base",
    "fit_with_effects",
    "noise_floor",
    "rank_variables",
]
