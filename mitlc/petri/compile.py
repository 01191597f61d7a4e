"""Compile a spec into a reward system: one composed Petri net and a reward expression.

Steps (docs/semantics.md explains each):

1. :func:`~mitlc.spec.passes.normal_form`: derived operators to primitives, negation to atoms.
2. :func:`reward_reading`: release ``a R_I b`` becomes ``(b U_I (a & b)) | G_I b``.
3. State-related sub-nets: the propositions are grouped so that every group's
   regions are provably disjoint (interval analysis); each group is one region
   net with a place per proposition plus "none" (for a group of one: ``p_a``,
   ``p_not_a``) and a transition between every two places.
4. Timing-related sub-nets: one *timeline* over the trial clock for all
   interval ends, a pending/done net for ``F`` of a state formula, a two-phase
   net for untimed ``U``, and one shared cycle for a conjunction of ``G F``.
5. The reward of Table 4-2, composed over the formula.

>>> from mitlc.spec.parse import parse_spec
>>> rs = compile_spec(parse_spec('''
... prop kappa = abs(q) < 0.3
... formula F G kappa'''))
>>> rs.net.place_names, rs.net.D.tolist()
(('p_kappa', 'p_not_kappa'), [[-1, 1], [1, -1]])
>>> print(rs.reward)
(1 + ~p_kappa) * (p_kappa - p_not_kappa)
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from mitlc.spec import ast as A
from mitlc.spec import predicates as P
from mitlc.petri import reward as R
from mitlc.errors import CompileError
from mitlc.petri.net import Guard, GuardTerm, Net, Place, SubNet, Transition, eval_state
from mitlc.spec.passes import is_state_formula, normal_form, push_negations
from mitlc.spec.model import Spec

__all__ = ["CompileOptions", "RewardSystem", "compile_spec", "reward_reading", "state_groups"]


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

    @staticmethod
    def from_spec(spec: Spec, **overrides: str | None) -> "CompileOptions":
        values = {"conjunction": spec.option("conjunction"), "violations": spec.option("violations")}
        values.update({k: v for k, v in overrides.items() if v is not None})
        return CompileOptions(**values)


@dataclass(frozen=True)
class RewardSystem:
    """What the compiler produces: the net, the reward, and how they were made."""

    spec: Spec
    normal_form: A.Formula
    net: Net
    reward: R.RExpr
    groups: tuple[tuple[str, ...], ...]
    options: CompileOptions
    penalty: float = 0.0
    """``c``: with ``permanent`` subtracted on every step from the first violation on,
    with ``counted`` once per violation; 0 with ``off``."""
    charge: R.RExpr | None = None
    """What ``c`` multiplies (``reward = base - c * charge``): ``v`` (0/1) with ``permanent``,
    the number of new violations with ``counted``; ``None`` with ``off``."""

    @property
    def atoms(self) -> tuple[str, ...]:
        return tuple(a for g in self.groups for a in g)


# ------------------------------------------------------------------ passes


def reward_reading(f: A.Formula) -> A.Formula:
    """Rewrite release into until and always, the operators the net implements.

    ``a R_I b`` becomes ``(b U_I (a & b)) | G_I b``, exact for the untimed
    operator (``a R b = b W (a & b)``) and the net's reading for intervals.

    >>> from mitlc.spec.parse import parse_formula
    >>> print(reward_reading(parse_formula("a R b")))
    b U (a & b) | G b
    """
    if isinstance(f, A.Release):
        left, right = reward_reading(f.left), reward_reading(f.right)
        return A.Or(A.Until(right, A.And(left, right), f.interval), A.Globally(right, f.interval), pos=f.pos)
    if not f.children:
        return f
    kids = [reward_reading(c) for c in f.children]
    if isinstance(f, (A.And, A.Or)):
        return f.__class__(kids[0], kids[1], pos=f.pos)
    if isinstance(f, A.Until):
        return A.Until(kids[0], kids[1], f.interval, pos=f.pos)
    if isinstance(f, A.Not):
        return A.Not(kids[0], pos=f.pos)
    if isinstance(f, A.Weighted):
        return A.Weighted(f.weight, kids[0], pos=f.pos)
    if isinstance(f, (A.Eventually, A.Globally)):
        return f.__class__(kids[0], f.interval, pos=f.pos)
    raise CompileError(f"cannot compile {type(f).__name__} (run normal_form first)")


def _strip(f: A.Formula) -> A.Formula:
    """Drop weights (they do not change truth)."""
    if isinstance(f, A.Weighted):
        return _strip(f.child)
    if isinstance(f, A.Not):
        return A.Not(_strip(f.child))
    if isinstance(f, (A.And, A.Or)):
        return f.__class__(_strip(f.left), _strip(f.right))
    return f


def _peel(f: A.Formula) -> tuple[float, A.Formula]:
    w = 1.0
    while isinstance(f, A.Weighted):
        w *= f.weight
        f = f.child
    return w, f


def _flatten(f: A.Formula, cls: type) -> list[A.Formula]:
    if isinstance(f, cls):
        return _flatten(f.left, cls) + _flatten(f.right, cls)  # type: ignore[attr-defined]
    return [f]


def _recurrence(f: A.Formula) -> tuple[float, A.Formula] | None:
    """``w * G F phi`` with both untimed and phi a state formula -> (w, phi)."""
    w1, g = _peel(f)
    if not (isinstance(g, A.Globally) and g.interval.is_unbounded):
        return None
    w2, ev = _peel(g.child)
    if not (isinstance(ev, A.Eventually) and ev.interval.is_unbounded and is_state_formula(ev.child)):
        return None
    return w1 * w2, ev.child


def _conj(a: A.Formula, b: A.Formula) -> A.Formula:
    if a == A.Const(True):
        return b
    if b == A.Const(True):
        return a
    return A.And(a, b)


def _disj(a: A.Formula, b: A.Formula) -> A.Formula:
    if A.Const(True) in (a, b):
        return A.Const(True)
    return A.Or(a, b)


def trigger(f: A.Formula) -> A.Formula:
    """A state condition that must hold at time t for ``f`` to hold at t (true if none).

    It guards the switch of an untimed until from its left to its right phase.
    """
    w, f = _peel(f)
    if is_state_formula(f):
        return _strip(f)
    if isinstance(f, A.And):
        return _conj(trigger(f.left), trigger(f.right))
    if isinstance(f, A.Or):
        return _disj(trigger(f.left), trigger(f.right))
    if isinstance(f, A.Globally):
        return trigger(f.child) if f.interval.lo == 0 and f.interval.lo_closed else A.Const(True)
    if isinstance(f, A.Until):
        if f.interval.lo == 0 and f.interval.lo_closed:
            return _disj(trigger(f.left), trigger(f.right))
        return trigger(f.left)
    return A.Const(True)


# ------------------------------------------------------------------ state groups


def state_groups(spec: Spec, names: Sequence[str]) -> tuple[tuple[str, ...], ...]:
    """Group propositions so that the regions within a group are provably disjoint.

    Greedy, in the order given: each proposition joins the first group whose
    members it is disjoint from, else starts a new group.
    """
    doms = spec.domains()
    groups: list[list[str]] = []
    for name in names:
        pred = spec.prop(name).pred
        for g in groups:
            if all(P.provably_disjoint(pred, spec.prop(m).pred, doms) for m in g):
                g.append(name)
                break
        else:
            groups.append([name])
    return tuple(tuple(g) for g in groups)


def _covers(spec: Spec, members: Sequence[str]) -> bool:
    """True if the members' regions provably cover the whole state space."""
    preds = [spec.prop(m).pred for m in members]
    union = preds[0]
    for p in preds[1:]:
        union = P.POr(union, p)
    return P.provably_empty(P.PNot(union), spec.domains())


