"""Timed obligations: nested intervals read as standard MITL, with clocks on tokens.

A temporal operator nested under another one (``G (fast -> F[0,0.5] !fast)``,
``F[0,2] G goal``) is an *obligation* that starts again at every sample its
parent needs it: one instance per start time ``s``, whose token's *age* is
``t_k - t_s``.  An :class:`ObligationTree` is the formula part such a family of
obligations lives in (its root is a temporal operator with no temporal
ancestor, so it has exactly one instance, started at ``t = 0``);
:class:`TimedState` is the per-run state of its tokens and steps them.

Semantics.  Every node instance ``n@s`` carries a three-valued value: true,
false or *pending*.  After sample ``k`` it is the Kleene value of the
finite-trace semantics of docs/monitor.md with the samples after ``k`` unknown
(and the trace's last sample ``N`` known, so windows are cut at the end as the
monitor cuts them).  Kleene values only ever go from pending to true or false,
never back; pending at the last sample cannot happen, so the value then is the
monitor's verdict.  A value is false only when every continuation makes it
false: the net never records a violation that could still be avoided.

Tokens.  An instance is *live* while it is pending and a live instance of its
parent needs it (the root: while pending).  Its token lies in one of three
places of its node's sub-net: ``open`` when the next sample falls inside its
interval (for until and release: inside the interval of the right side),
``wait`` otherwise (before its interval opens, or after it closed while its
value waits on nested obligations), ``idle`` when there is no live instance.
The learner's marking is this projection: one token per sub-net, in the most
urgent place any instance of the node occupies (open, then wait), so the
marking keeps one token per sub-net and live instances that are in the same
place are merged.  The root's sub-net has ``met`` and ``failed`` instead of
``idle``: absorbing places recording the verdict.

Live instances of one node number at most one per sample of the look-ahead
window that feeds them; :class:`TimedState` keeps a value per start time of the
trial, ``(R, N+1)`` per node, which holds every bound at once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from mitlc.errors import CompileError
from mitlc.petri.net import eval_state
from mitlc.spec import ast as A
from mitlc.spec.passes import is_state_formula

__all__ = [
    "FALSE",
    "PENDING",
    "TRUE",
    "TNode",
    "ObligationTree",
    "TimedState",
    "IDLE",
    "OPEN",
    "WAIT",
    "MET",
    "FAILED",
    "needs_obligations",
    "TimedNet",
    "ROOT_PLACES",
    "NODE_PLACES",
    "earliest_witness",
]

FALSE, PENDING, TRUE = 0, 1, 2
"""Three-valued truth, ordered so that ``and`` is min, ``or`` is max and ``not`` is ``2 - v``."""

IDLE, OPEN, WAIT, MET, FAILED = 0, 1, 2, 3, 4
"""Where a sub-net's token lies (``idle`` only below the root; ``met``, ``failed`` only at the root)."""

TEMPORAL = ("F", "G", "U", "R")


@dataclass(frozen=True)
class TNode:
    """One node of an obligation tree.

    ``op`` is ``state`` (a state formula, evaluated on the sample), ``and``,
    ``or`` or a temporal operator ``F``, ``G``, ``U``, ``R`` (``children`` are
    ``(left, right)`` for the binary ones).
    """

    op: str
    children: tuple[int, ...]
    formula: A.Formula
    interval: A.Interval = A.UNBOUNDED

    @property
    def temporal(self) -> bool:
        return self.op in TEMPORAL


def _strip(f: A.Formula) -> A.Formula:
    while isinstance(f, A.Weighted):
        f = f.child
    return f


