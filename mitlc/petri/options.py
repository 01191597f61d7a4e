"""How the compiler reads the parts the thesis leaves open: :class:`CompileOptions`.

Its own module so that the builder (:mod:`mitlc.petri.compile`) and its violation watches
(:mod:`mitlc.petri.violations`) both read it without importing each other;
``mitlc.petri.compile.CompileOptions`` and ``mitlc.CompileOptions`` are the same class.
"""

from __future__ import annotations

from dataclasses import dataclass

from mitlc.spec.model import Spec

__all__ = ["CompileOptions"]


@dataclass(frozen=True)
class CompileOptions:
    """How the compiler reads the parts the thesis leaves open."""

    conjunction: str = "literal"
    """``literal``: ``&`` is the min over all terms, as (4-13)..(4-17).
    ``active``: the min over the terms whose timing gate is open (docs/semantics.md)."""

    violations: str = "off"
    """``off``: the thesis's nets.  ``permanent``: an absorbing violated place per
    safety or deadline part, and from a violation on every step costs enough that
    it earns less than any violation-free step.  ``counted``: safety parts count
    their violations and each costs that once (docs/semantics.md, section 6)."""

    clock: str = "standard"
    """``standard``: a nested interval is measured from the moment its enclosing
    obligation starts (MITL; timed obligation sub-nets, :mod:`mitlc.petri.timed`).
    ``trial``: every interval on the trial clock, the thesis's reading (net C-5)."""

    reward: str = "net"
    """``net``: Table 4-2's reward, each proposition a flat +1 / -1 (``p_a - p_not_a``).
    ``graded``: each proposition's grade instead, its robustness normalised by the state bounds
    and clipped to [-1, 1] (:mod:`mitlc.spec.grades`). ``shaped``: the mean of the two, so
    the step at the region's boundary is kept and either side is graded (docs/semantics.md).
    ``sparse``, ``robustness``, ``robustness-window``: the field's rewards, paid by the monitor
    (:mod:`mitlc.monitor.rewards`); the net is Table 4-2's, which the learner's places follow."""

    @staticmethod
    def from_spec(spec: Spec, **overrides: str | None) -> CompileOptions:
        values = {name: spec.option(name) for name in ("conjunction", "violations", "clock", "reward")}
        values.update({k: v for k, v in overrides.items() if v is not None})
        return CompileOptions(**values)
