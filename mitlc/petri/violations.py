"""Violation sub-nets (``--violations permanent | counted``, docs/semantics.md section 6):
a watch per safety or deadline part that records a violation, a ``late`` place for an
eventually whose deadline passed, and the bounds of the reward that size the penalty.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from mitlc.petri import reward as R
from mitlc.petri.net import Guard, GuardTerm, Net, eval_state
from mitlc.petri.options import CompileOptions
from mitlc.petri.parts import Part
from mitlc.petri.reading import negate_state
from mitlc.petri.timeline import Threshold
from mitlc.spec import ast as A

__all__ = ["ViolationWatches", "MAX_PAIRS", "bounds_all_steps", "bounds_without_violation"]


def _complement_clock(i: A.Interval) -> list[A.Interval]:
    """The clock outside ``i``: up to two intervals."""
    out = []
    if i.lo > 0 or not i.lo_closed:
        out.append(A.Interval(0.0, i.lo, True, not i.lo_closed))
    if not math.isinf(i.hi):
        out.append(A.Interval(i.hi, math.inf, not i.hi_closed))
    return out


class ViolationWatches:
    """The violation sub-nets of the compiler's builder (a mixin: the builder holds the state)."""

    options: CompileOptions
    cache: dict[object, list[str]]
    timing: list[Part]
    violation_nets: list[Part]
    penalties: list[str]
    segments: list[str]
    thresholds: list[Threshold]
    end: float | None
    where: dict[str, tuple[list[str], list[str]]]
    _unique: Callable[[str], str]

    def _segments_clock(self, segs: frozenset[int] | None) -> A.Interval | None:
        """The clock interval covered by contiguous timeline segments (None: all time)."""
        if not self.segments or segs is None or len(segs) == len(self.segments):
            return None
        first, last = min(segs), max(segs)
        if first == 0:
            lo, lo_closed = 0.0, True
        else:
            th = self.thresholds[first - 1]
            lo, lo_closed = th.value, not th.strict
        if last == len(self.segments) - 1:
            return A.Interval(lo, math.inf, lo_closed)
        th = self.thresholds[last]
        return A.Interval(lo, th.value, lo_closed, th.strict)

    def _watch(
        self,
        label: str,
        bad: A.Formula,
        segs: frozenset[int] | None,
        text: str,
        counted: bool = False,
        clock: A.Interval | None = None,
    ) -> None:
        """A violation sub-net: it records that ``bad`` held while the part was active."""
        mode = self.options.violations
        if mode == "off":
            return
        key = ("watch", bad, segs, clock)
        if key in self.cache:
            return
        clock = clock if clock is not None else self._segments_clock(segs)
        guard = Guard((GuardTerm(bad, clock),))
        ok = self._unique(f"p_ok_{label}")
        if mode == "counted" and counted:
            bad_place, count = self._unique(f"p_bad_{label}"), self._unique(f"p_count_{label}")
            back = Guard(
                (GuardTerm(negate_state(bad)),)
                + tuple(GuardTerm(clock=c) for c in (_complement_clock(clock) if clock else []))
            )
            sub = Part(
                f"violations {label}",
                "violation",
                "violation",
                [(ok, f"ok,{label}"), (bad_place, f"bad,{label}"), (count, f"count,{label}")],
                [(0, (1, 2), guard), (1, 0, back)],
                0,
                text,
                counters=(2,),
            )
            self.penalties.append(count)
        else:
            viol = self._unique(f"p_violated_{label}")
            sub = Part(
                f"violations {label}",
                "violation",
                "violation",
                [(ok, f"ok,{label}"), (viol, f"violated,{label}")],
                [(0, 1, guard)],
                0,
                text,
            )
            self.penalties.append(viol)
        self.cache[key] = [ok]
        self.violation_nets.append(sub)

    def _late(self, key: tuple, f: A.Eventually) -> None:
        """Give an eventually net a ``late`` place: the deadline (or the trial) passed before it was met."""
        if self.options.violations == "off" or ("late",) + key in self.cache:
            return
        terms = []
        if not math.isinf(f.interval.hi) and (self.end is None or f.interval.hi < self.end):
            terms.append(GuardTerm(clock=A.Interval(f.interval.hi, math.inf, lo_closed=not f.interval.hi_closed)))
        elif self.end is not None:  # still pending at the last sample (done comes first if met there)
            terms.append(GuardTerm(clock=A.Interval(self.end, math.inf)))
        if not terms:
            return
        deadline = Guard(tuple(terms))
        sub = next(s for s in self.timing if s.places and s.places[0][0] == self.cache[key][0])
        label = sub.places[0][1].split(",", 1)[1]
        late = self._unique(f"p_late_{label}")
        sub.places.append((late, f"late,{label}"))
        sub.arcs.append((0, len(sub.places) - 1, deadline))
        self.penalties.append(late)
        self.cache[("late",) + key] = [late]


