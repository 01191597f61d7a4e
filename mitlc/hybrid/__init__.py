"""Spec to hybrid automaton: classical step-response criteria (thesis chapter 3).

In: a :class:`mitlc.spec.Spec` with ``require`` lines (overshoot, rise time, settling
time, steady-state error). Out: :class:`HybridAutomaton` (modes, guarded edges, a
reward per mode, appendix B) from :func:`compile_requirements`, and the criteria
checker (:mod:`mitlc.hybrid.criteria`) that measures a step response directly.

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`, :mod:`mitlc.plants`,
:mod:`mitlc.spec`.
"""

from mitlc.hybrid.automaton import Edge, HybridAutomaton, Mode, Trace, render_bytes
from mitlc.hybrid.compile import DEFAULT_HORIZON, MODE_OF, ORDER, compile_requirements
from mitlc.hybrid.criteria import (
    DEFAULT_SETTLING_BAND,
    Measured,
    Verdict,
    check,
    measure,
)
from mitlc.hybrid.guards import (
    FALSE,
    TRUE,
    VARS,
    AllOf,
    AnyOf,
    Cmp,
    Guard,
    Lin,
    all_of,
    any_of,
    evaluate,
    guard_from_dict,
    guard_to_dict,
    interior,
    negate,
)
from mitlc.hybrid.rewards import (
    AbsError,
    Const,
    IfElse,
    Reward,
    RewardConstants,
    StayBonus,
)

__all__ = [
    "FALSE",
    "TRUE",
    "AbsError",
    "AllOf",
    "AnyOf",
    "Cmp",
    "Const",
    "DEFAULT_HORIZON",
    "DEFAULT_SETTLING_BAND",
    "Edge",
    "Guard",
    "HybridAutomaton",
    "IfElse",
    "Lin",
    "MODE_OF",
    "Measured",
    "Mode",
    "ORDER",
    "Reward",
    "RewardConstants",
    "StayBonus",
    "Trace",
    "VARS",
    "Verdict",
    "all_of",
    "any_of",
    "check",
    "compile_requirements",
    "evaluate",
    "guard_from_dict",
    "guard_to_dict",
    "interior",
    "measure",
    "negate",
    "render_bytes",
]