# ------------------------------------------------------------------ threshold timeline


@dataclass(frozen=True, order=True)
class _Threshold:
    """The clock has passed ``value`` (``tau > value`` if strict, else ``tau >= value``)."""

    value: float
    strict: bool

    def clock(self) -> A.Interval:
        return A.Interval(self.value, math.inf, lo_closed=not self.strict)


def _lower(i: A.Interval) -> _Threshold | None:
    if i.lo == 0 and i.lo_closed:
        return None
    return _Threshold(i.lo, not i.lo_closed)


def _upper(i: A.Interval) -> _Threshold | None:
    if math.isinf(i.hi):
        return None
    return _Threshold(i.hi, i.hi_closed)


def _thresholds(f: A.Formula) -> list[_Threshold]:
    out: set[_Threshold] = set()
    for node in A.walk(f):
        if isinstance(node, (A.Eventually, A.Globally)) and not node.interval.is_unbounded:
            out.update(t for t in (_lower(node.interval), _upper(node.interval)) if t is not None)
        elif isinstance(node, A.Until) and _lower(node.interval) is not None:
            out.add(_lower(node.interval))  # type: ignore[arg-type]
    return sorted(out)


def _segment_name(lo: _Threshold | None, hi: _Threshold | None) -> str:
    left = "" if lo is None else f"{A.fmt_number(lo.value)}{'<' if lo.strict else '<='}"
    if hi is None:
        return f"p_tau{'>' if lo and lo.strict else '>='}{A.fmt_number(lo.value)}" if lo else "p_tau"
    right = f"{'<=' if hi.strict else '<'}{A.fmt_number(hi.value)}"
    return f"p_{left}tau{right}"