MAX_PAIRS = 200_000
"""Most marking pairs enumerated to bound the reward of steps without a violation."""


def _pairs(net: Net) -> tuple[np.ndarray, np.ndarray] | None:
    """Every one-move step of the net as (M_k, M_k+1) arrays, or None if there are too many."""
    count = 1
    for sub in net.subnets:  # exact integers, stopping at the limit (a float product overflows: 500 sub-nets)
        count *= len(sub.places) ** 2
        if count > MAX_PAIRS:
            return None
    pairs = list(net.step_pairs())
    return np.array([a for a, _ in pairs]), np.array([b for _, b in pairs])


def bounds_all_steps(net: Net, reward: R.RExpr) -> tuple[float, float]:
    """Bounds of ``reward`` over every one-move step (interval bounds if there are too many)."""
    pairs = _pairs(net)
    if pairs is None:
        return R.bounds(reward)
    lo, hi = R.pair_bounds(reward, *pairs)  # graded propositions: over every state the pair allows
    return float(lo.min()), float(hi.max())


def _contains(outer: A.Interval, inner: A.Interval) -> bool:
    lo_ok = outer.lo < inner.lo or (outer.lo == inner.lo and (outer.lo_closed or not inner.lo_closed))
    hi_ok = outer.hi > inner.hi or (outer.hi == inner.hi and (outer.hi_closed or not inner.hi_closed))
    return lo_ok and hi_ok


def bounds_without_violation(builder: ViolationWatches, net: Net, reward: R.RExpr) -> tuple[float, float]:
    """Bounds of ``reward`` over the steps on which no watched part is violated.

    Every one-move step of the net is enumerated; a step is left out when a
    violation place is marked after it, or when a watch's guard surely holds
    on it (its state condition holds for the propositions the region places
    say, and its clock interval covers the timeline segment) although the
    watch stayed quiet. Falls back to interval bounds of the whole tree when
    there are too many steps.
    """
    both = _pairs(net)
    if both is None:
        return R.bounds(reward)
    prev, now = both
    n = len(prev)
    idx = {p.name: i for i, p in enumerate(net.places)}
    keep = np.ones(n, dtype=bool)
    for name in builder.penalties:  # at or after a violation (its reward is pinned or penalised)
        keep &= now[:, idx[name]] == 0
    truth = {a: now[:, [idx[n] for n in pos]].sum(axis=1) > 0 for a, (pos, _) in builder.where.items()}
    segments = {i: builder._segments_clock(frozenset({i})) for i in range(len(builder.segments))}
    for sub in net.subnets:
        if sub.role != "violation":
            continue
        ok = sub.places[0]
        for t in sub.transitions:
            tr = net.transitions[t]
            if net.place_index(tr.inputs[0]) != ok:
                continue
            for term in tr.guard.terms:
                sure = np.ones(n, bool)
                if term.state is not None:  # broadcast: a constant has no proposition to take the shape of
                    sure &= np.broadcast_to(eval_state(term.state, truth), (n,))
                if term.clock is not None:
                    covered = np.zeros(n, dtype=bool)
                    for i, seg in segments.items():
                        if seg is not None and _contains(term.clock, seg):
                            covered |= now[:, idx[builder.segments[i]]] > 0
                    sure &= covered
                keep &= ~sure
        keep &= now[:, ok] > 0
    if not keep.any():
        return R.bounds(reward)
    lo, hi = R.pair_bounds(reward, prev[keep], now[keep])
    return float(lo.min()), float(hi.max())
