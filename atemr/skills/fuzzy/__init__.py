"""Fuzzy inference engines as data: YAML or fuzzylite `.fll` in, vectorised numpy evaluation out.

Use::

    from atemr.skills.fuzzy import load_builtin_engine
    idle = load_builtin_engine("idle")
    out = idle.process({"FR": ranges_fr, "FL": ..., ...})   # arrays of N rows → {"linSteer": (N,), ...}
"""

from atemr.skills.fuzzy.blend import FUZZY_RADIUS_OF_INTEREST_M, MANUAL_ENGINE_SPEED_LIMIT_MPS, blend
from atemr.skills.fuzzy.engine import Engine, FuzzyInputError, InputVariable, OutputVariable, RuleBlock
from atemr.skills.fuzzy.loader import BUILTIN_ENGINES, load_builtin_engine, load_engine, resolve_engine

__all__ = [
    "BUILTIN_ENGINES",
    "FUZZY_RADIUS_OF_INTEREST_M",
    "MANUAL_ENGINE_SPEED_LIMIT_MPS",
    "Engine",
    "FuzzyInputError",
    "InputVariable",
    "OutputVariable",
    "RuleBlock",
    "blend",
    "load_builtin_engine",
    "load_engine",
    "resolve_engine",
]