# ------------------------------------------------------------------ builder


@dataclass
class _Sub:
    name: str
    kind: str
    role: str
    places: list[tuple[str, str]]  # (name, label)
    arcs: list[tuple[int, int | tuple[int, ...], Guard]]  # local src, local dst(s), guard
    initial: int
    formula: str = ""
    counters: tuple[int, ...] = ()  # local indices of counting places (outside the one-token set)


def _negate_state(f: A.Formula) -> A.Formula:
    return push_negations(A.Not(f))


def _complement_clock(i: A.Interval) -> list[A.Interval]:
    """The clock outside ``i``: up to two intervals."""
    out = []
    if i.lo > 0 or not i.lo_closed:
        out.append(A.Interval(0.0, i.lo, True, not i.lo_closed))
    if not math.isinf(i.hi):
        out.append(A.Interval(i.hi, math.inf, not i.hi_closed))
    return out


def _tokens(names: Sequence[str], prev: bool = False) -> R.Tokens:
    return R.Tokens((), tuple(names), prev)


class _Builder:
    def __init__(self, spec: Spec, options: CompileOptions, formula: A.Formula) -> None:
        self.spec = spec
        self.options = options
        self.timing: list[_Sub] = []
        self.violation_nets: list[_Sub] = []
        self.penalties: list[str] = []  # places whose new tokens are penalised
        self.end = _last_sample(spec)
        self.cache: dict[object, list[str]] = {}  # one timing sub-net per distinct subformula
        self.used_names: set[str] = set()
        self.counter = 0
        names = A.atoms(formula)
        for n in names:
            spec.prop(n)  # undefined propositions were caught by the parser
        self.groups = state_groups(spec, names)
        self.state: list[_Sub] = [self._region_net(g) for g in self.groups]
        # atom -> (places where it holds, places where it does not)
        self.where: dict[str, tuple[list[str], list[str]]] = {}
        for g, sub in zip(self.groups, self.state):
            all_names = [n for n, _ in sub.places]
            for a in g:
                pos = [f"p_{a}"]
                self.where[a] = (pos, [n for n in all_names if n not in pos])
        self.thresholds = _thresholds(formula)
        self.segments: list[str] = []
        if self.thresholds:
            self._timeline()

    # -- naming
    def _unique(self, name: str) -> str:
        base, k = name, 1
        while name in self.used_names:
            k += 1
            name = f"{base}_{k}"
        self.used_names.add(name)
        return name

    def _label(self, f: A.Formula, prefix: str) -> str:
        _, core = _peel(f)
        if isinstance(core, A.Atom):
            return core.name
        if isinstance(core, A.Not) and isinstance(core.child, A.Atom):
            return f"not_{core.child.name}"
        self.counter += 1
        return f"{prefix}{self.counter}"

    # -- sub-nets
    def _region_net(self, group: tuple[str, ...]) -> _Sub:
        places = [(self._unique(f"p_{a}"), a) for a in group]
        regions: list[A.Formula] = [A.Atom(a) for a in group]
        if not _covers(self.spec, group):
            if len(group) == 1:
                places.append((self._unique(f"p_not_{group[0]}"), f"!{group[0]}"))
                regions.append(A.Not(A.Atom(group[0])))
            else:
                places.append((self._unique("p_none_" + "_".join(group)), "none"))
                none: A.Formula = A.Not(A.Atom(group[0]))
                for a in group[1:]:
                    none = A.And(none, A.Not(A.Atom(a)))
                regions.append(none)
        arcs = [
            (i, j, Guard.state(regions[j]))
            for i in range(len(places))
            for j in range(len(places))
            if i != j
        ]
        initial = self._initial_region(group)
        return _Sub(f"region({', '.join(group)})", "state", "region", places, arcs, initial)

    def _initial_region(self, group: tuple[str, ...]) -> int:
        point = self._init_point()
        if point is not None:
            for i, a in enumerate(group):
                pred = self.spec.prop(a).pred
                if all(v.name in point for v in P.variables(pred)) and bool(P.evaluate(pred, point)):
                    return i
        return len(group) if not _covers(self.spec, group) else 0

    def _init_point(self) -> dict[str, float] | None:
        spec = self.spec
        if not spec.init:
            return None
        point = {r.var: 0.5 * (r.lo + r.hi) for r in spec.init}
        plant = spec.plant
        if plant is not None:
            for v in plant.state:
                point.setdefault(v.name, 0.0)
                if v.periodic:
                    point[v.name] = float((point[v.name] + math.pi) % (2 * math.pi) - math.pi)
        return point

    def _timeline(self) -> None:
        th = self.thresholds
        bounds = [None, *th]
        places = []
        for i in range(len(th) + 1):
            lo = bounds[i]
            hi = th[i] if i < len(th) else None
            name = self._unique(_segment_name(lo, hi))
            places.append((name, name[2:]))
        arcs = [(i, i + 1, Guard.clock(t.clock())) for i, t in enumerate(th)]
        self.segments = [n for n, _ in places]
        self.timing.append(_Sub("timeline", "timing", "timeline", places, arcs, 0, "trial clock"))

    def _phase(self, interval: A.Interval) -> frozenset[int]:
        n = len(self.segments)
        lo, hi = _lower(interval), _upper(interval)
        start = 0 if lo is None else self.thresholds.index(lo) + 1
        stop = n if hi is None else self.thresholds.index(hi) + 1
        return frozenset(range(start, stop))

    def _all(self) -> frozenset[int]:
        return frozenset(range(len(self.segments)))

    def _seg_tokens(self, segs: frozenset[int], prev: bool = False) -> R.Tokens:
        return _tokens([self.segments[i] for i in sorted(segs)], prev)

    # -- indicators and rewards of state formulas
    def _h(self, f: A.Formula, prev: bool = True) -> R.RExpr:
        """0/1 indicator that state formula ``f`` holds, read off the marking."""
        _, f = _peel(f)
        if isinstance(f, A.Const):
            return R.ONE if f.value else R.ZERO
        if isinstance(f, A.Atom):
            return _tokens(self.where[f.name][0], prev)
        if isinstance(f, A.Not) and isinstance(f.child, A.Atom):
            return _tokens(self.where[f.child.name][1], prev)
        if isinstance(f, A.And):
            return R.Min(tuple(self._h(c, prev) for c in _flatten(f, A.And)))
        if isinstance(f, A.Or):
            return R.Max(tuple(self._h(c, prev) for c in _flatten(f, A.Or)))
        raise CompileError(f"not a state formula: {f}")

    # -- rewards
    def reward(self, f: A.Formula, ctx: frozenset[int], under_g: bool, conj: bool = False) -> R.RExpr:
        """The reward of ``f`` active on timeline segments ``ctx``.

        ``under_g``: ``f`` sits under an always (its eventually nets get no done place).
        ``conj``: ``f`` must hold for the whole formula to hold (it is reached from
        the root through ``&``, weights and timeline phases only), so its
        violations may be tracked.
        """
        if isinstance(f, A.Const):
            return R.Const(1.0 if f.value else -1.0)
        if isinstance(f, A.Atom):
            pos, neg = self.where[f.name]
            return R.Sum((_tokens(pos), R.Neg(_tokens(neg))))
        if isinstance(f, A.Not):
            if not isinstance(f.child, A.Atom):
                raise CompileError(f"negation of {f.child} left after normal form")
            pos, neg = self.where[f.child.name]
            return R.Sum((_tokens(neg), R.Neg(_tokens(pos))))
        if isinstance(f, A.Weighted):
            inner = self.reward(f.child, ctx, under_g, conj)
            if isinstance(inner, R.Gated):
                return R.Gated(inner.gate, R.scale(f.weight, inner.expr))
            return R.scale(f.weight, inner)
        if isinstance(f, A.And):
            return self._and(f, ctx, under_g, conj)
        if isinstance(f, A.Or):
            return R.Max(tuple(self.reward(c, ctx, under_g) for c in _flatten(f, A.Or)))
        if isinstance(f, A.Globally):
            return self._globally(f, ctx, under_g, conj)
        if isinstance(f, A.Eventually):
            return self._eventually(f, ctx, under_g, conj)
        if isinstance(f, A.Until):
            return self._until(f, ctx, under_g, conj)
        raise CompileError(f"cannot compile {type(f).__name__}")

    def _bonus(self, f: A.Formula, ctx: frozenset[int], under_g: bool) -> R.RExpr:
        """The reward of ``G f`` without its window: ``(1 + ~h_f) r_f`` for state formulas."""
        if is_state_formula(f):
            return R.Prod((R.Sum((R.ONE, self._h(f, prev=True))), self.reward(f, ctx, True)))
        return self.reward(f, ctx, True)

    def _gate(self, phase: frozenset[int], ctx: frozenset[int], expr: R.RExpr, prev: bool = False) -> R.RExpr:
        p = phase & ctx
        if p == ctx:
            return expr
        if not p:
            return R.ZERO
        return R.Gated(self._seg_tokens(p, prev), expr)

    def _globally(self, f: A.Globally, ctx: frozenset[int], under_g: bool, conj: bool) -> R.RExpr:
        rec = _recurrence(f)
        if rec is not None:  # a lone G F phi: its one-place cycle is trivial and dropped
            w, phi = rec
            return R.scale(w, self._bonus(phi, ctx, True))
        phase = self._phase(f.interval) if self.segments else ctx
        inner_ctx = (phase & ctx) or ctx
        if conj and is_state_formula(f.child) and (phase & ctx or not self.segments):
            self._watch(f"G_{self._label(f.child, '')}", _negate_state(_strip(f.child)), inner_ctx, str(f),
                        counted=True)
        return self._gate(phase, ctx, self._bonus(f.child, inner_ctx, True))

    def _eventually(self, f: A.Eventually, ctx: frozenset[int], under_g: bool, conj: bool) -> R.RExpr:
        timed = not f.interval.is_unbounded
        factors: list[R.RExpr] = []
        if timed:
            window = self._phase(f.interval)
            if not window & ctx:
                return R.ZERO
            factors.append(self._seg_tokens(window, prev=True))
        inner = self.reward(f.child, ctx, under_g)
        if conj and not timed and isinstance(f.child, A.Globally) and f.child.interval.is_unbounded \
                and is_state_formula(f.child.child) and self.end is not None:
            # F G phi on a finite trial: phi must hold at the last sample
            end = A.Interval(self.end, math.inf)
            self._watch(f"FG_{self._label(f.child.child, '')}", _negate_state(_strip(f.child.child)), None,
                        str(f), clock=end)
        if is_state_formula(f.child) and not under_g:
            key = ("eventually", _strip(f.child), f.interval)
            if key not in self.cache:
                label = self._label(f.child, "F")
                pending = self._unique(f"p_tau_{label}")
                done = self._unique(f"p_done_{label}")
                guard = Guard((GuardTerm(_strip(f.child), f.interval if timed else None),))
                self.timing.append(
                    _Sub(f"eventually {label}", "timing", "eventually",
                         [(pending, f"tau,{label}"), (done, f"done,{label}")], [(0, 1, guard)], 0, str(f))
                )
                self.cache[key] = [pending, done]
            if conj:
                self._late(key, f)
            factors.insert(0, _tokens([self.cache[key][0]], prev=True))
        if not factors:
            return inner  # the thesis's trivial one-place net, dropped
        gate = factors[0] if len(factors) == 1 else R.Prod(tuple(factors))
        return R.Gated(gate, inner)

    def _until(self, f: A.Until, ctx: frozenset[int], under_g: bool, conj: bool) -> R.RExpr:
        lo = _lower(f.interval)
        if lo is not None:  # time-triggered switch on the timeline (the thesis's C-5)
            k = self.thresholds.index(lo) + 1
            before = frozenset(range(k)) & ctx
            after = frozenset(range(k, len(self.segments))) & ctx
            if conj and before and is_state_formula(f.left):
                self._watch(f"U_{self._label(f.left, '')}", _negate_state(_strip(f.left)), before, str(f),
                            counted=True)
            terms: list[R.RExpr] = []
            for phase, side in ((before, f.left), (after, f.right)):
                if not phase:
                    continue
                sub = self.reward(side, phase, under_g, conj and side is f.right)
                if phase == ctx:
                    terms.append(sub)
                elif self._gated_within(sub, phase):
                    terms.extend(sub.terms if isinstance(sub, R.Sum) else (sub,))
                else:
                    terms.append(R.Gated(self._seg_tokens(phase), sub))
            return terms[0] if len(terms) == 1 else R.Sum(tuple(terms))
        watch = conj and self.options.violations != "off"
        left_cond = _strip(f.left) if watch and is_state_formula(f.left) else None
        # the net depends on nothing else (the left side only where its failure is watched)
        key = ("until", trigger(f.right), f.interval, left_cond, watch)
        if key not in self.cache:
            label = self._label(f, "U")
            switch = [GuardTerm(key[1])] if key[1] != A.Const(True) else [GuardTerm()]
            deadline = None
            if not math.isinf(f.interval.hi):
                deadline = GuardTerm(clock=A.Interval(f.interval.hi, math.inf, lo_closed=not f.interval.hi_closed))
            names = [self._unique(f"p_until_{label}"), self._unique(f"p_after_{label}")]
            places = [(names[0], f"{label},1"), (names[1], f"{label},2")]
            arcs: list[tuple[int, int | tuple[int, ...], Guard]] = []
            if not watch:
                arcs.append((0, 1, Guard(tuple(switch + ([deadline] if deadline and switch[0].state else [])))))
            else:
                if deadline is not None:  # met only within the interval (a late trigger fails)
                    switch = [GuardTerm(switch[0].state, A.Interval(0.0, f.interval.hi, hi_closed=f.interval.hi_closed))]
                arcs.append((0, 1, Guard(tuple(switch))))
                fail: list[GuardTerm] = []
                if left_cond is not None and key[1] != A.Const(True):
                    fail.append(GuardTerm(_conj(_negate_state(left_cond), _negate_state(key[1]))))
                if deadline is not None:
                    fail.append(deadline)
                if fail:
                    failed = self._unique(f"p_failed_{label}")
                    places.append((failed, f"{label},failed"))
                    arcs.append((0, 2, Guard(tuple(fail))))
                    self.penalties.append(failed)
            self.timing.append(_Sub(f"until {label}", "timing", "until", places, arcs, 0, str(f)))
            self.cache[key] = names
        left_place, right_place = self.cache[key][:2]
        return R.Sum(
            (
                R.Gated(_tokens([left_place]), self.reward(f.left, ctx, under_g)),
                R.Gated(_tokens([right_place]), self.reward(f.right, ctx, under_g)),
            )
        )

    def _gated_within(self, e: R.RExpr, phase: frozenset[int]) -> bool:
        names = {self.segments[i] for i in phase}
        terms = e.terms if isinstance(e, R.Sum) else (e,)
        return all(
            isinstance(t, R.Gated) and isinstance(t.gate, R.Tokens) and not t.gate.prev and set(t.gate.names) <= names
            for t in terms
        )

    def _and(self, f: A.And, ctx: frozenset[int], under_g: bool, conj: bool) -> R.RExpr:
        parts = _flatten(f, A.And)
        recurrences = [(i, _recurrence(p)) for i, p in enumerate(parts)]
        cyc = [(i, r) for i, r in recurrences if r is not None]
        terms: dict[int, R.RExpr] = {}
        if len(cyc) >= 2:
            key = ("recurrence",) + tuple(_strip(phi) for _, (_, phi) in cyc)
            if key not in self.cache:
                labels = [self._label(phi, "GF") for _, (_, phi) in cyc]
                names = [self._unique(f"p_tau_{lab}") for lab in labels]
                n = len(names)
                arcs = [(j, (j + 1) % n, Guard.state(_strip(phi))) for j, (_, (_, phi)) in enumerate(cyc)]
                self.timing.append(
                    _Sub("recurrence", "timing", "recurrence", [(nm, f"tau,{lab}") for nm, lab in zip(names, labels)],
                         arcs, 0, " & ".join(str(parts[i]) for i, _ in cyc))
                )
                self.cache[key] = names
            names = self.cache[key]
            for (i, (w, phi)), name in zip(cyc, names):
                terms[i] = R.Gated(_tokens([name], prev=True), R.scale(w, self._bonus(phi, ctx, True)))
        for i, p in enumerate(parts):
            if i not in terms:
                terms[i] = self.reward(p, ctx, under_g, conj)
        return R.Min(tuple(terms[i] for i in range(len(parts))), active=self.options.conjunction == "active")

    # -- violations (docs/semantics.md, section 6)
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

    def _watch(self, label: str, bad: A.Formula, segs: frozenset[int] | None, text: str,
               counted: bool = False, clock: A.Interval | None = None) -> None:
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
            back = Guard((GuardTerm(_negate_state(bad)),)
                         + tuple(GuardTerm(clock=c) for c in (_complement_clock(clock) if clock else [])))
            sub = _Sub(f"violations {label}", "violation", "violation",
                       [(ok, f"ok,{label}"), (bad_place, f"bad,{label}"), (count, f"count,{label}")],
                       [(0, (1, 2), guard), (1, 0, back)], 0, text, counters=(2,))
            self.penalties.append(count)
        else:
            viol = self._unique(f"p_violated_{label}")
            sub = _Sub(f"violations {label}", "violation", "violation",
                       [(ok, f"ok,{label}"), (viol, f"violated,{label}")], [(0, 1, guard)], 0, text)
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

    # -- assembly
    def assemble(self, reward: R.RExpr) -> tuple[Net, R.RExpr]:
        subs = self.timing + self.state + self.violation_nets
        places: list[Place] = []
        transitions: list[tuple[str, Guard, str, tuple[str, ...], int]] = []
        m0: list[int] = []
        subnets: list[SubNet] = []
        for s_idx, sub in enumerate(subs):
            base = len(places)
            for k, (name, label) in enumerate(sub.places):
                places.append(Place(name, "counter" if k in sub.counters else sub.kind, s_idx, label))
                m0.append(1 if k == sub.initial else 0)
            t_base = len(transitions)
            for src, dst, guard in sub.arcs:
                outs = tuple(sub.places[d][0] for d in (dst if isinstance(dst, tuple) else (dst,)))
                transitions.append((f"t{len(transitions) + 1}", guard, sub.places[src][0], outs, s_idx))
            own = [base + k for k in range(len(sub.places))]
            subnets.append(
                SubNet(sub.name, sub.kind, sub.role, tuple(i for k, i in enumerate(own) if k not in sub.counters),
                       tuple(range(t_base, len(transitions))), sub.formula,
                       tuple(i for k, i in enumerate(own) if k in sub.counters))
            )
        index = {p.name: i for i, p in enumerate(places)}
        d_minus = np.zeros((len(transitions), len(places)), dtype=np.int64)
        d_plus = np.zeros_like(d_minus)
        trans = []
        for t, (name, guard, src, outs, s_idx) in enumerate(transitions):
            d_minus[t, index[src]] = 1
            for dst in outs:
                d_plus[t, index[dst]] = 1
            trans.append(Transition(name, guard, (src,), outs, s_idx))
        net = Net(tuple(places), tuple(trans), tuple(subnets), d_minus, d_plus, np.array(m0, dtype=np.int64))
        return net, _resolve(reward, index)


