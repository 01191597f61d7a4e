"""State-related sub-nets: propositions grouped into provably disjoint regions, one
region net per group (thesis section 4-2, net C-2)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from mitlc.petri.net import Guard
from mitlc.petri.parts import Arc, Part
from mitlc.plants import wrap_angle
from mitlc.spec import ast as A
from mitlc.spec import predicates as P
from mitlc.spec.model import Spec

__all__ = ["state_groups", "covers", "region_net", "initial_region", "init_point"]


def state_groups(spec: Spec, names: Sequence[str]) -> tuple[tuple[str, ...], ...]:
    """Group propositions so that the regions within a group are provably disjoint.

    Greedy, in the order given: each proposition joins the first group whose
    members it is disjoint from (:func:`~mitlc.spec.predicates.provably_disjoint`
    with each), else starts a new group.

    Each proposition's region is computed once, and a group keeps, per variable,
    the union of its members' intervals: a region none of whose boxes meets that
    union in some variable is disjoint from every member without testing them one
    by one (500 disjoint intervals of one variable: 500 tests, not 125,000).
    Otherwise the members are tested one by one, so the groups are exactly those
    of the pairwise rule.
    """
    doms = spec.domains()
    groups: list[_Group] = []
    for name in names:
        reg = P.region(spec.prop(name).pred, doms)
        for g in groups:
            if g.admits(reg, doms):
                g.add(name, reg, doms)
                break
        else:
            g = _Group()
            g.add(name, reg, doms)
            groups.append(g)
    return tuple(tuple(g.names) for g in groups)


class _Group:
    """A group of :func:`state_groups` under construction: its members' regions and, for each
    variable that every one of their boxes constrains, the union of those boxes' intervals."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.regions: list[P.Region] = []
        self.known = True  # every member's region is known (else nothing is provably disjoint from it)
        self.hull: dict[str, P.IntervalSet] | None = None  # None: no box yet

    def add(self, name: str, reg: P.Region | None, doms: P.Domains) -> None:
        self.names.append(name)
        if reg is None:
            self.known = False
            return
        self.regions.append(reg)
        for box in reg:
            constrained = dict(box)
            if self.hull is None:
                self.hull = constrained
                continue
            for v in list(self.hull):  # a variable some box leaves free is dropped for good
                if v in constrained:
                    self.hull[v] = self.hull[v].union(constrained[v])
                else:
                    del self.hull[v]

    def admits(self, reg: P.Region | None, doms: P.Domains) -> bool:
        """True if ``reg`` is provably disjoint from every member's region."""
        if reg is None or not self.known:
            return False
        hull = self.hull or {}
        if all(any(v in hull and s.intersect(hull[v]).is_empty for v, s in box) for box in reg):
            return True  # each box misses, in some variable, the interval of every member's box
        return all(P.regions_disjoint(reg, other, doms) for other in self.regions)


def covers(spec: Spec, members: Sequence[str]) -> bool:
    """True if the members' regions provably cover the whole state space."""
    preds = [spec.prop(m).pred for m in members]
    union = preds[0]
    for p in preds[1:]:
        union = P.POr(union, p)
    return P.provably_empty(P.PNot(union), spec.domains())


def region_net(spec: Spec, group: tuple[str, ...], unique: Callable[[str], str]) -> Part:
    """The region net of ``group`` (the thesis's net C-2): a place per proposition, plus
    "none" unless the regions cover the state space, and an arc between every two places,
    guarded by the target's region. ``unique`` makes each place name unused."""
    places = [(unique(f"p_{a}"), a) for a in group]
    regions: list[A.Formula] = [A.Atom(a) for a in group]
    whole = covers(spec, group)
    if not whole:
        if len(group) == 1:
            places.append((unique(f"p_not_{group[0]}"), f"!{group[0]}"))
            regions.append(A.Not(A.Atom(group[0])))
        else:
            places.append((unique("p_none_" + "_".join(group)), "none"))
            none: A.Formula = A.Not(A.Atom(group[0]))
            for a in group[1:]:
                none = A.And(none, A.Not(A.Atom(a)))
            regions.append(none)
    guards = [Guard.state(r) for r in regions]  # one guard per target, shared by the arcs into it
    arcs: list[Arc] = [(i, j, guards[j]) for i in range(len(places)) for j in range(len(places)) if i != j]
    initial = initial_region(spec, group, whole)
    return Part(f"region({', '.join(group)})", "state", "region", places, arcs, initial)


def initial_region(spec: Spec, group: tuple[str, ...], whole: bool) -> int:
    """The place marked first: the region of the centre of the spec's initial set (``whole``:
    the group's regions cover the state space, so there is no "none" place)."""
    point = init_point(spec)
    if point is not None:
        for i, a in enumerate(group):
            pred = spec.prop(a).pred
            if all(v.name in point for v in P.variables(pred)) and bool(P.evaluate(pred, point)):
                return i
    return 0 if whole else len(group)


def init_point(spec: Spec) -> dict[str, float] | None:
    """The centre of the spec's initial set (angles wrapped), None without an ``init``."""
    if not spec.init:
        return None
    point = {r.var: 0.5 * (r.lo + r.hi) for r in spec.init}
    plant = spec.plant
    if plant is not None:
        for v in plant.state:
            point.setdefault(v.name, 0.0)
            if v.periodic:
                point[v.name] = float(wrap_angle(np.float64(point[v.name])))
    return point
