"""Compile a spec into a reward system: one composed Petri net and a reward expression.

Steps (docs/semantics.md explains each):

1. :func:`~mitlc.spec.passes.normal_form`: derived operators to primitives, negation to atoms.
2. :func:`~mitlc.petri.reading.reward_reading`: release ``a R_I b`` becomes
   ``(b U_I (a & b)) | G_I b``.
3. State-related sub-nets (:mod:`mitlc.petri.regions`): the propositions are grouped
   so that every group's regions are provably disjoint (interval analysis); each
   group is one region net with a place per proposition plus "none" (for a group of
   one: ``p_a``, ``p_not_a``) and a transition between every two places.
4. Timing-related sub-nets: one *timeline* over the trial clock for all interval
   ends (:mod:`mitlc.petri.timeline`), and here, per operator, a pending/done net for
   ``F`` of a state formula, a two-phase net for untimed ``U``, and one shared cycle
   for a conjunction of ``G F``; violation sub-nets (:mod:`mitlc.petri.violations`).
5. The reward of Table 4-2, composed over the formula (:class:`_Builder`, one method
   per operator), and the sub-nets assembled into one :class:`~mitlc.petri.net.Net`.

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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mitlc.errors import CompileError
from mitlc.petri import reward as R
from mitlc.petri.net import Guard, GuardTerm, Incidence, Net, Place, SubNet, Transition
from mitlc.petri.options import CompileOptions  # re-exported: mitlc.petri.compile.CompileOptions is documented
from mitlc.petri.parts import Arc, Part, tokens
from mitlc.petri.reading import (
    conjoin,
    flatten,
    negate_state,
    peel_weights,
    recurrence,
    reward_reading,
    strip_weights,
    trigger,
)
from mitlc.petri.regions import region_net, state_groups
from mitlc.petri.timed import (
    NODE_PLACES,
    ROOT_PLACES,
    ObligationTree,
    TimedNet,
    earliest_witness,
    needs_obligations,
)
from mitlc.petri.timeline import formula_thresholds, lower, timeline_net, upper
from mitlc.petri.violations import (
    ViolationWatches,
    bounds_all_steps,
    bounds_without_violation,
)
from mitlc.spec import ast as A
from mitlc.spec.grades import Grader
from mitlc.spec.model import MONITOR_REWARDS, OPTIONS, Spec
from mitlc.spec.passes import desugar, is_state_formula, normal_form

__all__ = ["CompileOptions", "RewardSystem", "compile_spec", "reward_reading", "state_groups"]


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
    timed: tuple[TimedNet, ...] = ()
    """The timed obligation trees (``clock = standard`` with nested intervals) and their sub-nets."""
    warnings: tuple[str, ...] = ()
    """What the compiler noticed (a part that no trial of the horizon can satisfy)."""
    grader: Grader | None = None
    """``reward = shaped``: the propositions' grades (:mod:`mitlc.spec.grades`), in :attr:`atoms`
    order, which the reward reads at the new state; None when the reward reads markings only."""

    @property
    def atoms(self) -> tuple[str, ...]:
        return tuple(a for g in self.groups for a in g)

    @property
    def paid_by_monitor(self) -> bool:
        """Whether the learner is paid by the monitor (``sparse``, ``robustness``, ``robustness-window``)
        instead of :attr:`reward`."""
        return self.options.reward in MONITOR_REWARDS


# ------------------------------------------------------------------ builder


class _Builder(ViolationWatches):
    """Builds the sub-nets of a formula and its reward, one method per operator (Table 4-2)."""

    def __init__(
        self, spec: Spec, options: CompileOptions, formula: A.Formula, roots: Sequence[A.Formula] = ()
    ) -> None:
        self.spec = spec
        self.roots = {id(r) for r in roots}  # obligation trees: compiled by _obligation
        self.obligations: list[tuple[ObligationTree, list[tuple[int, Part]]]] = []
        self.options = options
        self.timing: list[Part] = []
        self.violation_nets: list[Part] = []
        self.penalties: list[str] = []  # places whose new tokens are penalised
        self.end = _last_sample(spec)
        self.cache: dict[object, list[str]] = {}  # one timing sub-net per distinct subformula
        self.used_names: set[str] = set()
        self.next_suffix: dict[str, int] = {}  # base name -> the suffix _unique tries first
        self.counter = 0
        names = A.atoms(formula)
        for n in names:
            spec.prop(n)  # undefined propositions were caught by the parser
        self.groups = state_groups(spec, names)
        self.state: list[Part] = [region_net(spec, g, self._unique) for g in self.groups]
        # atom -> (places where it holds, places where it does not)
        self.where: dict[str, tuple[list[str], list[str]]] = {}
        for g, sub in zip(self.groups, self.state, strict=True):
            all_names = [n for n, _ in sub.places]
            for a in g:
                pos = [f"p_{a}"]
                self.where[a] = (pos, [n for n in all_names if n not in pos])
        self.thresholds = formula_thresholds(_masked(formula, self.roots))
        # threshold -> its place in clock order (the thresholds are distinct)
        self.threshold_index = {t: i for i, t in enumerate(self.thresholds)}
        self.segments: list[str] = []
        if self.thresholds:
            line = timeline_net(self.thresholds, self._unique)
            self.segments = [n for n, _ in line.places]
            self.timing.append(line)

    # -- naming
    def _unique(self, name: str) -> str:
        """``name``, else ``name_2``, ``name_3``, ...: the first unused. Names are never freed, so
        the search for a base resumes where its last one ended (linear, not quadratic, in the
        number of places sharing a base: a thousand eventuallys of one proposition)."""
        base, k = name, self.next_suffix.get(name, 1)
        if k > 1:
            name = f"{base}_{k}"
        while name in self.used_names:
            k += 1
            name = f"{base}_{k}"
        self.used_names.add(name)
        self.next_suffix[base] = k
        return name

    def _label(self, f: A.Formula, prefix: str) -> str:
        _, core = peel_weights(f)
        if isinstance(core, A.Atom):
            return core.name
        if isinstance(core, A.Not) and isinstance(core.child, A.Atom):
            return f"not_{core.child.name}"
        self.counter += 1
        return f"{prefix}{self.counter}"

    def _phase(self, interval: A.Interval) -> frozenset[int]:
        n = len(self.segments)
        lo, hi = lower(interval), upper(interval)
        start = 0 if lo is None else self.threshold_index[lo] + 1
        stop = n if hi is None else self.threshold_index[hi] + 1
        return frozenset(range(start, stop))

    def _all(self) -> frozenset[int]:
        return frozenset(range(len(self.segments)))

    def _seg_tokens(self, segs: frozenset[int], prev: bool = False) -> R.Tokens:
        return tokens([self.segments[i] for i in sorted(segs)], prev)

    # -- indicators and rewards of state formulas
    def _h(self, f: A.Formula, prev: bool = True) -> R.RExpr:
        """0/1 indicator that state formula ``f`` holds, read off the marking."""
        _, f = peel_weights(f)
        if isinstance(f, A.Const):
            return R.ONE if f.value else R.ZERO
        if isinstance(f, A.Atom):
            return tokens(self.where[f.name][0], prev)
        if isinstance(f, A.Not) and isinstance(f.child, A.Atom):
            return tokens(self.where[f.child.name][1], prev)
        if isinstance(f, A.And):
            return R.Min(tuple(self._h(c, prev) for c in flatten(f, A.And)))
        if isinstance(f, A.Or):
            return R.Max(tuple(self._h(c, prev) for c in flatten(f, A.Or)))
        raise CompileError(f"not a state formula: {f}")

    # -- rewards
    def reward(self, f: A.Formula, ctx: frozenset[int], under_g: bool, conj: bool = False) -> R.RExpr:
        """The reward of ``f`` active on timeline segments ``ctx``.

        ``under_g``: ``f`` sits under an always (its eventually nets get no done place).
        ``conj``: ``f`` must hold for the whole formula to hold (it is reached from
        the root through ``&``, weights and timeline phases only), so its
        violations may be tracked.
        """
        if id(f) in self.roots:
            return self._obligation(f, ctx, conj)
        if isinstance(f, A.Const):
            return R.Const(1.0 if f.value else -1.0)
        if isinstance(f, A.Atom):
            pos, neg = self.where[f.name]
            return self._graded(f.name, R.Sum((tokens(pos), R.Neg(tokens(neg)))), False)
        if isinstance(f, A.Not):
            if not isinstance(f.child, A.Atom):
                raise CompileError(f"negation of {f.child} left after normal form")
            pos, neg = self.where[f.child.name]
            return self._graded(f.child.name, R.Sum((tokens(neg), R.Neg(tokens(pos)))), True)
        if isinstance(f, A.Weighted):
            return _weighted(f.weight, self.reward(f.child, ctx, under_g, conj))
        if isinstance(f, A.And):
            return self._and(f, ctx, under_g, conj)
        if isinstance(f, A.Or):
            return R.Max(tuple(self.reward(c, ctx, under_g) for c in flatten(f, A.Or)))
        if isinstance(f, A.Globally):
            return self._globally(f, ctx, under_g, conj)
        if isinstance(f, A.Eventually):
            return self._eventually(f, ctx, under_g, conj)
        if isinstance(f, A.Until):
            return self._until(f, ctx, under_g, conj)
        raise CompileError(f"cannot compile {type(f).__name__}")

    def _graded(self, atom: str, flat: R.RExpr, negated: bool) -> R.RExpr:
        """A proposition's reward: ``flat`` (+1 / -1), or its grade (``graded``), or their mean (``shaped``)."""
        if self.options.reward not in ("shaped", "graded"):
            return flat
        atoms = [a for g in self.groups for a in g]
        return R.Graded(atom, atoms.index(atom), flat, negated, 0.5 if self.options.reward == "shaped" else 0.0)

    def _bonus(self, f: A.Formula, ctx: frozenset[int]) -> R.RExpr:
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
        rec = recurrence(f)
        if rec is not None:  # a lone G F phi: its one-place cycle is trivial and dropped
            w, phi = rec
            return R.scale(w, self._bonus(phi, ctx))
        phase = self._phase(f.interval) if self.segments else ctx
        inner_ctx = (phase & ctx) or ctx
        if conj and is_state_formula(f.child) and (phase & ctx or not self.segments):
            self._watch(
                f"G_{self._label(f.child, '')}", negate_state(strip_weights(f.child)), inner_ctx, str(f), counted=True
            )
        return self._gate(phase, ctx, self._bonus(f.child, inner_ctx))

    def _eventually(self, f: A.Eventually, ctx: frozenset[int], under_g: bool, conj: bool) -> R.RExpr:
        timed = not f.interval.is_unbounded
        factors: list[R.RExpr] = []
        if timed:
            window = self._phase(f.interval)
            if not window & ctx:
                return R.ZERO
            factors.append(self._seg_tokens(window, prev=True))
        inner = self.reward(f.child, ctx, under_g)
        if (
            conj
            and not timed
            and isinstance(f.child, A.Globally)
            and f.child.interval.is_unbounded
            and is_state_formula(f.child.child)
            and self.end is not None
        ):
            # F G phi on a finite trial: phi must hold at the last sample
            end = A.Interval(self.end, math.inf)
            self._watch(
                f"FG_{self._label(f.child.child, '')}",
                negate_state(strip_weights(f.child.child)),
                None,
                str(f),
                clock=end,
            )
        if is_state_formula(f.child) and not under_g:
            key = ("eventually", strip_weights(f.child), f.interval)
            if key not in self.cache:
                label = self._label(f.child, "F")
                pending = self._unique(f"p_tau_{label}")
                done = self._unique(f"p_done_{label}")
                guard = Guard((GuardTerm(strip_weights(f.child), f.interval if timed else None),))
                self.timing.append(
                    Part(
                        f"eventually {label}",
                        "timing",
                        "eventually",
                        [(pending, f"tau,{label}"), (done, f"done,{label}")],
                        [(0, 1, guard)],
                        0,
                        str(f),
                    )
                )
                self.cache[key] = [pending, done]
            if conj:
                self._late(key, f)
            factors.insert(0, tokens([self.cache[key][0]], prev=True))
        if not factors:
            return inner  # the thesis's trivial one-place net, dropped
        gate = factors[0] if len(factors) == 1 else R.Prod(tuple(factors))
        return R.Gated(gate, inner)

    def _until(self, f: A.Until, ctx: frozenset[int], under_g: bool, conj: bool) -> R.RExpr:
        lo = lower(f.interval)
        if lo is not None:  # time-triggered switch on the timeline (the thesis's C-5)
            k = self.threshold_index[lo] + 1
            before = frozenset(range(k)) & ctx
            after = frozenset(range(k, len(self.segments))) & ctx
            if conj and before and is_state_formula(f.left):
                self._watch(
                    f"U_{self._label(f.left, '')}", negate_state(strip_weights(f.left)), before, str(f), counted=True
                )
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
        left_cond = strip_weights(f.left) if watch and is_state_formula(f.left) else None
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
                    switch = [
                        GuardTerm(switch[0].state, A.Interval(0.0, f.interval.hi, hi_closed=f.interval.hi_closed))
                    ]
                arcs.append((0, 1, Guard(tuple(switch))))
                fail: list[GuardTerm] = []
                if left_cond is not None and key[1] != A.Const(True):
                    fail.append(GuardTerm(conjoin(negate_state(left_cond), negate_state(key[1]))))
                if deadline is not None:
                    fail.append(deadline)
                if fail:
                    failed = self._unique(f"p_failed_{label}")
                    places.append((failed, f"{label},failed"))
                    arcs.append((0, 2, Guard(tuple(fail))))
                    self.penalties.append(failed)
            self.timing.append(Part(f"until {label}", "timing", "until", places, arcs, 0, str(f)))
            self.cache[key] = names
        left_place, right_place = self.cache[key][:2]
        return R.Sum(
            (
                R.Gated(tokens([left_place]), self.reward(f.left, ctx, under_g)),
                R.Gated(tokens([right_place]), self.reward(f.right, ctx, under_g)),
            )
        )

    def _obligation(self, f: A.Formula, ctx: frozenset[int], conj: bool) -> R.RExpr:
        """A temporal part with nested intervals: one timed sub-net per temporal node (standard MITL)."""
        tree, index = ObligationTree.build_indexed(f)
        names: dict[int, dict[str, str]] = {}
        parts: list[tuple[int, Part]] = []
        for i in tree.temporal:
            node = tree.nodes[i]
            root = i == tree.root
            self.counter += 1
            label = f"{node.op}{self.counter}"
            roles = ROOT_PLACES if root else NODE_PLACES
            names[i] = {role: self._unique(f"p_{role}_{label}") for role in roles}
            places = [(names[i][role], f"{label},{role}") for role in roles]
            age = node.interval

            def ev(text: str, in_window: bool = False, age: A.Interval = age) -> Guard:
                return Guard((GuardTerm(age=age if in_window else None, event=text),))

            if root:
                arcs: list[Arc] = [
                    (0, 1, ev("next sample outside its interval")),
                    (1, 0, ev("next sample in its interval", True)),
                    (0, 2, ev("met")),
                    (0, 3, ev("failed")),
                    (1, 2, ev("met")),
                    (1, 3, ev("failed")),
                ]
            else:
                arcs = [
                    (0, 1, ev("an obligation starts, next sample in its interval", True)),
                    (0, 2, ev("an obligation starts before its interval")),
                    (1, 2, ev("no obligation's next sample in its interval")),
                    (2, 1, ev("an obligation's next sample in its interval", True)),
                    (1, 0, ev("every obligation decided")),
                    (2, 0, ev("every obligation decided")),
                ]
            part = Part(f"obligation {label}", "timing", "obligation", places, arcs, 0, str(node.formula))
            self.timing.append(part)
            parts.append((i, part))
        self.obligations.append((tree, parts))
        if conj and self.options.violations != "off":
            self.penalties.append(names[tree.root]["failed"])
        active = self.options.conjunction == "active"

        def gate(i: int, role: str, expr: R.RExpr) -> R.RExpr:
            return R.Gated(tokens([names[i][role]], prev=True), expr)

        def rew(g: A.Formula) -> R.RExpr:
            w, core = peel_weights(g)
            if w != 1.0:
                return _weighted(w, rew(core))
            i = index[id(core)]
            node = tree.nodes[i]
            if node.op == "state":
                return self.reward(core, ctx, True)
            if node.op in ("and", "or"):
                terms = (rew(core.left), rew(core.right))  # type: ignore[attr-defined]
                if node.op == "and":
                    return started(i, core, terms) or R.Min(terms, active=active)
                return R.Max(terms)
            if isinstance(core, A.Eventually):
                if is_state_formula(core.child):
                    return gate(i, "open", self.reward(core.child, ctx, True))
                return pulled(i, core.child)
            if isinstance(core, A.Globally):
                if is_state_formula(core.child):
                    return gate(i, "open", self._bonus(core.child, ctx))
                return rew(core.child)
            if isinstance(core, A.Until):
                return R.Sum((gate(i, "wait", rew(core.left)), gate(i, "open", rew(core.right))))
            if isinstance(core, A.Release):
                if is_state_formula(core.right):
                    return gate(i, "open", self._bonus(core.right, ctx))
                return rew(core.right)
            raise CompileError(f"cannot compile {type(core).__name__} in a timed obligation")

        def started(i: int, core: A.Formula, terms: tuple[R.RExpr, R.RExpr]) -> R.RExpr | None:
            """``s & T`` with ``s`` a state formula and ``T`` temporal: ``s`` is needed at the sample an
            instance starts only, and ``T`` has a live instance only where one started with ``s``
            true (a false conjunct decides the ``&`` at once). So while ``T``'s sub-net holds a live
            instance the reward is ``T``'s alone, and ``s`` pays only while none does: a learner that
            reached ``s`` is not paid to stay there when ``T`` asks it to leave (``F[0,2] (mark &
            F[0,2] G home)``). None for other conjunctions."""
            kids = [index[id(peel_weights(c)[1])] for c in (core.left, core.right)]  # type: ignore[attr-defined]
            ops = [tree.nodes[k].op for k in kids]
            if sorted(op == "state" for op in ops) != [False, True]:
                return None
            t = kids[ops.index("state") ^ 1]
            if t not in names or tree.nodes[t].op in ("and", "or"):
                return None
            live = tokens([names[t]["open"], names[t]["wait"]], prev=True)
            idle = tokens([names[t]["idle"]], prev=True)
            r_t = terms[ops.index("state") ^ 1]
            return R.Sum((R.Gated(idle, R.Min(terms, active=active)), R.Gated(live, r_t)))

        def head(g: A.Formula) -> R.RExpr | None:
            """The reward of what ``g`` needs at the sample it starts, where that is a state formula:
            ``g`` itself, the child of ``G`` (interval from 0), the right side of ``U``, ``R``;
            the min (``&``) or max (``|``) of the sides'; None where ``g`` needs nothing yet."""
            w, core = peel_weights(g)
            if is_state_formula(core):
                return R.scale(w, self.reward(core, ctx, True))
            if isinstance(core, (A.And, A.Or)):
                sides = [head(core.left), head(core.right)]
                if isinstance(core, A.Or) and None in sides:
                    return None
                h = _sides(core, sides)
                return None if h is None else R.scale(w, h)
            interval = getattr(core, "interval", None)
            if interval is None or interval.lo > 0 or not interval.lo_closed:
                return None
            if isinstance(core, A.Eventually):
                return None  # it needs nothing at its first sample: a later one in its window will do
            if isinstance(core, A.Globally):
                child = head(core.child)
            elif isinstance(core, (A.Until, A.Release)):
                child = head(core.right)
            else:
                return None
            return None if child is None else R.scale(w, child)

        def pulled(i: int, child: A.Formula) -> R.RExpr:
            """The reward of ``F_I child`` for a temporal ``child``: the child's own while one of
            its instances is live, and while none is (``F[0,2] G goal`` away from the goal: every
            instance started is false at once) and the window is open, the reward of what a new
            instance would need now (:func:`head`), so that the learner is pulled towards it."""
            own = rew(child)
            need = head(child)
            c = index[id(peel_weights(child)[1])]
            if need is None or c not in names:
                return own
            waiting = R.Gated(
                R.Prod((tokens([names[i]["open"]], prev=True), tokens([names[c]["idle"]], prev=True))), need
            )
            return R.Sum((own, waiting))

        def chase(g: A.Formula) -> R.RExpr | None:
            """The reward of the state formula ``g`` ultimately needs, intervals ignored: the
            child of ``F``, ``G``, the right side of ``U``, ``R``; the min (``&``) or max (``|``)."""
            w, core = peel_weights(g)
            if is_state_formula(core):
                return R.scale(w, self.reward(core, ctx, True))
            if isinstance(core, (A.And, A.Or)):
                h = _sides(core, [chase(core.left), chase(core.right)])
                return None if h is None else R.scale(w, h)
            if isinstance(core, (A.Globally, A.Eventually)):
                child = chase(core.child)
            elif isinstance(core, (A.Until, A.Release)):
                child = chase(core.right)
            else:
                return None
            return None if child is None else R.scale(w, child)

        body = rew(f)
        need = chase(f)
        if tree.root not in names or need is None:
            return body
        # Once the obligation has failed nothing it pays is live any more; a failed run that paid 0
        # from then on would beat one still trying (-1 per step away from the goal), and learners
        # learn to give up. It pays what the formula still needs, less one, so failing never pays
        # and the goal still pulls.
        failed = R.Gated(tokens([names[tree.root]["failed"]], prev=True), R.Sum((need, R.Const(-1.0))))
        return R.Sum((body, failed))

    def _gated_within(self, e: R.RExpr, phase: frozenset[int]) -> bool:
        names = {self.segments[i] for i in phase}
        terms = e.terms if isinstance(e, R.Sum) else (e,)
        return all(
            isinstance(t, R.Gated) and isinstance(t.gate, R.Tokens) and not t.gate.prev and set(t.gate.names) <= names
            for t in terms
        )

    def _and(self, f: A.And, ctx: frozenset[int], under_g: bool, conj: bool) -> R.RExpr:
        parts = flatten(f, A.And)
        recurrences = [(i, recurrence(p)) for i, p in enumerate(parts)]
        cyc = [(i, r) for i, r in recurrences if r is not None]
        terms: dict[int, R.RExpr] = {}
        if len(cyc) >= 2:
            key = ("recurrence",) + tuple(strip_weights(phi) for _, (_, phi) in cyc)
            if key not in self.cache:
                labels = [self._label(phi, "GF") for _, (_, phi) in cyc]
                names = [self._unique(f"p_tau_{lab}") for lab in labels]
                n = len(names)
                arcs: list[Arc] = [
                    (j, (j + 1) % n, Guard.state(strip_weights(phi))) for j, (_, (_, phi)) in enumerate(cyc)
                ]
                self.timing.append(
                    Part(
                        "recurrence",
                        "timing",
                        "recurrence",
                        [(nm, f"tau,{lab}") for nm, lab in zip(names, labels, strict=True)],
                        arcs,
                        0,
                        " & ".join(str(parts[i]) for i, _ in cyc),
                    )
                )
                self.cache[key] = names
            names = self.cache[key]
            for (i, (w, phi)), name in zip(cyc, names, strict=True):
                terms[i] = R.Gated(tokens([name], prev=True), R.scale(w, self._bonus(phi, ctx)))
        for i, p in enumerate(parts):
            if i not in terms:
                terms[i] = self.reward(p, ctx, under_g, conj)
        return R.Min(tuple(terms[i] for i in range(len(parts))), active=self.options.conjunction == "active")

    # -- assembly
    def assemble(self, reward: R.RExpr) -> tuple[Net, R.RExpr]:
        subs = self.timing + self.state + self.violation_nets
        places: list[Place] = []
        m0: list[int] = []
        for s_idx, sub in enumerate(subs):
            for k, (name, label) in enumerate(sub.places):
                places.append(Place(name, "counter" if k in sub.counters else sub.kind, s_idx, label))
                m0.append(1 if k == sub.initial else 0)
        index = {p.name: i for i, p in enumerate(places)}
        # per arc, in net order: guard, input place, output places (names and indices); a
        # region net of n places has n (n - 1) arcs, so this is kept to list comprehensions
        guards: list[Guard] = []
        ins: list[tuple[str, ...]] = []
        outs: list[tuple[str, ...]] = []
        t_subnet: list[int] = []
        src: list[int] = []
        out_rows: list[int] = []
        out_cols: list[int] = []
        subnets: list[SubNet] = []
        base = 0
        for s_idx, sub in enumerate(subs):
            names = [name for name, _ in sub.places]
            glob = [index[name] for name in names]
            one = [(name,) for name in names]  # one tuple per place, shared by the arcs through it
            t_base = len(guards)
            arcs = sub.arcs
            guards += [g for _, _, g in arcs]
            ins += [one[i] for i, _, _ in arcs]
            src += [glob[i] for i, _, _ in arcs]
            dsts = [d if isinstance(d, tuple) else (d,) for _, d, _ in arcs]
            outs += [one[d[0]] if len(d) == 1 else tuple(names[j] for j in d) for d in dsts]
            out_rows += [t_base + t for t, d in enumerate(dsts) for _ in d]
            out_cols += [glob[j] for d in dsts for j in d]
            t_subnet += [s_idx] * len(arcs)
            own = [base + k for k in range(len(sub.places))]
            base += len(sub.places)
            subnets.append(
                SubNet(
                    sub.name,
                    sub.kind,
                    sub.role,
                    tuple(i for k, i in enumerate(own) if k not in sub.counters),
                    tuple(range(t_base, len(guards))),
                    sub.formula,
                    tuple(i for k, i in enumerate(own) if k in sub.counters),
                )
            )
        n_t = len(guards)
        # D- and D+ in compressed rows (dense, a 500-place region net would be 250,000 x 1,500)
        shape = (n_t, len(places))
        pre = Incidence.ones(shape, np.arange(n_t), src)
        post = Incidence.ones(shape, out_rows, out_cols)
        trans = [
            Transition(f"t{t + 1}", g, i, o, s)
            for t, (g, i, o, s) in enumerate(zip(guards, ins, outs, t_subnet, strict=True))
        ]
        net = Net(tuple(places), tuple(trans), tuple(subnets), pre, post, np.array(m0, dtype=np.int64))
        return net, _resolve(reward, index)