@dataclass(frozen=True)
class ObligationTree:
    """A formula part in normal form as nodes in post-order (children first, the root last)."""

    nodes: tuple[TNode, ...]

    @property
    def root(self) -> int:
        return len(self.nodes) - 1

    @property
    def temporal(self) -> tuple[int, ...]:
        """Indices of the temporal nodes, the ones with a sub-net."""
        return tuple(i for i, n in enumerate(self.nodes) if n.temporal)

    @property
    def formula(self) -> A.Formula:
        return self.nodes[-1].formula

    @staticmethod
    def build(formula: A.Formula) -> ObligationTree:
        return ObligationTree.build_indexed(formula)[0]

    @staticmethod
    def build_indexed(formula: A.Formula) -> tuple[ObligationTree, dict[int, int]]:
        """The tree of ``formula`` (in normal form; weights are dropped: they do not change truth),
        and the node index of every visited subformula object (by ``id``, weights peeled).

        >>> from mitlc.spec.parse import parse_formula
        >>> t, _ = ObligationTree.build_indexed(parse_formula("F[0,2] G goal"))
        >>> [(n.op, n.children) for n in t.nodes]
        [('state', ()), ('G', (0,)), ('F', (1,))]
        """
        nodes: list[TNode] = []
        index: dict[int, int] = {}

        def visit(f: A.Formula) -> int:
            i = add(f)
            index[id(_strip(f))] = i
            return i

        def add(f: A.Formula) -> int:
            f = _strip(f)
            if is_state_formula(f):
                nodes.append(TNode("state", (), f))
            elif isinstance(f, (A.And, A.Or)):
                kids = (visit(f.left), visit(f.right))
                nodes.append(TNode("and" if isinstance(f, A.And) else "or", kids, f))
            elif isinstance(f, (A.Eventually, A.Globally)):
                kid = visit(f.child)
                nodes.append(TNode("F" if isinstance(f, A.Eventually) else "G", (kid,), f, f.interval))
            elif isinstance(f, (A.Until, A.Release)):
                kids = (visit(f.left), visit(f.right))
                nodes.append(TNode("U" if isinstance(f, A.Until) else "R", kids, f, f.interval))
            else:
                raise CompileError(f"cannot track {type(f).__name__} as an obligation (run normal_form first)")
            return len(nodes) - 1

        visit(formula)
        return ObligationTree(tuple(nodes)), index


def _temporal_nodes(f: A.Formula) -> bool:
    return isinstance(f, (A.Eventually, A.Globally, A.Until, A.Release))


def needs_obligations(f: A.Formula) -> bool:
    """Whether the trial clock and the obligation clocks differ for the temporal part ``f``.

    They differ when an interval other than ``[0, inf)`` sits below another
    temporal operator (it restarts with every obligation) or above one (its
    window must not cut off the nested part's reward once the nested part has
    started). ``f`` is a temporal operator with no temporal ancestor.

    >>> from mitlc.spec.parse import parse_formula
    >>> [needs_obligations(parse_formula(s)) for s in ("F G k", "F[0,2] G k", "G (a -> F[0,1] b)", "G[0,3] a")]
    [False, True, True, False]
    """

    def timed(g: A.Formula) -> bool:
        return _temporal_nodes(g) and not g.interval.is_unbounded  # type: ignore[attr-defined]

    def below(g: A.Formula) -> list[A.Formula]:
        return [n for c in g.children for n in A.walk(c) if _temporal_nodes(n)]

    for node in A.walk(f):
        if not _temporal_nodes(node):
            continue
        nested = below(node)
        if nested and (timed(node) or any(timed(n) for n in nested)):
            return True
    return False


def earliest_witness(f: A.Formula, dt: float) -> float:
    """The earliest sample offset (seconds) at which a trace can satisfy ``f``, ``inf`` if never.

    A lower bound used for the compiler's warning: strong operators need a
    witness at least ``inf I`` after they start; ``G`` and ``R`` need nothing.
    """
    f = _strip(f)
    if is_state_formula(f):
        return 0.0
    if isinstance(f, A.And):
        return max(earliest_witness(f.left, dt), earliest_witness(f.right, dt))
    if isinstance(f, A.Or):
        return min(earliest_witness(f.left, dt), earliest_witness(f.right, dt))
    if isinstance(f, (A.Eventually, A.Until)):
        lo, hi = A.offsets(f.interval, dt)
        if lo > hi:
            return math.inf
        right = f.child if isinstance(f, A.Eventually) else f.right
        return lo * dt + earliest_witness(right, dt)
    return 0.0


@dataclass(frozen=True)
class TimedNet:
    """An obligation tree inside a compiled net: which sub-net shows each temporal node."""

    tree: ObligationTree
    subnets: tuple[tuple[int, int], ...]
    """``(tree node, net sub-net)`` for every temporal node."""

    def local(self, node: int) -> np.ndarray:
        """Engine place code (``IDLE .. FAILED``) -> local place index in the node's sub-net."""
        return ROOT_LOCAL if node == self.tree.root else NODE_LOCAL


ROOT_PLACES = ("open", "wait", "met", "failed")
NODE_PLACES = ("idle", "open", "wait")
ROOT_LOCAL = np.array([-1, 0, 1, 2, 3], dtype=np.int64)
NODE_LOCAL = np.array([0, 1, 2, -1, -1], dtype=np.int64)


# ----------------------------------------------------------------- the engine


def _constant(f: A.Formula, max_atoms: int = 12) -> bool | None:
    """The value of state formula ``f`` if it is the same for every valuation, else None."""
    names = A.atoms(f)
    if len(names) > max_atoms:
        return None
    combos = np.arange(1 << len(names))
    values = eval_state(f, {a: ((combos >> i) & 1).astype(bool) for i, a in enumerate(names)})
    values = np.broadcast_to(values, combos.shape)
    return bool(values[0]) if values.all() or not values.any() else None