def _resolve(e: R.RExpr, index: dict[str, int]) -> R.RExpr:
    if isinstance(e, R.Tokens):
        return R.Tokens(tuple(index[n] for n in e.names), e.names, e.prev)
    if not e.children:
        return e
    if isinstance(e, R.Gated):
        return R.Gated(_resolve(e.gate, index), _resolve(e.expr, index))
    if isinstance(e, R.Neg):
        return R.Neg(_resolve(e.arg, index))
    field_name = {R.Sum: "terms", R.Prod: "factors", R.Min: "terms", R.Max: "terms"}[type(e)]
    return dataclasses.replace(e, **{field_name: tuple(_resolve(c, index) for c in e.children)})


def compile_spec(spec: Spec, options: CompileOptions | None = None) -> RewardSystem:
    """Compile a checked spec into its reward system."""
    if spec.formula is None:
        raise CompileError(
            "the spec has no 'formula' to compile (its 'require' criteria compile to a hybrid automaton)",
            file=spec.path,
        )
    options = options or CompileOptions.from_spec(spec)
    if options.conjunction not in ("literal", "active"):
        raise CompileError(f"unknown conjunction reading '{options.conjunction}' (literal or active)")
    if options.violations not in ("off", "permanent", "counted"):
        raise CompileError(f"unknown violations mode '{options.violations}' (off, permanent or counted)")
    if options.violations != "off" and _last_sample(spec) is None:
        raise CompileError(
            f"--violations {options.violations} needs the trial length: give the spec a 'horizon' and a 'plant'",
            file=spec.path,
        )
    nf = normal_form(spec.formula)
    formula = reward_reading(nf)
    builder = _Builder(spec, options, formula)
    everything = builder._all() if builder.segments else frozenset()
    reward = builder.reward(formula, everything, under_g=False, conj=True)
    penalty = 0.0
    net, resolved = builder.assemble(reward)
    if builder.penalties:
        # c: more than any step can earn above a violation-free step
        lo_free, _ = _bounds_without_violation(builder, net, resolved)
        _, hi = _bounds_all_steps(net, resolved)
        penalty = hi - lo_free + 1.0
        if options.violations == "permanent":
            # r' = r - c v, v = 1 once any watched part is violated (on every later step)
            marks = [_tokens([p]) for p in builder.penalties]
            charge = marks[0] if len(marks) == 1 else R.Max(tuple(marks))
        else:
            # r' = r - c * (new violations)
            new = [R.Sum((_tokens([p]), R.Neg(_tokens([p], prev=True)))) for p in builder.penalties]
            charge = new[0] if len(new) == 1 else R.Sum(tuple(new))
        reward = R.Sum((reward, R.Neg(R.scale(penalty, charge))))
        index = {p.name: i for i, p in enumerate(net.places)}
        resolved = _resolve(reward, index)
        charge = _resolve(charge, index)
    else:
        charge = None
    return RewardSystem(spec, nf, net, resolved, builder.groups, options, penalty, charge)