def _masked(f: A.Formula, roots: set[int]) -> A.Formula:
    """``f`` with the obligation trees replaced by ``true`` (they have clocks of their own)."""
    if id(f) in roots:
        return A.Const(True)
    if isinstance(f, (A.And, A.Or)):
        return f.__class__(_masked(f.left, roots), _masked(f.right, roots))
    if isinstance(f, A.Weighted):
        return A.Weighted(f.weight, _masked(f.child, roots))
    if isinstance(f, A.Until):
        return A.Until(_masked(f.left, roots), _masked(f.right, roots), f.interval)
    if isinstance(f, (A.Eventually, A.Globally)):
        return f.__class__(_masked(f.child, roots), f.interval)
    return f


def _split_reading(f: A.Formula, standard: bool, roots: list[A.Formula]) -> A.Formula:
    """:func:`reward_reading` of ``f``, leaving the temporal parts with nested intervals as they
    are (collected in ``roots``) when ``standard``: their timed sub-nets track release exactly."""
    if isinstance(f, (A.Eventually, A.Globally, A.Until, A.Release)):
        if standard and needs_obligations(f):
            roots.append(f)
            return f
        return reward_reading(f)
    if isinstance(f, (A.And, A.Or)):
        return f.__class__(_split_reading(f.left, standard, roots), _split_reading(f.right, standard, roots), pos=f.pos)
    if isinstance(f, A.Weighted):
        return A.Weighted(f.weight, _split_reading(f.child, standard, roots), pos=f.pos)
    return f


