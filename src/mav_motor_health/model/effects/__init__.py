"""Physical effects the paper's model leaves out, composable on top of it (see :mod:`.base`)."""

from .base import Effect, EffectParameter, ModelTerms, base_terms, compose, equation_residuals, solve
from .library import BUILTIN_EFFECTS
from .user import ENTRY_POINT_GROUP, available_effects, load_effects_file, resolve

__all__ = [
    "BUILTIN_EFFECTS",
    "ENTRY_POINT_GROUP",
    "Effect",
    "EffectParameter",
    "ModelTerms",
    "available_effects",
    "base_terms",
    "compose",
    "equation_residuals",
    "load_effects_file",
    "resolve",
    "solve",
]
