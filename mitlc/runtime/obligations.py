"""Timed obligations at run time: the per-run state of an obligation tree's tokens, stepped per sample.

The compiler (:mod:`mitlc.petri.timed`) turns a formula part with nested intervals into an
:class:`~mitlc.petri.timed.ObligationTree` and shows each temporal node as a sub-net of three
or four places (a :class:`~mitlc.petri.timed.TimedNet`); the semantics, three-valued values and
the places a token lies in are stated there. Here :class:`TimedState` keeps those values for
``R`` runs, one per start time of the trial, and :class:`Obligations` moves the sub-nets' tokens
of every tree of a net for :class:`~mitlc.runtime.NetRuntime`, one sample per call, in order.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from mitlc.petri.net import eval_state
from mitlc.petri.timed import FAILED, FALSE, IDLE, MET, OPEN, PENDING, TRUE, WAIT, ObligationTree, TimedNet
from mitlc.spec import ast as A

__all__ = ["Obligations", "TimedState"]


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


class Obligations:
    """The timed obligation sub-nets of one net, for ``R`` runs of ``steps`` samples of ``dt``.

    :meth:`start` takes the first sample's atom codes, :meth:`observe` each next one; both say
    where every obligation sub-net's token now lies, as ``(sub-net, local place (R,))`` pairs.
    """

    def __init__(self, timed: Sequence[TimedNet], atoms: Sequence[str], dt: float, steps: int) -> None:
        self.timed = tuple(timed)
        self.atoms = tuple(atoms)
        self.dt, self.steps = float(dt), int(steps)
        self.states: list[TimedState] = []
        self._map = [
            [(node, s, tn.local(node)) for node, s in tn.subnets] for tn in self.timed
        ]  # per tree: (node, sub-net, engine code -> local place)

    def start(self, atom_code: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """New obligation state for ``len(atom_code)`` runs, then :meth:`observe` the first sample."""
        n = np.shape(atom_code)[0]
        self.states = [TimedState(tn.tree, self.dt, n, self.steps) for tn in self.timed]
        return self.observe(atom_code)

    def observe(self, atom_code: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """Feed the sample with atom codes ``atom_code`` ``(R,)`` to every tree: ``(sub-net, local place (R,))``."""
        truth = {a: ((atom_code >> i) & 1).astype(bool) for i, a in enumerate(self.atoms)}
        out: list[tuple[int, np.ndarray]] = []
        for state, mapping in zip(self.states, self._map, strict=True):
            state.observe(truth)
            where = state.places()
            out.extend((s, local[where[node]]) for node, s, local in mapping)
        return out

    def clocks(self) -> np.ndarray:
        """Per run, the age of each timed node's oldest live obligation divided by its interval's
        upper end (the trial length when unbounded), 0 where none lives: ``(R, timed nodes)``."""
        cols = []
        for state, tn in zip(self.states, self.timed, strict=True):
            ages = state.clocks()
            for node, _ in tn.subnets:
                iv = tn.tree.nodes[node].interval
                scale = iv.hi if math.isfinite(iv.hi) and iv.hi > 0 else max(state.N * state.dt, state.dt)
                cols.append(np.nan_to_num(ages[node] / scale, nan=0.0))
        if not cols:
            return np.zeros((0, 0))
        return np.stack(cols, axis=1)

    def verdicts(self) -> np.ndarray:
        """Per run, each tree's value so far (``timed.TRUE``, ``FALSE``, ``PENDING``), ``(R, trees)``."""
        return np.stack([s.verdict() for s in self.states], axis=1) if self.states else np.zeros((0, 0))
