"""Run a batch of reward nets in lock-step with a batch of plants.

A :class:`NetRuntime` holds one compiled :class:`~mitlc.petri.compile.RewardSystem`
and steps ``R`` independent copies of its net at once.  Markings are integer
arrays of shape ``(R, P)`` (runs x places); states are ``(R, n)`` in the
plant's ``state_names`` order.

Firing rule (one step, ``M_k -> M_k+1``)
----------------------------------------
Given the marking ``M_k``, the next state ``x_k+1`` and the clock
``tau_k+1``:

1. every proposition is evaluated on ``x_k+1`` (:meth:`NetRuntime.truth`);
2. every guard is evaluated on those truth values and on ``tau_k+1``
   (:meth:`mitlc.petri.net.Guard.evaluate`);
3. in every sub-net *at most one* transition fires: the first one, in net
   order (``t1, t2, ...``), whose input place is marked in ``M_k`` and whose
   guard holds.  A sub-net whose enabled transitions all have false guards
   keeps its token where it is.  Tokens never move twice in one step, so a
   chain of transitions whose guards hold at once takes one step per arc;
4. ``M_k+1 = T D + M_k`` with ``T`` the 0/1 row vector of fired transitions.

In a region sub-net (a transition from every place to every other, in that order, each
guarded by its target's region) the rule moves the token to the first other place whose
region holds, and leaves it where it is when none does; the runtime computes that
directly instead of scanning the sub-net's ``n (n - 1)`` transitions, and adds the fired
rows of ``D`` from the net's sparse ``D-`` and ``D+`` (``NetRuntime._fire_scanning`` is
the rule as written above, kept as the reference the tests compare with).

Time-triggered transitions (the timeline of an interval, the deadline of a
bounded until) are ordinary transitions whose guard is a clock condition; they
fire on the first step whose ``tau_k+1`` satisfies it.

The reward of the step is ``r_k+1 = r(M_k, M_k+1)`` (:meth:`NetRuntime.reward`).

Fast path
---------
Each sub-net holds one token, so a marking is one of finitely many
*codes* (mixed radix over the sub-nets' local place indices), the guards see
the propositions only through a finite *atom code* (one bit per proposition)
and the clock only through which of the guards' clock intervals contain
``tau``.  When those sets are small, the runtime tabulates the rule above once
(``next_code[clock, code, atom]`` and ``reward[code, code']``), and a step is
two table look-ups.  The tables are built *from* the direct rule, and
:meth:`NetRuntime.step` gives the same markings either way (tested).  When the
product of the sub-nets' places is too large, only the markings reachable from
those :meth:`NetRuntime.reset` can produce are tabulated (*compact* tables, codes
index them), and the reward is evaluated on the markings if its table of pairs
would be too large.

Timed obligations
-----------------
The sub-nets of a formula part with nested intervals (``clock = standard``,
:mod:`mitlc.petri.timed`) are moved by per-run obligation state, not by the
tables: :meth:`NetRuntime.reset` starts it, :meth:`NetRuntime.step` and
:meth:`NetRuntime.step_code` advance it (one sample per call, in order), and a
trainer that looks ``next_code`` up itself calls :meth:`NetRuntime.advance_code`.

>>> from mitlc.spec.parse import parse_spec
>>> from mitlc.petri.compile import compile_spec
>>> rs = compile_spec(parse_spec('''
... plant pendulum(u_max = 3)
... prop kappa = abs(q) < 0.3
... formula F G kappa'''))
>>> rt = NetRuntime(rs)
>>> x0 = np.array([[np.pi, 0.0], [0.1, 0.0]])
>>> M0 = rt.reset(x0); M0.tolist()              # places: p_kappa, p_not_kappa
[[0, 1], [1, 0]]
>>> M1 = rt.step(M0, np.array([[0.2, 0.0], [0.5, 0.0]]), 0.03); M1.tolist()
[[1, 0], [0, 1]]
>>> rt.reward(M0, M1).tolist()                   # (1 + ~p_kappa)(p_kappa - p_not_kappa)
[1.0, -2.0]
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from mitlc.petri import reward as R
from mitlc.petri.compile import RewardSystem
from mitlc.petri.net import Net, eval_state
from mitlc.petri.timed import TimedState
from mitlc.spec import ast as A
from mitlc.spec import predicates as P

__all__ = ["NetRuntime"]

MAX_TABLE = 1 << 22
"""Largest transition or reward table (entries) the fast path builds."""


def _clock_ok(interval: A.Interval, tau: np.ndarray | float) -> np.ndarray | bool:
    lo = tau >= interval.lo if interval.lo_closed else tau > interval.lo
    hi = tau <= interval.hi if interval.hi_closed else tau < interval.hi
    return lo & hi


def compile_predicate(p: P.Pred, columns: Mapping[str, int]) -> Callable[[np.ndarray], np.ndarray | float]:
    """A predicate as one closure over a state batch ``x`` ``(R, n)`` (columns by variable name)."""

    def column(name: str) -> Callable[[Any], np.ndarray]:
        i = columns[name]
        return lambda x: x[:, i]

    return P.compile_numpy(p, column)


def _change_rows(net: Net, transitions: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
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


def _region_subnets(net: Net) -> list[tuple[int, list[A.Formula | None]]]:
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


class NetRuntime:
    """Step ``R`` copies of a reward net together with ``R`` plant states.

    ``state_names`` maps the columns of a state array to variables; by default
    the spec's plant's ``state_names``.
    """

    def __init__(
        self,
        rs: RewardSystem,
        state_names: Sequence[str] | None = None,
        dt: float | None = None,
        steps: int | None = None,
    ) -> None:
        self.rs = rs
        self.net = net = rs.net
        if state_names is None:
            plant = rs.spec.plant
            if plant is None:
                raise ValueError("the spec names no plant: pass state_names")
            state_names = plant.state_names
        self.state_names = tuple(state_names)
        self.atoms: tuple[str, ...] = rs.atoms
        self.graded = rs.grader is not None
        """Whether the reward reads the new state too (``reward = shaped``): then no reward table."""
        self._preds = tuple(rs.spec.prop(a).pred for a in self.atoms)
        self._columns = {name: i for i, name in enumerate(self.state_names)}
        for pred in self._preds:
            for v in P.variables(pred):
                if v.name not in self._columns:
                    raise ValueError(f"state variable '{v.name}' is not among {self.state_names}")
        self._fast_preds = tuple(compile_predicate(p, self._columns) for p in self._preds)

        self.n_places = len(net.places)
        self.n_subnets = len(net.subnets)
        self.subnet_places = tuple(np.array(s.places, dtype=np.intp) for s in net.subnets)
        self._src = np.array([net.place_index(t.inputs[0]) for t in net.transitions], dtype=np.intp)
        self._dst = np.array([net.place_index(t.outputs[0]) for t in net.transitions], dtype=np.intp)
        self._t_subnet = np.array([t.subnet for t in net.transitions], dtype=np.intp)
        # region sub-nets (a transition from every place to every other, guarded by the target's
        # region): stepped by the region that holds (_region_move); the rest transition by transition
        self._regions = _region_subnets(net)
        in_region = {s for s, _ in self._regions}
        self._scan = np.array(
            [t for t, sub in enumerate(self._t_subnet.tolist()) if sub not in in_region], dtype=np.intp
        )
        # the scanned transitions' rows of D = D+ - D-, as (places, changes), from the sparse D-, D+
        self._d_rows = _change_rows(net, self._scan)

        # distinct clock intervals of all guards, for the clock code
        clocks: list[A.Interval] = []
        for t in net.transitions:
            for term in t.guard.terms:
                if term.clock is not None and term.clock not in clocks:
                    clocks.append(term.clock)
        self.clocks: tuple[A.Interval, ...] = tuple(clocks)

        # mixed-radix marking codes: code = sum_s local_index_s * stride_s
        sizes = [len(p) for p in self.subnet_places]
        n_codes = math.prod(sizes)  # a Python int: the product may not fit in int64
        big = [0] * len(sizes)
        if n_codes < 2**62:  # past int64 the mixed-radix codes are not used (compact tables or none at all)
            acc = 1
            for s in range(len(sizes) - 1, -1, -1):  # suffix products in one pass (500 sub-nets: not 250,000)
                big[s] = acc
                acc *= sizes[s]
        strides = np.array(big, dtype=np.int64)
        self._sizes = sizes
        self._strides = strides
        self.n_codes = n_codes
        self.compact = False  # codes index the reachable markings (_build_compact) instead of mixed radix
        self._place_weight = np.zeros(self.n_places, dtype=np.int64)
        self._place_subnet = np.zeros(self.n_places, dtype=np.intp)
        for s, places in enumerate(self.subnet_places):
            for local, p in enumerate(places):
                self._place_weight[p] = local * strides[s]
                self._place_subnet[p] = s
        self._atom_bits = (
            (np.int64(1) << np.arange(len(self.atoms), dtype=np.int64)) if self.atoms else np.zeros(0, np.int64)
        )

        # state sub-nets: the region of each place (the state guard into it)
        self._region_of: dict[int, A.Formula] = {}
        regions = dict(self._regions)
        for s_index, sub in enumerate(net.subnets):
            if sub.kind != "state":
                continue
            if s_index in regions:  # every transition into a place has the one guard, its region
                self._region_of.update(
                    (int(p), f) for p, f in zip(sub.places, regions[s_index], strict=True) if f is not None
                )
                continue
            for t_index in sub.transitions:
                tr = net.transitions[t_index]
                p = net.place_index(tr.outputs[0])
                terms = [term.state for term in tr.guard.terms if term.state is not None and term.clock is None]
                if p not in self._region_of and terms:
                    self._region_of[p] = terms[0]

        # counting places (violations = counted) are outside the one-token codes:
        # their increments are tabulated per (code, next code) pair
        self.counters = np.array(net.counters, dtype=np.intp)
        self._clock_ends = np.zeros(0)
        self.timed = rs.timed
        self.tables = self._build_tables()

        # timed obligation sub-nets (clock = standard with nested intervals): their tokens
        # are moved by the obligation state (one TimedState per tree), not by the tables
        self._timed_states: list[TimedState] = []
        self.dt: float | None = None
        self.steps: int | None = None
        if self.timed:
            plant = rs.spec.plant
            if dt is None and plant is not None:
                dt = float(rs.spec.param("dt"))
            if steps is None and dt is not None and rs.spec.horizon is not None:
                steps = int(round(rs.spec.horizon / dt))
            if dt is None or steps is None:
                raise ValueError(
                    "the net has timed obligations: give the spec a plant and a horizon, or pass dt and steps"
                )
            self.dt, self.steps = float(dt), int(steps)
        self._timed_map = [
            [(node, s, tn.local(node)) for node, s in tn.subnets] for tn in self.timed
        ]  # per tree: (node, sub-net, engine code -> local place)

    # ------------------------------------------------------------ truth
    def truth(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Proposition truth on states ``x`` ``(R, n)``: ``{atom: (R,) bool}``."""
        x = np.asarray(x, dtype=float)
        env = {name: x[:, i] for name, i in self._columns.items()}
        out = {}
        for atom, pred in zip(self.atoms, self._preds, strict=True):
            out[atom] = np.broadcast_to(np.asarray(P.evaluate(pred, env), dtype=bool), x.shape[:1])
        return out

    def atom_code(self, x: np.ndarray) -> np.ndarray:
        """The propositions' truth on ``x`` packed into one integer per run (bit i = atom i)."""
        preds = self._fast_preds
        if not preds:
            return np.zeros(np.shape(x)[0], dtype=np.int64)
        with np.errstate(all="ignore"):  # IEEE arithmetic, as the monitor reads it: exp(exp(q)) > 5 holds at inf
            return self._atom_code(preds, x)

    @staticmethod
    def _atom_code(preds: tuple[Callable[[np.ndarray], np.ndarray | float], ...], x: np.ndarray) -> np.ndarray:
        code = np.asarray(preds[0](x), dtype=bool)
        if len(preds) <= 7:  # bools viewed as 0/1 bytes: no conversion pass
            code = code.view(np.int8)
            for i, pred in enumerate(preds[1:], 1):
                code = code + (np.asarray(pred(x), dtype=bool).view(np.int8) << i)
            return code
        code = code.astype(np.int64)
        for i, pred in enumerate(preds[1:], 1):
            code += np.asarray(pred(x), dtype=np.int64) << i
        return code

    def clock_code(self, tau: np.ndarray | float) -> np.ndarray | int:
        """Which of the guards' clock intervals contain ``tau``, packed into an integer.

        With compact tables (:meth:`_build_compact`) the index of the elementary clock
        segment holding ``tau`` instead (the intervals' ends cut the time line into
        points and open stretches on which every clock condition is constant).
        """
        if self.compact:
            ends = self._clock_ends
            j = np.searchsorted(ends, tau, side="left")
            on = (j < len(ends)) & (ends[np.minimum(j, len(ends) - 1)] == tau) if len(ends) else False
            seg = 2 * j + np.asarray(on, dtype=np.int64)
            return int(seg) if np.ndim(tau) == 0 else seg
        if np.ndim(tau) == 0:
            tau = float(tau)
            return sum(1 << i for i, c in enumerate(self.clocks) if _clock_ok(c, tau))
        tau = np.asarray(tau, dtype=float)
        code = np.zeros(tau.shape, dtype=np.int64)
        for i, c in enumerate(self.clocks):
            code += np.asarray(_clock_ok(c, tau), dtype=np.int64) << i
        return code

    # ------------------------------------------------------------ markings and codes
    def _check_marking(self, M: np.ndarray) -> np.ndarray:
        M = np.asarray(M)
        if M.ndim != 2 or M.shape[1] != self.n_places:
            raise ValueError(f"marking must be (R, {self.n_places}), got {M.shape}")
        for s, places in enumerate(self.subnet_places):
            if not np.all(M[:, places].sum(axis=1) == 1):
                raise ValueError(f"sub-net {self.net.subnets[s].name!r} must hold exactly one token")
        return M

    def encode(self, M: np.ndarray) -> np.ndarray:
        """Marking ``(R, P)`` (one token per sub-net) to codes ``(R,)``."""
        if self.compact:
            assert self.tables is not None and self.tables.index is not None
            index, rows = self.tables.index, np.ascontiguousarray(np.asarray(M, dtype=np.int8))
            try:
                return np.array([index[r.tobytes()] for r in rows], dtype=np.int64)
            except KeyError:
                raise ValueError("marking outside the net's reachable markings") from None
        return np.asarray(M, dtype=np.int64) @ self._place_weight

    def decode(self, code: np.ndarray) -> np.ndarray:
        """Codes ``(R,)`` to markings ``(R, P)``."""
        if self.compact:
            assert self.tables is not None and self.tables.markings is not None
            return self.tables.markings[np.asarray(code, dtype=np.int64)].astype(np.int64)
        code = np.asarray(code, dtype=np.int64)
        M = np.zeros((code.shape[0], self.n_places), dtype=np.int64)
        rows = np.arange(code.shape[0])
        for s, places in enumerate(self.subnet_places):
            local = (code // self._strides[s]) % self._sizes[s]
            M[rows, places[local]] = 1
        return M

    def marked_places(self, code: np.ndarray) -> np.ndarray:
        """Codes ``(R,)`` to the marked place of every sub-net, ``(R, S)`` place indices."""
        return (
            self.tables.marked[np.asarray(code)]
            if self.tables is not None
            else np.stack(
                [
                    self.subnet_places[s][(np.asarray(code) // self._strides[s]) % self._sizes[s]]
                    for s in range(self.n_subnets)
                ],
                axis=1,
            )
        )

    # ------------------------------------------------------------ the rule itself
    def _guards(
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

    def _fire_scanning(self, M: np.ndarray, guards: np.ndarray) -> np.ndarray:
        """The documented rule transition by transition, ``T D + M`` with the dense ``D``: the
        reference that :meth:`_fire` (region sub-nets by their region) is tested against."""
        n = M.shape[0]
        taken = np.zeros((n, self.n_subnets), dtype=bool)
        T = np.zeros((n, len(self.net.transitions)), dtype=np.int64)
        for t in range(len(self.net.transitions)):
            s = self._t_subnet[t]
            fire = (M[:, self._src[t]] > 0) & guards[t] & ~taken[:, s]
            T[:, t] = fire
            taken[:, s] |= fire
        return T @ np.asarray(self.net.D) + M

    def _region_move(
        self, formulas: Sequence[A.Formula | None], here: np.ndarray, truth: Mapping[str, np.ndarray]
    ) -> np.ndarray:
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

    def _fire(
        self, M: np.ndarray, truth: Mapping[str, np.ndarray], clock_truth: Sequence[np.ndarray | bool]
    ) -> np.ndarray:
        """The documented rule: per sub-net the first enabled transition with a true guard.

        Region sub-nets move to the first other region that holds (:meth:`_region_move`), the
        others are scanned transition by transition; ``M + sum of the fired rows of D``,
        from the sparse rows. Equal to :meth:`_fire_scanning` (tested).
        """
        n = M.shape[0]
        marked = [M[:, self.subnet_places[s]] > 0 for s, _ in self._regions]
        if np.any(M < 0) or any(np.any(m.sum(axis=1) > 1) for m in marked):
            # not one token per region sub-net: the reference rule as it is
            return self._fire_scanning(M, self._guards(truth, clock_truth, n))
        out = np.array(M, dtype=np.int64)
        rows = np.arange(n)
        for (s, formulas), m in zip(self._regions, marked, strict=True):
            places = self.subnet_places[s]
            here = np.argmax(m, axis=1)
            there = self._region_move(formulas, here, truth)
            moved = (there != here) & m.any(axis=1)  # a sub-net without its token stays empty
            out[rows[moved], places[here[moved]]] -= 1
            out[rows[moved], places[there[moved]]] += 1
        guards = self._guards(truth, clock_truth, n, self._scan)
        taken = np.zeros((n, self.n_subnets), dtype=bool)
        for k, t in enumerate(self._scan.tolist()):
            s = self._t_subnet[t]
            fire = (M[:, self._src[t]] > 0) & guards[k] & ~taken[:, s]
            if not fire.any():
                continue
            taken[:, s] |= fire
            cols, change = self._d_rows[t]
            out[np.ix_(np.flatnonzero(fire), cols)] += change
        return out

    def step_direct(self, M: np.ndarray, x_next: np.ndarray, tau_next: np.ndarray | float) -> np.ndarray:
        """:meth:`step` computed from the rule (no tables); the reference."""
        M = self._check_marking(M)
        n = M.shape[0]
        truth = self.truth(x_next)
        tau = np.broadcast_to(np.asarray(tau_next, dtype=float), (n,))
        clock_truth = [_clock_ok(c, tau) for c in self.clocks]
        return self._fire(M, truth, clock_truth)

    def _step_scanning(self, M: np.ndarray, x_next: np.ndarray, tau_next: np.ndarray | float) -> np.ndarray:
        """:meth:`step_direct` by the transition-scanning rule everywhere (:meth:`_fire_scanning`)."""
        M = self._check_marking(M)
        n = M.shape[0]
        truth = self.truth(x_next)
        tau = np.broadcast_to(np.asarray(tau_next, dtype=float), (n,))
        clock_truth = [_clock_ok(c, tau) for c in self.clocks]
        return self._fire_scanning(M, self._guards(truth, clock_truth, n))

    # ------------------------------------------------------------ timed obligations
    def _timed_observe(self, x: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """Feed sample ``x`` to every obligation tree: ``(sub-net, local place (R,))`` pairs."""
        code = self.atom_code(x)
        truth = {a: ((code >> i) & 1).astype(bool) for i, a in enumerate(self.atoms)}
        out: list[tuple[int, np.ndarray]] = []
        for state, mapping in zip(self._timed_states, self._timed_map, strict=True):
            state.observe(truth)
            where = state.places()
            out.extend((s, local[where[node]]) for node, s, local in mapping)
        return out

    def _timed_reset(self, x0: np.ndarray) -> list[tuple[int, np.ndarray]]:
        assert self.dt is not None and self.steps is not None
        n = np.shape(x0)[0]
        self._timed_states = [TimedState(tn.tree, self.dt, n, self.steps) for tn in self.timed]
        return self._timed_observe(x0)

    def _timed_markings(self, M: np.ndarray, moves: list[tuple[int, np.ndarray]]) -> np.ndarray:
        rows = np.arange(M.shape[0])
        for s, local in moves:
            places = self.subnet_places[s]
            M[:, places] = 0
            M[rows, places[local]] = 1
        return M

    def _timed_codes(self, code: np.ndarray, moves: list[tuple[int, np.ndarray]]) -> np.ndarray:
        if self.compact:
            return self.encode(self._timed_markings(self.decode(code), moves))
        code = np.array(code, dtype=np.int64)
        for s, local in moves:
            old = (code // self._strides[s]) % self._sizes[s]
            code += (local - old) * self._strides[s]
        return code

    def advance_code(self, code_next: np.ndarray, x_next: np.ndarray) -> np.ndarray:
        """Move the timed obligation tokens of codes ``code_next`` for sample ``x_next``.

        The tables keep those tokens where they are; a trainer that looks
        ``next_code`` up itself calls this after every look-up (a no-op, returning
        ``code_next``, when the net has no timed obligations).
        """
        if not self.timed:
            return code_next
        return self._timed_codes(code_next, self._timed_observe(np.asarray(x_next, dtype=float)))

    def obligation_clocks(self) -> np.ndarray:
        """Per run, the age of each timed node's oldest live obligation divided by its interval's
        upper end (the trial length when unbounded), 0 where none lives: ``(R, timed nodes)``."""
        cols = []
        for state, tn in zip(self._timed_states, self.timed, strict=True):
            ages = state.clocks()
            for node, _ in tn.subnets:
                iv = tn.tree.nodes[node].interval
                scale = iv.hi if math.isfinite(iv.hi) and iv.hi > 0 else max(state.N * state.dt, state.dt)
                cols.append(np.nan_to_num(ages[node] / scale, nan=0.0))
        if not cols:
            return np.zeros((0, 0))
        return np.stack(cols, axis=1)

    def verdicts(self) -> np.ndarray:
        """Per run, each obligation tree's value so far (``timed.TRUE``, ``FALSE``, ``PENDING``), ``(R, trees)``."""
        return np.stack([s.verdict() for s in self._timed_states], axis=1) if self._timed_states else np.zeros((0, 0))

    # ------------------------------------------------------------ public API
    def reset(self, x0: np.ndarray) -> np.ndarray:
        """Initial markings ``(R, P)``: timing places from ``net.M0``, state tokens on x0's region."""
        x0 = np.asarray(x0, dtype=float)
        n = x0.shape[0]
        M = np.tile(np.asarray(self.net.M0, dtype=np.int64), (n, 1))
        truth = self.truth(x0)
        for sub, places in zip(self.net.subnets, self.subnet_places, strict=True):
            if sub.kind != "state":
                continue
            placed = np.zeros(n, dtype=bool)
            new = np.zeros((n, len(places)), dtype=np.int64)
            for j, p in enumerate(places):
                region = self._region_of.get(int(p))
                if region is None:
                    continue
                here = eval_state(region, truth) & ~placed
                new[:, j] = here
                placed |= here
            new[~placed] = M[~placed][:, places]  # no region holds: keep M0 (cannot happen for region nets)
            M[:, places] = new
        if self.timed:
            M = self._timed_markings(M, self._timed_reset(x0))
        return M

    def step(self, M: np.ndarray, x_next: np.ndarray, tau_next: np.ndarray | float) -> np.ndarray:
        """``M_k+1`` from ``M_k`` ``(R, P)``, ``x_k+1`` ``(R, n)`` and ``tau_k+1`` (scalar or ``(R,)``)."""
        if self.tables is None:
            M_next = self.step_direct(M, x_next, tau_next)
            if self.timed:
                M_next = self._timed_markings(M_next, self._timed_observe(np.asarray(x_next, dtype=float)))
            return M_next
        M = self._check_marking(M)
        code = self.encode(M)
        code_next = self.step_code(code, np.asarray(x_next, dtype=float), tau_next)
        M_next = self.decode(code_next)
        if self.counters.size:
            M_next[:, self.counters] = M[:, self.counters] + self.tables.counter_inc[code, code_next]
        return M_next

    def reward(self, M_prev: np.ndarray, M_next: np.ndarray, x_next: np.ndarray | None = None) -> np.ndarray:
        """``r(M_k, M_k+1)`` for every run, ``(R,)`` floats; a graded reward (``reward = shaped``) also
        reads the new states ``x_next`` ``(R, n)``."""
        grades = self.grades(x_next) if self.graded else None
        return np.asarray(self.rs.reward.evaluate(np.asarray(M_prev), np.asarray(M_next), grades), dtype=float)

    def grades(self, x: np.ndarray | None) -> np.ndarray:
        """The propositions' grades ``(R, atoms)`` at states ``x`` ``(R, n)`` (``reward = shaped``)."""
        if self.rs.grader is None:
            raise ValueError("the reward has no graded propositions (reward = net)")
        if x is None:
            raise ValueError("a graded reward (reward = shaped) needs the new states x_next")
        x = np.asarray(x, dtype=float)
        return self.rs.grader.grades({name: x[:, i] for name, i in self._columns.items()})

    # ------------------------------------------------------------ fast path on codes
    def reset_code(self, x0: np.ndarray) -> np.ndarray:
        """:meth:`reset` as marking codes ``(R,)``."""
        return self.encode(self.reset(x0))

    def step_code(self, code: np.ndarray, x_next: np.ndarray, tau_next: np.ndarray | float) -> np.ndarray:
        """:meth:`step` on marking codes (needs the tables)."""
        tables = self.tables
        if tables is None:
            code_next = self.encode(self.step_direct(self.decode(code), x_next, tau_next))
        else:
            code_next = tables.next_code[self.clock_code(tau_next), code, self.atom_code(x_next)]
        return self.advance_code(code_next, x_next)

    def trace_codes(self, x: np.ndarray, taus: np.ndarray) -> np.ndarray | None:
        """The marking codes ``(N+1,)`` of one run over a whole recorded trace: :meth:`reset_code` on
        ``x[0]``, then :meth:`step_code` on each ``x[k]`` at ``taus[k]``, ``x`` ``(N+1, n)``. The
        propositions and clock conditions of every sample are evaluated at once, then one table
        look-up per sample (what ``mitlc check --net`` steps a long trace with). None where a step
        needs more than the tables: no tables, or timed obligations.

        >>> from mitlc.spec.parse import parse_spec
        >>> from mitlc.petri.compile import compile_spec
        >>> rt = NetRuntime(compile_spec(parse_spec("prop a = x < 1\\nformula F[0,1] a")), ["x"])
        >>> x, taus = np.array([[2.0], [0.5], [3.0]]), np.array([0.0, 0.6, 1.2])
        >>> codes = [rt.reset_code(x[:1])]
        >>> for k in (1, 2):
        ...     codes.append(rt.step_code(codes[-1], x[k : k + 1], taus[k]))
        >>> rt.trace_codes(x, taus).tolist() == np.concatenate(codes).tolist()
        True
        """
        tables = self.tables
        if tables is None or self.timed:
            return None
        x = np.asarray(x, dtype=float)
        code = int(self.reset_code(x[:1])[0])
        if len(x) == 1:
            return np.array([code], dtype=np.int64)
        atoms = np.asarray(self.atom_code(x[1:]), dtype=np.int64)
        clocks = np.asarray(self.clock_code(np.asarray(taus[1:], dtype=float)), dtype=np.int64)
        clocks = np.broadcast_to(clocks, atoms.shape)
        table = np.ascontiguousarray(tables.next_code, dtype=np.int64)
        n_codes, n_atoms = table.shape[1], table.shape[2]
        flat = table.reshape(-1).data  # a memoryview, whose items are Python ints: the loop stays in plain Python
        out = [code]
        append = out.append
        for base in (clocks * n_codes * n_atoms + atoms).tolist():
            code = flat[base + code * n_atoms]
            append(code)
        return np.array(out, dtype=np.int64)

    def sample_stepper(self) -> Callable[[int, Sequence[float], float], int] | None:
        """:meth:`step_code` for one run on Python numbers, ``step(code, x, tau) -> code``, with ``x`` the
        state as a sequence of floats (``state_names`` order): the propositions in plain Python
        (:func:`mitlc.learn.kernel.scalar_atoms`, numpy's truths) and one table look-up, for callers
        that step one sample at a time (the Gymnasium wrapper). None where a step needs more than
        the tables: no tables, timed obligations, or counting places.
        """
        tables = self.tables
        if tables is None or self.timed or self.counters.size:
            return None
        from mitlc.learn.kernel import scalar_atoms  # the same stage; kernel is only needed here

        atoms = scalar_atoms(self._preds, self._columns)
        table = tables.next_code
        if not self.compact and not self.clocks:

            def step(code: int, x: Sequence[float], tau: float) -> int:
                return int(table[0, code, atoms(x)])

        else:
            clock = self.clock_code

            def step(code: int, x: Sequence[float], tau: float) -> int:
                return int(table[clock(tau), code, atoms(x)])

        return step

    def trace_markings(self, codes: np.ndarray) -> np.ndarray:
        """Full markings ``(R, N+1, P)`` of code sequences ``(R, N+1)``, counters included.

        Codes leave out the counting places; their tokens are the running sum of
        the increments of each step.
        """
        codes = np.asarray(codes, dtype=np.int64)
        R, K = codes.shape
        M = self.decode(codes.reshape(-1)).reshape(R, K, self.n_places)
        if self.counters.size and K > 1:
            if self.tables is None:  # pragma: no cover - counted nets small enough to tabulate
                raise ValueError("counter tokens need the tables; use step() markings instead")
            inc = self.tables.counter_inc[codes[:, :-1], codes[:, 1:]]  # (R, K-1, C)
            M[:, 1:, self.counters] = np.cumsum(inc, axis=1)
        return M

    def reward_code(self, code_prev: np.ndarray, code_next: np.ndarray, x_next: np.ndarray | None = None) -> np.ndarray:
        """:meth:`reward` on marking codes (a graded reward reads ``x_next`` too)."""
        if self.tables is None or self.tables.reward is None:
            shape = np.shape(code_prev)
            prev, nxt = np.ravel(code_prev), np.ravel(code_next)
            return self.reward(self.decode(prev), self.decode(nxt), x_next).reshape(shape)
        return self.tables.reward[code_prev, code_next]

    def charge_code(self, code_prev: np.ndarray, code_next: np.ndarray) -> np.ndarray:
        """What the violation penalty ``c`` multiplies on these steps (0 without violations)."""
        if self.tables is not None and self.tables.charge is not None:
            return self.tables.charge[code_prev, code_next]
        if self.rs.charge is None:
            return np.zeros(np.shape(code_prev))
        shape = np.shape(code_prev)
        prev, nxt = self.decode(np.ravel(code_prev)), self.decode(np.ravel(code_next))
        return np.asarray(self.rs.charge.evaluate(prev, nxt), dtype=float).reshape(shape)

    def _build_tables(self) -> _Tables | None:
        n_atoms, n_clocks, n_codes = len(self.atoms), len(self.clocks), self.n_codes
        n_atom_codes, n_clock_codes = 1 << n_atoms, 1 << n_clocks
        if n_clock_codes * n_codes * n_atom_codes > MAX_TABLE or n_codes * n_codes > MAX_TABLE:
            return self._build_compact()
        codes = np.arange(n_codes, dtype=np.int64)
        markings = self.decode(codes)
        # every (code, atom code) pair in one batch
        pair_code = np.repeat(codes, n_atom_codes)
        pair_atom = np.tile(np.arange(n_atom_codes, dtype=np.int64), n_codes)
        M = markings[pair_code]
        truth = {a: ((pair_atom >> i) & 1).astype(bool) for i, a in enumerate(self.atoms)}
        next_code = np.empty((n_clock_codes, n_codes, n_atom_codes), dtype=np.int64)
        for ck in range(n_clock_codes):
            clock_truth = [bool((ck >> i) & 1) for i in range(n_clocks)]
            nxt = self._fire(M, truth, clock_truth)
            next_code[ck] = self.encode(nxt).reshape(n_codes, n_atom_codes)
        marked = (
            np.stack(
                [self.subnet_places[s][(codes // self._strides[s]) % self._sizes[s]] for s in range(self.n_subnets)],
                axis=1,
            )
            if self.n_subnets
            else np.zeros((n_codes, 0), dtype=np.intp)
        )
        # a counter grows when a transition feeding it fires, i.e. when its sub-net's
        # token moves from the transition's input to its one-token output
        counter_inc = np.zeros((n_codes, n_codes, len(self.counters)), dtype=np.int64)
        counter_col = {int(p): j for j, p in enumerate(self.counters)}
        for t, tr in enumerate(self.net.transitions):
            fed = [counter_col[self.net.place_index(o)] for o in tr.outputs if self.net.place_index(o) in counter_col]
            if not fed:
                continue
            s = self._t_subnet[t]
            dst = next(self.net.place_index(o) for o in tr.outputs if self.net.place_index(o) not in counter_col)
            moved = (marked[:, s] == self._src[t])[:, None] & (marked[:, s] == dst)[None, :]
            for j in fed:
                counter_inc[:, :, j] += moved
        prev = np.repeat(markings, n_codes, axis=0)
        now = np.tile(markings, (n_codes, 1))
        if self.counters.size:
            now[:, self.counters] = counter_inc.reshape(n_codes * n_codes, -1)
        # a graded reward reads the state too: no table of it (the charge reads markings only)
        if self.graded:
            exprs = [self.rs.charge if self.rs.charge is not None else R.ZERO]
        else:
            exprs = [self.rs.reward] + ([self.rs.charge] if self.rs.charge is not None else [])
        tabs = [np.asarray(e.evaluate(prev, now), dtype=float).reshape(n_codes, n_codes) for e in exprs]
        if self.counters.size:  # the table assumes the reward sees counters only through p - ~p
            prev[:, self.counters] += 7
            now[:, self.counters] += 7
            for e, tab in zip(exprs, tabs, strict=True):
                if not np.array_equal(np.asarray(e.evaluate(prev, now), dtype=float).reshape(n_codes, n_codes), tab):
                    return None
        reward: np.ndarray | None = tabs[0]
        charge = tabs[1] if len(tabs) > 1 else np.zeros_like(tabs[0])
        if self.graded:
            reward, charge = None, tabs[0]
        for a in (next_code, reward, charge, marked, counter_inc):
            if a is not None:
                a.setflags(write=False)
        return _Tables(next_code, reward, charge, marked, counter_inc)

    def _build_compact(self) -> _Tables | None:
        """Tables over the *reachable* markings only, with elementary clock segments.

        For nets whose sub-nets are many but move together (sixty bounded eventuallys of
        one proposition: 2^60 products, a few thousand reachable markings), the firing
        rule is tabulated by a breadth-first search from every initial marking
        :meth:`reset` can produce (the state and timed sub-nets' tokens anywhere, the
        others at ``M0``), and a code is an index into the reachable markings.  The
        reward is tabulated too when the square of their number fits, and evaluated on
        the markings otherwise.  ``None`` when even that is too large.
        """
        n_atoms = len(self.atoms)
        if n_atoms > 16 or self.counters.size:
            return None
        n_atom_codes = 1 << n_atoms
        ends = sorted({c.lo for c in self.clocks} | {c.hi for c in self.clocks if math.isfinite(c.hi)})
        reps = [ends[0] - 1.0] if ends else [0.0]
        for j, e in enumerate(ends):
            reps += [e, (e + ends[j + 1]) / 2 if j + 1 < len(ends) else e + 1.0]
        n_segs = len(reps)
        seg_truth = np.array([[bool(_clock_ok(c, t)) for c in self.clocks] for t in reps], dtype=bool).reshape(
            n_segs, len(self.clocks)
        )
        timed = {s for tn in self.timed for _, s in tn.subnets}
        free = [s for s, sub in enumerate(self.net.subnets) if sub.kind == "state" or s in timed]
        n_start = math.prod(len(self.subnet_places[s]) for s in free)
        if n_start > MAX_TABLE // 64:
            return None
        # markings as local place indices per sub-net, (n, S); the same rule as _fire
        S = self.n_subnets
        local_of = np.zeros(self.n_places, dtype=np.int64)
        for places in self.subnet_places:
            local_of[places] = np.arange(len(places))
        src_local, dst_local = local_of[self._src], local_of[self._dst]
        m0 = np.asarray(self.net.M0)
        base = np.array([local_of[places[np.argmax(m0[places])]] for places in self.subnet_places], dtype=np.int64)
        grids = np.meshgrid(*[np.arange(len(self.subnet_places[s])) for s in free], indexing="ij")
        start = np.tile(base, (n_start, 1))
        for s, g in zip(free, grids, strict=True):
            start[:, s] = g.reshape(-1)
        # rows are told apart by a 64-bit hash, checked to be exact (two markings never share one)
        weights = np.random.default_rng(20261201).integers(1, 2**63, size=S, dtype=np.uint64)
        index: dict[int, int] = {}
        rows: list[np.ndarray] = []

        def add(batch: np.ndarray) -> np.ndarray:
            with np.errstate(over="ignore"):
                keys = (batch.astype(np.uint64) * weights).sum(axis=1, dtype=np.uint64)
            uniq, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
            if not np.array_equal(batch, batch[first][inverse.reshape(-1)]):
                raise RuntimeError("marking hash collision")  # pragma: no cover - about 2^-40 here
            ids = np.empty(len(uniq), dtype=np.int64)
            for i, (key, j) in enumerate(zip(uniq.tolist(), first.tolist(), strict=True)):
                if key not in index:
                    index[key] = len(rows)
                    rows.append(batch[j])
                ids[i] = index[key]
            return ids[inverse.reshape(-1)]

        add(start)
        atom_of = np.tile(np.arange(n_atom_codes, dtype=np.int64), n_segs)
        seg_of = np.repeat(np.arange(n_segs), n_atom_codes)
        transitions: dict[int, np.ndarray] = {}  # code -> next codes (segs x atom codes)
        done = 0
        while done < len(rows):
            layer = np.arange(done, len(rows))
            done = len(rows)
            if done * n_segs * n_atom_codes > MAX_TABLE:
                return None
            L = np.repeat(np.array([rows[i] for i in layer], dtype=np.int64), n_segs * n_atom_codes, axis=0)
            reps_atom = np.tile(atom_of, len(layer))
            reps_seg = np.tile(seg_of, len(layer))
            truth = {a: ((reps_atom >> i) & 1).astype(bool) for i, a in enumerate(self.atoms)}
            clock_truth = [seg_truth[reps_seg, c] for c in range(len(self.clocks))]
            guards = self._guards(truth, clock_truth, L.shape[0], self._scan)
            nxt = L.copy()
            for sub, formulas in self._regions:
                nxt[:, sub] = self._region_move(formulas, L[:, sub], truth)
            taken = np.zeros(L.shape, dtype=bool)
            for k, t in enumerate(self._scan.tolist()):
                sub = self._t_subnet[t]
                fire = (L[:, sub] == src_local[t]) & guards[k] & ~taken[:, sub]
                nxt[fire, sub] = dst_local[t]
                taken[:, sub] |= fire
            ids = add(nxt).reshape(len(layer), n_segs, n_atom_codes)
            for i, code in enumerate(layer):
                transitions[int(code)] = ids[i]
        n_codes = len(rows)
        if n_segs * n_codes * n_atom_codes > MAX_TABLE:
            return None
        next_code = np.stack([transitions[c] for c in range(n_codes)], axis=1)  # (segs, codes, atoms)
        locals_ = np.array(rows, dtype=np.int64)
        marked = np.stack([places[locals_[:, s]] for s, places in enumerate(self.subnet_places)], axis=1)
        markings = np.zeros((n_codes, self.n_places), dtype=np.int8)
        markings[np.arange(n_codes)[:, None], marked] = 1
        by_bytes = {m.tobytes(): c for c, m in enumerate(markings)}
        reward = charge = None
        pairs = n_codes * n_codes
        # evaluating every pair of a large net costs more than it saves: pairs, and pairs x places (what the
        # evaluation reads: 250 bounded G's, 750 places, would be 1.5 GB per marking array and a minute)
        if pairs <= MAX_TABLE // 16 and pairs * self.n_places <= 4 * MAX_TABLE:
            prev = np.repeat(markings, n_codes, axis=0).astype(np.int64)
            now = np.tile(markings, (n_codes, 1)).astype(np.int64)
            if not self.graded:
                reward = np.asarray(self.rs.reward.evaluate(prev, now), dtype=float).reshape(n_codes, n_codes)
            charge = (
                np.asarray(self.rs.charge.evaluate(prev, now), dtype=float).reshape(n_codes, n_codes)
                if self.rs.charge is not None
                else np.zeros((n_codes, n_codes))
            )
        self.compact = True
        self.n_codes = n_codes
        self._clock_ends = np.array(ends, dtype=float)
        counter_inc = np.zeros((0, 0, 0), dtype=np.int64)
        for a in (next_code, markings, marked):
            a.setflags(write=False)
        return _Tables(next_code, reward, charge, marked, counter_inc, markings, by_bytes)


class _Tables:
    """The firing rule and the reward tabulated over marking, atom and clock codes."""

    __slots__ = ("next_code", "reward", "charge", "marked", "counter_inc", "markings", "index")

    def __init__(
        self,
        next_code: np.ndarray,
        reward: np.ndarray | None,
        charge: np.ndarray | None,
        marked: np.ndarray,
        counter_inc: np.ndarray,
        markings: np.ndarray | None = None,
        index: dict[bytes, int] | None = None,
    ) -> None:
        self.next_code = next_code  # (clock codes, marking codes, atom codes) -> marking code
        self.reward = reward  # (marking codes, marking codes) -> r(M_k, M_k+1); None: evaluate on markings
        self.charge = charge  # (marking codes, marking codes) -> what the penalty c multiplies (0 with off)
        self.marked = marked  # (marking codes, sub-nets) -> marked place index
        self.counter_inc = counter_inc  # (marking codes, marking codes, counters) -> tokens added
        self.markings = markings  # compact tables: (marking codes, places) int8, the reachable markings
        self.index = index  # compact tables: marking bytes -> code