def _count(c: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Number of marked positions in ``[lo, hi]`` per run and column (``hi`` per run), 0 if empty.

    Windows that are the same for every run are :class:`_Windows`, computed once.
    """
    L = c.shape[1] - 1
    lo_c = np.broadcast_to(np.clip(lo, 0, L), (c.shape[0], L))
    hi_c = np.broadcast_to(np.clip(hi + 1, 0, L), (c.shape[0], L))
    n = np.take_along_axis(c, hi_c, axis=1) - np.take_along_axis(c, lo_c, axis=1)
    return np.where(hi_c > lo_c, n, 0)


class _Windows:
    """Fixed windows ``[lo[s], hi[s]]`` over positions ``0..L-1``, as prefix-count indices.

    ``count(c)`` is the number of marked positions in each window, for prefix counts
    ``c`` (:meth:`TimedState._prefix`); an empty window counts 0.
    """

    __slots__ = ("lo", "hi", "length")

    def __init__(self, lo: np.ndarray, hi: np.ndarray, L: int) -> None:
        lo_c, hi_c = np.clip(lo, 0, L), np.clip(hi + 1, 0, L)
        empty = hi_c <= lo_c
        self.lo = np.where(empty, 0, lo_c).astype(np.intp)
        self.hi = np.where(empty, 0, hi_c).astype(np.intp)
        self.length = self.hi - self.lo

    def count(self, c: np.ndarray) -> np.ndarray:
        return c[:, self.hi] - c[:, self.lo]


def _first_from(mask: np.ndarray) -> np.ndarray:
    """``out[:, s]`` = the first ``t >= s`` with ``mask[:, t]``, ``L`` if none."""
    L = mask.shape[1]
    idx = np.where(mask, np.arange(L), L)
    return np.minimum.accumulate(idx[:, ::-1], axis=1)[:, ::-1]


class TimedState:
    """The tokens of one obligation tree for ``runs`` runs of ``steps`` steps (samples ``0..steps``)."""

    def __init__(self, tree: ObligationTree, dt: float, runs: int, steps: int) -> None:
        self.tree = tree
        self.dt = float(dt)
        self.R, self.N = int(runs), int(steps)
        L = self.N + 1
        self.L = L
        self.k = -1
        s = np.arange(L)
        self._window: dict[int, tuple[int, float]] = {}
        self._ranges: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._own: dict[int, _Windows] = {}  # each temporal node's window over its children's positions
        for i, n in enumerate(tree.nodes):
            if n.temporal:
                lo, hi = A.offsets(n.interval, self.dt)
                self._window[i] = (lo, hi)
                hi_i = s + min(hi, L) if math.isfinite(hi) else np.full(L, L)
                self._ranges[i] = (s + lo, np.minimum(hi_i, self.N))
                self._own[i] = _Windows(*self._ranges[i], L)
        self.values = [np.full((self.R, L), PENDING, dtype=np.int8) for _ in tree.nodes]
        self._known: set[int] = set()
        for i, n in enumerate(tree.nodes):  # a valid or unsatisfiable state part is known in advance
            if n.op == "state" and (constant := _constant(n.formula)) is not None:
                self.values[i][...] = TRUE if constant else FALSE
                self._known.add(i)
        self.live = [np.zeros((self.R, L), dtype=bool) for _ in tree.nodes]
        self._parent = [-1] * len(tree.nodes)
        for i, n in enumerate(tree.nodes):
            for c in n.children:
                self._parent[c] = i
        # which parent start times need a child's instance at s: s' in [s - hi, s - lo]
        self._needs: dict[int, _Windows] = {}
        for i in range(len(tree.nodes)):
            p = self._parent[i]
            if p < 0 or not tree.nodes[p].temporal:
                continue
            jlo, jhi = self._window[p]
            parent = tree.nodes[p]
            lo, hi = (0, jhi - 1) if parent.op in ("U", "R") and i == parent.children[0] else (jlo, jhi)
            first = s - hi if math.isfinite(hi) else np.zeros(L, dtype=np.int64)
            self._needs[i] = _Windows(np.maximum(first, 0).astype(np.int64), s - lo, L)
        self._buf = np.zeros((self.R, L + 1), dtype=np.int32)

    # -- values
    def observe(self, truth: Mapping[str, np.ndarray]) -> None:
        """Take the next sample (proposition truth ``{atom: (R,) bool}``) and update every value."""
        self.k += 1
        k = self.k
        if k > self.N:
            raise ValueError(f"the trial has {self.N} steps; sample {k} is past its end")
        for i, n in enumerate(self.tree.nodes):
            if n.op == "state":
                if i in self._known:
                    continue
                holds = np.broadcast_to(eval_state(n.formula, truth), (self.R,))
                self.values[i][:, k] = np.where(holds, TRUE, FALSE)
            elif n.op == "and":
                np.minimum(self.values[n.children[0]], self.values[n.children[1]], out=self.values[i])
            elif n.op == "or":
                np.maximum(self.values[n.children[0]], self.values[n.children[1]], out=self.values[i])
            elif n.op in ("F", "G"):
                v = self.values[n.children[0]]
                if n.op == "G":
                    v = TRUE - v
                out = self._eventually(i, v)
                self.values[i][...] = out if n.op == "F" else TRUE - out
            else:
                a, b = (self.values[c] for c in n.children)
                if n.op == "R":
                    a, b = TRUE - a, TRUE - b
                out = self._until(i, a, b)
                self.values[i][...] = out if n.op == "U" else TRUE - out
        self._liveness()

    def _prefix(self, mask: np.ndarray) -> np.ndarray:
        """Prefix counts ``c[:, i] = mask[:, :i].sum()``, ``(R, L+1)``, in the one buffer (read before the next)."""
        np.cumsum(mask, axis=1, out=self._buf[:, 1:])
        return self._buf

    def _eventually(self, i: int, v: np.ndarray) -> np.ndarray:
        w = self._own[i]
        some = w.count(self._prefix(v == TRUE)) > 0
        none = w.count(self._prefix(v == FALSE)) == w.length
        out = np.full(v.shape, PENDING, dtype=np.int8)
        out[none] = FALSE
        out[some] = TRUE
        return out

    def _until(self, i: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        lo, hi = self._ranges[i]
        not_true = _first_from(a != TRUE)  # the left side holds on [s, not_true)
        first_false = _first_from(a == FALSE)
        hi_t = np.minimum(hi, not_true)
        some = _count(self._prefix(b == TRUE), lo, hi_t) > 0
        hi_f = np.minimum(hi, first_false)
        length = np.maximum(hi_f - lo + 1, 0)
        none = _count(self._prefix(b == FALSE), lo, hi_f) == length
        return np.where(some, TRUE, np.where(none, FALSE, PENDING)).astype(np.int8)

    def _liveness(self) -> None:
        L = self.L
        nodes = self.tree.nodes
        root = self.tree.root
        for i in range(len(nodes) - 1, -1, -1):
            if i == root:
                need = np.zeros((self.R, L), dtype=bool)
                need[:, 0] = True
            else:
                p = self._parent[i]
                live_p = self.live[p]
                need = live_p if i not in self._needs else self._needs[i].count(self._prefix(live_p)) > 0
            self.live[i] = need & (self.values[i] == PENDING)

    # -- tokens
    def places(self) -> dict[int, np.ndarray]:
        """Per temporal node, where its sub-net's token lies after the latest sample, ``(R,)``."""
        k, out = self.k, {}
        nxt = k + 1
        for i, n in enumerate(self.tree.nodes):
            if not n.temporal:
                continue
            jlo, jhi = self._window[i]
            live = self.live[i]
            if nxt <= self.N:
                first = max(nxt - jhi, 0) if math.isfinite(jhi) else 0
                last = min(nxt - jlo, nxt)
                opened = live[:, first : last + 1].any(axis=1) if last >= first else np.zeros(self.R, bool)
            else:
                opened = np.zeros(self.R, dtype=bool)
            waiting = live[:, : k + 1].any(axis=1)
            here = np.where(opened, OPEN, np.where(waiting, WAIT, IDLE))
            if i == self.tree.root:
                v = self.values[i][:, 0]
                here = np.where(v == TRUE, MET, np.where(v == FALSE, FAILED, np.where(opened, OPEN, WAIT)))
            out[i] = here.astype(np.int64)
        return out

    def verdict(self) -> np.ndarray:
        """The root's value, ``(R,)``: ``TRUE``, ``FALSE`` or ``PENDING``."""
        return self.values[self.tree.root][:, 0].copy()

    def clocks(self) -> dict[int, np.ndarray]:
        """Per temporal node, the age (seconds) of its oldest live instance, ``nan`` where none."""
        k, out = self.k, {}
        for i in self.tree.temporal:
            live = self.live[i][:, : k + 1]
            oldest = np.argmax(live, axis=1)
            out[i] = np.where(live.any(axis=1), (k - oldest) * self.dt, np.nan)
        return out
