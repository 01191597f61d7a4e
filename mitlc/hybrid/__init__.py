"""Spec to hybrid automaton: classical step-response criteria (thesis chapter 3).

In: a :class:`mitlc.spec.Spec` with ``require`` lines (overshoot, rise time, settling
time, steady-state error). Out: :class:`HybridAutomaton` (modes, guarded edges, a
reward per mode, appendix B) from :func:`compile_requirements`, and the criteria
checker (:mod:`mitlc.hybrid.criteria`) that measures a step response directly.

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.plants`,
:mod:`mitlc.spec`.
"""

from mitlc.hybrid.automaton import HybridAutomaton, compile_requirements
from mitlc.hybrid.criteria import Measured, Verdict, check, measure

__all__ = ["HybridAutomaton", "Measured", "Verdict", "check", "compile_requirements", "measure"]