def _unsatisfiable(spec: Spec, nf: A.Formula) -> list[str]:
    """Warnings for the conjuncts of ``nf`` that no trial of the spec's horizon can satisfy."""
    if spec.horizon is None or spec.plant is None:
        return []
    dt, steps = spec.param("dt"), _steps(spec)
    out = []
    for part in flatten(strip_weights(nf), A.And):
        first = earliest_witness(part, dt)
        if first > steps * dt * (1 + 1e-12):
            when = "never" if math.isinf(first) else f"not before t = {A.fmt_number(round(first, 9))} s"
            out.append(
                f"{spec.path or '<spec>'}: warning: '{part}' cannot be satisfied within the horizon "
                f"{A.fmt_number(spec.horizon)} s (its earliest witness: {when}); "
                "every trial violates it (option clock = trial reads intervals on the trial clock)"
            )
    return out


def _sides(core: A.Formula, sides: list[R.RExpr | None]) -> R.RExpr | None:
    """The reward of ``&`` (min) or ``|`` (max) over the sides that have one: the one side alone,
    None when neither has."""
    known = tuple(h for h in sides if h is not None)
    if not known:
        return None
    if len(known) == 1:
        return known[0]
    return R.Min(known) if isinstance(core, A.And) else R.Max(known)


def _weighted(w: float, e: R.RExpr) -> R.RExpr:
    """``w * e`` with a timing gate kept outside (so that ``min_active`` still sees it): a gated
    term scales its expression, a sum of gated terms each of its terms."""
    if isinstance(e, R.Gated):
        return R.Gated(e.gate, R.scale(w, e.expr))
    if isinstance(e, R.Sum) and all(isinstance(t, R.Gated) for t in e.terms):
        return R.Sum(tuple(_weighted(w, t) for t in e.terms))
    return R.scale(w, e)