MAX_PAIRS = 200_000
"""Most marking pairs enumerated to bound the reward of steps without a violation."""


def _pairs(net: Net) -> tuple[np.ndarray, np.ndarray] | None:
    """Every one-move step of the net as (M_k, M_k+1) arrays, or None if there are too many."""
    sizes = [len(sub.places) ** 2 for sub in net.subnets]
    if float(np.prod(sizes, dtype=float)) > MAX_PAIRS:
        return None
    pairs = list(net.step_pairs())
    return np.array([a for a, _ in pairs]), np.array([b for _, b in pairs])


def _bounds_all_steps(net: Net, reward: R.RExpr) -> tuple[float, float]:
    """Bounds of ``reward`` over every one-move step (interval bounds if there are too many)."""
    pairs = _pairs(net)
    if pairs is None:
        return R.bounds(reward)
    values = reward.evaluate(*pairs)
    return float(values.min()), float(values.max())


def _contains(outer: A.Interval, inner: A.Interval) -> bool:
    lo_ok = outer.lo < inner.lo or (outer.lo == inner.lo and (outer.lo_closed or not inner.lo_closed))
    hi_ok = outer.hi > inner.hi or (outer.hi == inner.hi and (outer.hi_closed or not inner.hi_closed))
    return lo_ok and hi_ok


def _bounds_without_violation(builder: "_Builder", net: Net, reward: R.RExpr) -> tuple[float, float]:
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
                sure = eval_state(term.state, truth) if term.state is not None else np.ones(n, bool)
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
    values = reward.evaluate(prev[keep], now[keep])
    return float(values.min()), float(values.max())


def _steps(spec: Spec) -> int:
    """Number of steps in a trial, ``round(horizon / dt)``."""
    return int(round(spec.horizon / spec.param("dt")))  # type: ignore[operator]


def _last_sample(spec: Spec) -> float | None:
    """A clock threshold that only the last sample of a trial passes (half a step before it)."""
    if spec.horizon is None or spec.plant is None:
        return None
    dt = spec.param("dt")
    return (_steps(spec) - 0.5) * dt
