"""Timing-related sub-net of the trial clock: the *timeline*, one place per segment
between the interval ends of the formula (the thesis's absolute-clock reading, nets C-5).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from mitlc.petri.net import Guard
from mitlc.petri.parts import Arc, Part
from mitlc.spec import ast as A

__all__ = ["Threshold", "lower", "upper", "formula_thresholds", "segment_name", "timeline_net"]


@dataclass(frozen=True, order=True)
class Threshold:
    """The clock has passed ``value`` (``tau > value`` if strict, else ``tau >= value``)."""

    value: float
    strict: bool

    def clock(self) -> A.Interval:
        return A.Interval(self.value, math.inf, lo_closed=not self.strict)


def lower(i: A.Interval) -> Threshold | None:
    """The threshold the clock passes when ``i`` opens (None if open from 0)."""
    if i.lo == 0 and i.lo_closed:
        return None
    return Threshold(i.lo, not i.lo_closed)


def upper(i: A.Interval) -> Threshold | None:
    """The threshold the clock passes when ``i`` closes (None if unbounded)."""
    if math.isinf(i.hi):
        return None
    return Threshold(i.hi, i.hi_closed)


def formula_thresholds(f: A.Formula) -> list[Threshold]:
    """Every interval end of ``f`` the timeline must tell apart, in clock order."""
    out: set[Threshold] = set()
    for node in A.walk(f):
        if isinstance(node, (A.Eventually, A.Globally)) and not node.interval.is_unbounded:
            out.update(t for t in (lower(node.interval), upper(node.interval)) if t is not None)
        elif isinstance(node, A.Until) and lower(node.interval) is not None:
            out.add(lower(node.interval))  # type: ignore[arg-type]
    return sorted(out)


def segment_name(lo: Threshold | None, hi: Threshold | None) -> str:
    """The place name of the clock segment between two thresholds, e.g. ``p_1<tau<=2``."""
    left = "" if lo is None else f"{A.fmt_number(lo.value)}{'<' if lo.strict else '<='}"
    if hi is None:
        return f"p_tau{'>' if lo and lo.strict else '>='}{A.fmt_number(lo.value)}" if lo else "p_tau"
    right = f"{'<=' if hi.strict else '<'}{A.fmt_number(hi.value)}"
    return f"p_{left}tau{right}"


def timeline_net(th: Sequence[Threshold], unique: Callable[[str], str]) -> Part:
    """The timeline: a place per clock segment between thresholds ``th``, each passed to
    the next when the trial clock crosses their threshold."""
    bounds = [None, *th]
    places = []
    for i in range(len(th) + 1):
        lo = bounds[i]
        hi = th[i] if i < len(th) else None
        name = unique(segment_name(lo, hi))
        places.append((name, name[2:]))
    arcs: list[Arc] = [(i, i + 1, Guard.clock(t.clock())) for i, t in enumerate(th)]
    return Part("timeline", "timing", "timeline", places, arcs, 0, "trial clock")