def _resolve(e: R.RExpr, index: dict[str, int]) -> R.RExpr:
    if isinstance(e, R.Tokens):
        return R.Tokens(tuple(index[n] for n in e.names), e.names, e.prev)
    if not e.children:
        return e
    if isinstance(e, R.Gated):
        return R.Gated(_resolve(e.gate, index), _resolve(e.expr, index))
    if isinstance(e, R.Neg):
        return R.Neg(_resolve(e.arg, index))
    if isinstance(e, R.Graded):
        return dataclasses.replace(e, flat=_resolve(e.flat, index))
    field_name = {R.Sum: "terms", R.Prod: "factors", R.Min: "terms", R.Max: "terms"}[type(e)]
    children = tuple(_resolve(c, index) for c in e.children)
    return dataclasses.replace(e, **{field_name: children})  # type: ignore[type-var]  # e is Sum/Prod/Min/Max here


MAX_NORMAL_FORM = 10_000
"""Most nodes the normal form of a formula may have as a tree (what the compiler's passes walk):
``<->`` and ``W`` repeat their operands, so ten nested ``<->`` are already a thousand times the
formula (each nesting about doubles the compile time, and a normal form of 28,000 operators is a
net of 73,000 transitions). 255 conjuncts of three operators each are 1,000."""


