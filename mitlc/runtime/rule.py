"""The firing rule's pieces that need no runtime: clock conditions, the rows of ``D``, region sub-nets.

:class:`~mitlc.runtime.NetRuntime` steps the rule its docstring states; a *region* sub-net (a
transition from every place to every other, each guarded by its target's region,
:func:`mitlc.petri.regions.region_net`) is moved by :func:`region_move` instead of a scan of its
``n (n - 1)`` transitions, and the other sub-nets add the fired rows of ``D`` found by
:func:`change_rows`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from mitlc.petri.net import Net, eval_state
from mitlc.spec import ast as A

__all__ = ["Rule", "change_rows", "clock_ok", "region_move", "region_subnets"]


def clock_ok(interval: A.Interval, tau: np.ndarray | float) -> np.ndarray | bool:
    lo = tau >= interval.lo if interval.lo_closed else tau > interval.lo
    hi = tau <= interval.hi if interval.hi_closed else tau < interval.hi
    return lo & hi


def change_rows(net: Net, transitions: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """The row of ``D = D+ - D-`` of each of ``transitions``, as its nonzero columns and values, from
    the sparse ``D-`` and ``D+`` (a place both taken from and fed cancels, as in the dense difference)."""
    pre, post = net.pre, net.post
    out = {}
    for t in transitions.tolist():
        change: dict[int, int] = {}
        for sign, inc in ((1, post), (-1, pre)):
            cols, vals = inc.row(t)
            for c, v in zip(cols.tolist(), vals.tolist(), strict=True):
                change[c] = change.get(c, 0) + sign * v
        kept = sorted((c, v) for c, v in change.items() if v)
        out[t] = (np.array([c for c, _ in kept], dtype=np.intp), np.array([v for _, v in kept], dtype=np.int64))
    return out


def region_subnets(net: Net) -> list[tuple[int, list[A.Formula | None]]]:
    """The sub-nets stepped by their region, with the region (state formula) of each place.

    A sub-net qualifies when its transitions are exactly, in net order, one from every place
    ``i`` to every other place ``j`` (``i`` major, ``j`` increasing), each taking the one token
    of ``i`` and putting it in ``j`` and guarded by one term, a state formula and nothing else,
    the same formula on every transition into ``j`` (:func:`mitlc.petri.regions.region_net`).
    The rule then moves the token from ``i`` to the first ``j != i`` whose formula holds.
    """
    by_subnet: dict[int, list[int]] = {}
    for t, tr in enumerate(net.transitions):
        by_subnet.setdefault(tr.subnet, []).append(t)

    pre_col, post_col = net.pre.single_columns(), net.post.single_columns()  # -1: not one token
    out = []
    for s, sub in enumerate(net.subnets):
        places, ts = sub.places, by_subnet.get(s, [])
        K = len(places)
        if K < 2 or sub.counters or len(ts) != K * (K - 1) or list(sub.transitions) != ts:
            continue
        formulas: list[A.Formula | None] = [None] * K
        ok = True
        k = 0
        for i in range(K):
            for j in range(K):
                if i == j:
                    continue
                t = ts[k]
                k += 1
                terms = net.transitions[t].guard.terms
                if pre_col[t] != places[i] or post_col[t] != places[j] or len(terms) != 1:
                    ok = False
                    break
                term = terms[0]
                if term.state is None or term.clock is not None or term.age is not None or term.event is not None:
                    ok = False
                    break
                if formulas[j] is None:
                    formulas[j] = term.state
                elif formulas[j] is not term.state and formulas[j] != term.state:
                    ok = False
                    break
            if not ok:
                break
        if ok:
            out.append((s, formulas))
    return out


def region_move(formulas: Sequence[A.Formula | None], here: np.ndarray, truth: Mapping[str, np.ndarray]) -> np.ndarray:
    """Where a region sub-net's token goes from local place ``here`` ``(n,)``: the rule's first
    transition in net order, from ``here`` to the first other place whose region holds;
    nowhere (it stays) when no other region holds."""
    n = here.shape[0]
    holds = np.zeros((n, len(formulas)), dtype=bool)
    for j, f in enumerate(formulas):
        if f is not None:
            holds[:, j] = eval_state(f, truth)
    holds[np.arange(n), here] = False  # no transition from a place to itself
    return np.where(holds.any(axis=1), holds.argmax(axis=1), here)


class Rule:
    """The firing rule of one net on batches of markings (the rule :class:`~mitlc.runtime.NetRuntime`
    states): per sub-net the first enabled transition, in net order, whose guard holds.

    Built once per net: the transitions' input and output places, the region sub-nets (moved by
    :func:`region_move`), the other transitions and their sparse rows of ``D``, and the distinct
    clock intervals of the guards (``clocks``: the order of the clock truths every method takes).
    """

    def __init__(self, net: Net) -> None:
        self.net = net
        self.n_subnets = len(net.subnets)
        self.subnet_places = tuple(np.array(s.places, dtype=np.intp) for s in net.subnets)
        self.src = np.array([net.place_index(t.inputs[0]) for t in net.transitions], dtype=np.intp)
        self.dst = np.array([net.place_index(t.outputs[0]) for t in net.transitions], dtype=np.intp)
        self.t_subnet = np.array([t.subnet for t in net.transitions], dtype=np.intp)
        # region sub-nets (a transition from every place to every other, guarded by the target's
        # region): stepped by the region that holds (region_move); the rest transition by transition
        self.regions = region_subnets(net)
        in_region = {s for s, _ in self.regions}
        self.scan = np.array([t for t, sub in enumerate(self.t_subnet.tolist()) if sub not in in_region], dtype=np.intp)
        # the scanned transitions' rows of D = D+ - D-, as (places, changes), from the sparse D-, D+
        self.d_rows = change_rows(net, self.scan)
        # distinct clock intervals of all guards, for the clock code
        clocks: list[A.Interval] = []
        for t in net.transitions:
            for term in t.guard.terms:
                if term.clock is not None and term.clock not in clocks:
                    clocks.append(term.clock)
        self.clocks: tuple[A.Interval, ...] = tuple(clocks)

    def guards(
        self,
        truth: Mapping[str, np.ndarray],
        clock_truth: Sequence[np.ndarray | bool],
        n: int,
        transitions: np.ndarray | None = None,
    ) -> np.ndarray:
        """Guard values ``(T, n)`` given atom truth and the truth of each clock interval
        (of ``transitions`` only, in that order, when given)."""
        ts = range(len(self.net.transitions)) if transitions is None else transitions.tolist()
        out = np.zeros((len(ts), n), dtype=bool)
        for k, t in enumerate(ts):
            for term in self.net.transitions[t].guard.terms:
                if term.event is not None:  # moved by the obligation state, not by the tables
                    continue
                ok = np.ones(n, dtype=bool)
                if term.state is not None:
                    ok = ok & eval_state(term.state, truth)
                if term.clock is not None:
                    ok = ok & clock_truth[self.clocks.index(term.clock)]
                out[k] |= ok
        return out

    def fire_scanning(self, M: np.ndarray, guards: np.ndarray) -> np.ndarray:
        """The documented rule transition by transition, ``T D + M`` with the dense ``D``: the
        reference that :meth:`fire` (region sub-nets by their region) is tested against."""
        n = M.shape[0]
        taken = np.zeros((n, self.n_subnets), dtype=bool)
        T = np.zeros((n, len(self.net.transitions)), dtype=np.int64)
        for t in range(len(self.net.transitions)):
            s = self.t_subnet[t]
            fire = (M[:, self.src[t]] > 0) & guards[t] & ~taken[:, s]
            T[:, t] = fire
            taken[:, s] |= fire
        return T @ np.asarray(self.net.D) + M

    def fire(
        self, M: np.ndarray, truth: Mapping[str, np.ndarray], clock_truth: Sequence[np.ndarray | bool]
    ) -> np.ndarray:
        """The documented rule: per sub-net the first enabled transition with a true guard.

        Region sub-nets move to the first other region that holds (:func:`region_move`), the
        others are scanned transition by transition; ``M + sum of the fired rows of D``,
        from the sparse rows. Equal to :meth:`fire_scanning` (tested).
        """
        n = M.shape[0]
        marked = [M[:, self.subnet_places[s]] > 0 for s, _ in self.regions]
        if np.any(M < 0) or any(np.any(m.sum(axis=1) > 1) for m in marked):
            # not one token per region sub-net: the reference rule as it is
            return self.fire_scanning(M, self.guards(truth, clock_truth, n))
        out = np.array(M, dtype=np.int64)
        rows = np.arange(n)
        for (s, formulas), m in zip(self.regions, marked, strict=True):
            places = self.subnet_places[s]
            here = np.argmax(m, axis=1)
            there = region_move(formulas, here, truth)
            moved = (there != here) & m.any(axis=1)  # a sub-net without its token stays empty
            out[rows[moved], places[here[moved]]] -= 1
            out[rows[moved], places[there[moved]]] += 1
        guards = self.guards(truth, clock_truth, n, self.scan)
        taken = np.zeros((n, self.n_subnets), dtype=bool)
        for k, t in enumerate(self.scan.tolist()):
            s = self.t_subnet[t]
            fire = (M[:, self.src[t]] > 0) & guards[k] & ~taken[:, s]
            if not fire.any():
                continue
            taken[:, s] |= fire
            cols, change = self.d_rows[t]
            out[np.ix_(np.flatnonzero(fire), cols)] += change
        return out