def _expanded_size(f: A.Formula) -> int:
    """Nodes of ``f`` counted as a tree (a shared subformula once per use), computed on the shared
    nodes once each, children before parents, without recursion."""
    size: dict[int, int] = {}
    stack: list[tuple[A.Formula, bool]] = [(f, False)]
    while stack:
        node, ready = stack.pop()
        if id(node) in size:
            continue
        if ready:
            size[id(node)] = 1 + sum(size[id(c)] for c in node.children)
        else:
            stack.append((node, True))
            stack.extend((c, False) for c in node.children)
    return size[id(f)]


def compile_spec(spec: Spec, options: CompileOptions | None = None) -> RewardSystem:
    """Compile a checked spec into its reward system."""
    if spec.formula is None:
        raise CompileError(
            "the spec has no 'formula' to compile (its 'require' criteria compile to a hybrid automaton)",
            file=spec.path,
        )
    options = options or CompileOptions.from_spec(spec)
    if options.conjunction not in OPTIONS["conjunction"]:
        raise CompileError(f"unknown conjunction reading '{options.conjunction}' (literal or active)")
    if options.violations not in OPTIONS["violations"]:
        raise CompileError(f"unknown violations mode '{options.violations}' (off, permanent or counted)")
    if options.violations != "off" and _last_sample(spec) is None:
        raise CompileError(
            f"--violations {options.violations} needs the trial length: give the spec a 'horizon' and a 'plant'",
            file=spec.path,
        )
    if options.clock not in OPTIONS["clock"]:
        raise CompileError(f"unknown clock reading '{options.clock}' (standard or trial)")
    if options.reward not in OPTIONS["reward"]:
        raise CompileError(f"unknown reward '{options.reward}' ({', '.join(OPTIONS['reward'])})")
    if options.reward in MONITOR_REWARDS and options.violations != "off":
        raise CompileError(
            f"reward {options.reward} is paid by the monitor, not by the net: --violations {options.violations} "
            "applies to the net's rewards (net, shaped, graded)",
            file=spec.path,
        )
    size = _expanded_size(desugar(spec.formula))
    if size > MAX_NORMAL_FORM:
        raise CompileError(
            f"the formula's normal form would have {size:,} operators, more than the {MAX_NORMAL_FORM:,} supported: "
            "each '<->' and 'W' repeats its operands, so nesting them multiplies the formula; nest fewer, or give "
            "the repeated parts their own propositions",
            file=spec.path,
        )
    nf = normal_form(spec.formula)
    roots: list[A.Formula] = []
    formula = _split_reading(nf, options.clock == "standard", roots)
    warnings = _unsatisfiable(spec, nf) if options.clock == "standard" else []
    builder = _Builder(spec, options, formula, roots)
    everything = builder._all() if builder.segments else frozenset()
    reward = builder.reward(formula, everything, under_g=False, conj=True)
    penalty = 0.0
    net, resolved = builder.assemble(reward)
    charge: R.RExpr | None
    if builder.penalties:
        # c: more than any step can earn above a violation-free step
        lo_free, _ = bounds_without_violation(builder, net, resolved)
        _, hi = bounds_all_steps(net, resolved)
        penalty = hi - lo_free + 1.0
        if options.violations == "permanent":
            # r' = r - c v, v = 1 once any watched part is violated (on every later step)
            marks = [tokens([p]) for p in builder.penalties]
            charge = marks[0] if len(marks) == 1 else R.Max(tuple(marks))
        else:
            # r' = r - c * (new violations)
            new = [R.Sum((tokens([p]), R.Neg(tokens([p], prev=True)))) for p in builder.penalties]
            charge = new[0] if len(new) == 1 else R.Sum(tuple(new))
        reward = R.Sum((reward, R.Neg(R.scale(penalty, charge))))
        index = {p.name: i for i, p in enumerate(net.places)}
        resolved = _resolve(reward, index)
        charge = _resolve(charge, index)
    else:
        charge = None
    subs = builder.timing + builder.state + builder.violation_nets
    timed = tuple(
        TimedNet(tree, tuple((i, next(k for k, s in enumerate(subs) if s is part)) for i, part in parts))
        for tree, parts in builder.obligations
    )
    grader = Grader.of(spec, [a for g in builder.groups for a in g]) if R.is_graded(resolved) else None
    return RewardSystem(
        spec, nf, net, resolved, builder.groups, options, penalty, charge, timed, tuple(warnings), grader
    )


def _steps(spec: Spec) -> int:
    """Number of steps in a trial, ``round(horizon / dt)``."""
    return int(round(spec.horizon / spec.param("dt")))  # type: ignore[operator]


def _last_sample(spec: Spec) -> float | None:
    """A clock threshold that only the last sample of a trial passes (half a step before it)."""
    if spec.horizon is None or spec.plant is None:
        return None
    dt = spec.param("dt")
    return (_steps(spec) - 0.5) * dt
