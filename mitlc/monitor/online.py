"""The online monitor: the verdict and robustness of a growing trace, one sample at a time.

:class:`OnlineMonitor` takes the samples ``x_0, x_1, ...`` of ``R`` runs as they come and,
after each, says what :func:`mitlc.monitor.offline.monitor` would say about the prefix
``x_0 .. x_k``: the same verdict and the same robustness, bit for bit (tests/test_online.py
checks every prefix of random formulas and traces). The offline monitor reads the whole
prefix again; this one keeps, per subformula, only what later samples can still change.

How (docs/monitor.md, "Online"):

* A subformula with a finite horizon ``h`` (in samples) has a final value at sample
  ``t`` once ``k >= t + h``. The root of a bounded formula is final after ``h`` samples,
  and costs nothing after that; before, each sample re-evaluates the provisional part,
  at most ``h + 1`` samples long.
* An unbounded ``F``, ``G`` or ``U`` over bounded operands keeps a running aggregate of
  its operands' final values (one more each sample) and combines it with their
  provisional tail: constant work per sample, whatever the trace length.
* An unbounded operator over an unbounded one (``F G kappa``, ``G F kappa``) uses
  monotonicity: ``G`` of anything is non-decreasing in time on a prefix and ``F``
  non-increasing, so an ``F`` or ``G`` over such a signal is its value at one end of the
  window.
* What is left (an unbounded operator over an unbounded non-monotone one, as in
  ``G (a U b)``) is evaluated over the prefix again: exact, but linear in ``k`` per
  sample; :attr:`OnlineMonitor.constant_time` says whether a formula needs it.

>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec("prop up = abs(q) < 0.3\\nformula F[0,1] G up")
>>> mon = OnlineMonitor(spec, dt=0.5)
>>> [bool(mon.update([q]).satisfied[0]) for q in (2.0, 0.1, 0.2, 0.0)]
[False, True, True, True]
>>> round(float(mon.robustness[0]), 6), mon.constant_time
(0.1, True)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.errors import InputError
from mitlc.monitor.kernels import BOOL, REAL, Lattice, until, window
from mitlc.monitor.offline import compile_pred, judged_formula, needed_variables, sample_time, state_columns
from mitlc.plants.base import wrap_angle
from mitlc.spec import ast as A
from mitlc.spec.model import Spec

__all__ = ["OnlineMonitor", "OnlineVerdict"]

_INF = math.inf


@dataclass(frozen=True)
class OnlineVerdict:
    """What the monitor says about the prefix ``x_0 .. x_k`` of each of ``R`` runs."""

    satisfied: np.ndarray
    """``(R,)`` bool: the verdict at time 0 on the prefix."""
    robustness: np.ndarray
    """``(R,)`` float: the robustness at time 0 on the prefix."""


# ----------------------------------------------------------------- the formula, in samples


class _Node:
    """A core operator with sample offsets: const, atom, not, and, or, F, G, U."""

    __slots__ = ("op", "kids", "lo", "hi", "value", "name", "h", "mono")

    def __init__(
        self, op: str, kids: tuple[_Node, ...] = (), lo: int = 0, hi: float = 0.0, value: bool = False, name: str = ""
    ) -> None:
        self.op, self.kids, self.lo, self.hi, self.value, self.name = op, kids, lo, hi, value, name
        # horizon: how many samples past t the value at t reads (inf: to the trace's end)
        if op in ("const", "atom"):
            self.h: float = 0.0
        elif op in ("F", "G", "U"):
            self.h = hi + max(k.h for k in kids)
        else:
            self.h = max(k.h for k in kids)
        # monotone in t on any prefix: +1 non-decreasing, -1 non-increasing, 2 constant, 0 neither
        self.mono = _monotone(self)

    @property
    def bounded(self) -> bool:
        return self.h < _INF


def _monotone(n: _Node) -> int:
    if n.op == "const":
        return 2
    if n.op == "atom" or n.op == "U":
        return 0
    if n.op == "not":
        m = n.kids[0].mono
        return -m if m in (1, -1) else m
    if n.op in ("and", "or"):
        a, b = n.kids[0].mono, n.kids[1].mono
        if a == 2:
            return b
        if b == 2 or a == b:
            return a
        return 0
    if math.isinf(n.hi):  # a window [t + lo, k] shrinks as t grows
        return 1 if n.op == "G" else -1
    m = n.kids[0].mono  # a bounded window of a monotone signal is its value at one end
    return m if m in (1, -1, 2) else 0


class _Builder:
    """Formula to core nodes at a sample time, shared subformulas shared."""

    def __init__(self, dt: float) -> None:
        self.dt = dt
        self.memo: dict[A.Formula, _Node] = {}

    def __call__(self, f: A.Formula) -> _Node:
        node = self.memo.get(f)
        if node is None:
            node = self._build(f)
            self.memo[f] = node
        return node

    def _timed(self, op: str, kids: tuple[_Node, ...], interval: A.Interval) -> _Node:
        lo, hi = A.offsets(interval, self.dt)
        if hi < lo:  # no sample offset in the interval: F and U never hold, G always does
            return _Node("const", value=op == "G")
        return _Node(op, kids, lo, hi)

    def _build(self, f: A.Formula) -> _Node:
        if isinstance(f, A.Const):
            return _Node("const", value=bool(f.value))
        if isinstance(f, A.Atom):
            return _Node("atom", name=f.name)
        if isinstance(f, A.Weighted):
            return self(f.child)
        if isinstance(f, A.Not):
            return _Node("not", (self(f.child),))
        if isinstance(f, A.And):
            return _Node("and", (self(f.left), self(f.right)))
        if isinstance(f, A.Or):
            return _Node("or", (self(f.left), self(f.right)))
        if isinstance(f, A.Implies):
            return _Node("or", (_Node("not", (self(f.left),)), self(f.right)))
        if isinstance(f, A.Iff):
            a, b = self(f.left), self(f.right)
            na, nb = _Node("not", (a,)), _Node("not", (b,))
            return _Node("and", (_Node("or", (na, b)), _Node("or", (a, nb))))
        if isinstance(f, A.Eventually):
            return self._timed("F", (self(f.child),), f.interval)
        if isinstance(f, A.Globally):
            return self._timed("G", (self(f.child),), f.interval)
        if isinstance(f, A.Until):
            return self._timed("U", (self(f.left), self(f.right)), f.interval)
        if isinstance(f, A.Release):  # !(!a U !b), as the offline monitor reads it
            na, nb = _Node("not", (self(f.left),)), _Node("not", (self(f.right),))
            return _Node("not", (self._timed("U", (na, nb), f.interval),))
        if isinstance(f, A.WeakUntil):  # (a U b) | G[0, sup I] a
            upto = A.Interval(0.0, f.interval.hi, True, f.interval.hi_closed)
            left = self(f.left)
            return _Node("or", (self._timed("U", (left, self(f.right)), f.interval), self._timed("G", (left,), upto)))
        raise InputError(f"cannot monitor formula node {type(f).__name__}")  # pragma: no cover - every node has a case


# ----------------------------------------------------------------- evaluation


class _Running:
    """An unbounded ``F`` or ``G`` over a bounded operand, at the samples ``p .. q`` (q may be inf).

    ``acc[t]`` aggregates the operand's final values over ``[t + lo, f]``; each sample
    seals the next ones and the provisional tail ``(f, k]`` is combined on the fly.
    """

    def __init__(self, eng: _Engine, node: _Node, p: int) -> None:
        self.eng, self.node, self.p = eng, node, p
        lat = eng.lat
        self.op = lat.join if node.op == "F" else lat.meet
        self.ident = lat.bottom if node.op == "F" else lat.top
        self.f = p + node.lo - 1  # the operand's last sealed sample
        self.acc = lat.full((eng.R, 0), self.ident)

    def values(self, e: int) -> np.ndarray:
        eng, node, p = self.eng, self.node, self.p
        kid, lo, k = node.kids[0], node.lo, eng.k
        m = e - p + 1
        if self.acc.shape[1] < m:  # the new samples' windows hold no sealed value yet
            grown = eng.lat.full((eng.R, m), self.ident)
            grown[:, : self.acc.shape[1]] = self.acc
            self.acc = grown
        f_new = k - int(kid.h)
        if f_new > self.f:
            first = self.f + 1
            block = eng.vals(kid, first, f_new, fixed=False)
            suffix = self.op.accumulate(block[:, ::-1], axis=1)[:, ::-1]
            t = np.arange(p, p + self.acc.shape[1])
            start = np.maximum(t + lo, first)
            hit = start <= f_new
            if hit.any():
                idx = np.flatnonzero(hit)
                self.acc[:, idx] = self.op(self.acc[:, idx], suffix[:, start[idx] - first])
            self.f = f_new
        out = self.acc[:, :m].copy()
        first = self.f + 1
        if first <= k:
            tail = eng.vals(kid, first, k, fixed=False)
            suffix = self.op.accumulate(tail[:, ::-1], axis=1)[:, ::-1]
            t = np.arange(p, e + 1)
            start = np.maximum(t + lo, first)
            hit = start <= k
            if hit.any():
                idx = np.flatnonzero(hit)
                out[:, idx] = self.op(out[:, idx], suffix[:, start[idx] - first])
        return out


class _RunningUntil:
    """An unbounded ``a U b`` over bounded operands, at the samples ``p .. q``.

    For each ``t``: ``lm[t]``, the meet of ``a`` over ``[t, f]``, and ``best[t]``, the join
    over sealed witnesses ``j in [t + lo, f]`` of ``b(j) & a`` on ``[t, j - 1]``.
    """

    def __init__(self, eng: _Engine, node: _Node, p: int) -> None:
        self.eng, self.node, self.p = eng, node, p
        self.f = p - 1
        self.lm = eng.lat.full((eng.R, 0), eng.lat.top)
        self.best = eng.lat.full((eng.R, 0), eng.lat.bottom)

    def values(self, e: int) -> np.ndarray:
        eng, node, p, lat = self.eng, self.node, self.p, self.eng.lat
        left, right = node.kids
        lo, k = node.lo, eng.k
        m = e - p + 1
        have = self.lm.shape[1]
        if have < m:
            lm, best = lat.full((eng.R, m), lat.top), lat.full((eng.R, m), lat.bottom)
            lm[:, :have], best[:, :have] = self.lm, self.best
            self.lm, self.best = lm, best
        f_new = k - int(max(left.h, right.h))
        if f_new > self.f:
            first = self.f + 1
            a = eng.vals(left, first, f_new, fixed=False)
            b = eng.vals(right, first, f_new, fixed=False)
            n = self.lm.shape[1]
            for i, j in enumerate(range(first, f_new + 1)):
                w = min(j - lo - p + 1, n)  # the t with j in their window: t + lo <= j
                if w > 0:
                    self.best[:, :w] = lat.join(self.best[:, :w], lat.meet(b[:, i : i + 1], self.lm[:, :w]))
                s = min(j - p + 1, n)  # the t whose left side reaches j: t <= j
                if s > 0:
                    self.lm[:, :s] = lat.meet(self.lm[:, :s], a[:, i : i + 1])
            self.f = f_new
        out = self.best[:, :m].copy()
        first = self.f + 1
        if first <= k:
            a = eng.vals(left, first, k, fixed=False)
            b = eng.vals(right, first, k, fixed=False)
            # witness j in the tail: b(j), a over the tail before j, and a over [t, f]
            before = np.concatenate([lat.full((eng.R, 1), lat.top), lat.meet.accumulate(a, axis=1)[:, :-1]], axis=1)
            q = lat.meet(b, before)
            suffix = lat.join.accumulate(q[:, ::-1], axis=1)[:, ::-1]
            sealed_t = min(e, self.f) - p + 1  # t <= f: sealed left sides
            if sealed_t > 0:
                t = np.arange(p, p + sealed_t)
                start = np.maximum(t + lo, first)
                hit = start <= k
                if hit.any():
                    idx = np.flatnonzero(hit)
                    reach = lat.meet(self.lm[:, idx], suffix[:, start[idx] - first])
                    out[:, idx] = lat.join(out[:, idx], reach)
            if e >= first:  # t in the tail: the offline until over the tail itself
                u = until(a, b, lo, _INF, lat)
                out[:, first - p : e - p + 1] = u[:, : e - first + 1]
        return out


class _Engine:
    """Values of core nodes on the current prefix, in one lattice."""

    def __init__(self, lat: Lattice, atoms: dict[str, np.ndarray], R: int) -> None:
        self.lat, self.atoms, self.R = lat, atoms, R
        self.k = -1
        self.final: dict[tuple[int, int, float], np.ndarray] = {}
        self.memo: dict[tuple[int, int, float], np.ndarray] = {}
        self.states: dict[tuple[int, int, float], Any] = {}
        self.growing = False  # set when some part is evaluated over the whole prefix

    def advance(self, k: int) -> None:
        self.k = k
        self.memo.clear()

    def vals(self, g: _Node, p: int, q: float, fixed: bool = True) -> np.ndarray:
        """Values of ``g`` at the samples ``p .. min(q, k)``, ``(R, n)``."""
        k = self.k
        e = int(min(q, k))
        if p > e:
            return self.lat.full((self.R, 0), self.lat.bottom)
        key = (id(g), p, q)
        if fixed:
            out = self.final.get(key)
            if out is not None:
                return out
        out = self.memo.get(key)
        if out is None:
            out = self._compute(g, p, q, e, fixed)
            if fixed and q < k and q + g.h <= k:  # no later sample changes these
                self.final[key] = out
            else:
                self.memo[key] = out
        return out

    def _compute(self, g: _Node, p: int, q: float, e: int, fixed: bool) -> np.ndarray:
        lat, k = self.lat, self.k
        if g.bounded:
            return self.slice(g, p, int(min(e + g.h, k)))[:, : e - p + 1]
        op = g.op
        if op == "not":
            return lat.neg(self.vals(g.kids[0], p, q, fixed))
        if op in ("and", "or"):
            a, b = (self.vals(c, p, q, fixed) for c in g.kids)
            return lat.meet(a, b) if op == "and" else lat.join(a, b)
        lo, hi = g.lo, g.hi
        if op in ("F", "G"):
            agg, ident = (lat.join, lat.bottom) if op == "F" else (lat.meet, lat.top)
            kid = g.kids[0]
            out = lat.full((self.R, e - p + 1), ident)
            live = min(e, k - lo) - p + 1  # samples whose window starts inside the prefix
            if live <= 0:
                return out
            if not math.isinf(hi):  # a bounded window over an unbounded operand
                c = self.vals(kid, p + lo, q + hi, fixed)
                out[:, :live] = window(c, 0, hi - lo, agg, ident)[:, :live]
                return out
            if p == e == k:  # the last sample: its window is the sample itself, or empty
                if lo == 0:
                    out[:, :1] = self.vals(kid, k, k, fixed=False)
                return out
            first_end = (kid.mono == 1) == (op == "G") or kid.mono == 2
            if kid.mono in (1, -1, 2) and not kid.bounded:
                if first_end:  # the aggregate sits at the window's first sample, t + lo
                    out[:, :live] = self.vals(kid, p + lo, q + lo, fixed)[:, :live]
                else:  # at its last, k
                    out[:, :live] = self.vals(kid, k, k, fixed=False)
                return out
            if kid.bounded:
                return self._state(g, p, q, _Running).values(e)
        elif op == "U" and math.isinf(hi):
            if p == e == k:
                out = lat.full((self.R, 1), lat.bottom)
                if lo == 0:
                    out[:, :1] = self.vals(g.kids[1], k, k, fixed=False)
                return out
            if all(c.bounded for c in g.kids):
                return self._state(g, p, q, _RunningUntil).values(e)
        elif op == "U":  # a bounded until over unbounded operands
            a = self.vals(g.kids[0], p, q + hi, fixed)
            b = self.vals(g.kids[1], p, q + hi, fixed)
            return until(a, b, lo, hi, lat)[:, : e - p + 1]
        # an unbounded operator over an unbounded, non-monotone one: the whole prefix again
        self.growing = True
        return self.slice(g, p, k)[:, : e - p + 1]

    def _state(self, g: _Node, p: int, q: float, kind: type) -> Any:
        key = (id(g), p, q)
        st = self.states.get(key)
        if st is None:
            st = self.states[key] = kind(self, g, p)
        return st

    def slice(self, g: _Node, a: int, b: int) -> np.ndarray:
        """``g`` evaluated on the samples ``a .. b`` as a trace of its own (the offline rule)."""
        memo: dict[int, np.ndarray] = {}
        lat, R, L = self.lat, self.R, b - a + 1

        def ev(n: _Node) -> np.ndarray:
            out = memo.get(id(n))
            if out is not None:
                return out
            op = n.op
            if op == "const":
                out = lat.full((R, L), lat.top if n.value else lat.bottom)
            elif op == "atom":
                out = self.atoms[n.name][:, a : b + 1]
            elif op == "not":
                out = lat.neg(ev(n.kids[0]))
            elif op == "and":
                out = lat.meet(ev(n.kids[0]), ev(n.kids[1]))
            elif op == "or":
                out = lat.join(ev(n.kids[0]), ev(n.kids[1]))
            elif op == "F":
                out = window(ev(n.kids[0]), n.lo, n.hi, lat.join, lat.bottom)
            elif op == "G":
                out = window(ev(n.kids[0]), n.lo, n.hi, lat.meet, lat.top)
            else:
                out = until(ev(n.kids[0]), ev(n.kids[1]), n.lo, n.hi, lat)
            memo[id(n)] = out
            return out

        return ev(g)


def _growing(n: _Node, seen: set[int] | None = None) -> bool:
    """Whether some part of ``n`` is evaluated over the whole prefix (see the module text)."""
    seen = set() if seen is None else seen
    if id(n) in seen:
        return False
    seen.add(id(n))
    if n.bounded:
        return False
    if n.op in ("F", "G") and math.isinf(n.hi):
        kid = n.kids[0]
        if not kid.bounded and kid.mono not in (1, -1, 2):
            return True
    if n.op == "U" and math.isinf(n.hi) and not all(c.bounded for c in n.kids):
        return True
    return any(_growing(c, seen) for c in n.kids)


# ----------------------------------------------------------------- the monitor


class OnlineMonitor:
    """Judge ``R`` growing traces by ``formula`` (default: the spec's ``check`` line, else
    its ``formula``), one sample at a time, as the offline monitor judges each prefix.

    ``dt`` is the sample time in seconds. :meth:`update` takes sample ``k`` of every run:
    an array ``(R, n)`` (or ``(n,)`` for one run) with columns in
    :func:`~mitlc.monitor.offline.state_columns` order, or a mapping from state variable
    name to ``(R,)`` values. Periodic state variables are wrapped to ``[-pi, pi)`` first.
    """

    def __init__(self, spec: Spec, dt: float, formula: A.Formula | None = None, runs: int = 1) -> None:
        dt = sample_time(dt)
        if not (isinstance(runs, int | np.integer) and runs >= 1):
            raise InputError(f"runs must be a positive integer, got {runs!r}")
        self.spec, self.dt, self.R = spec, dt, int(runs)
        self.formula = judged_formula(spec, formula)
        self.columns = state_columns(spec)
        self.needed = needed_variables(spec, self.formula)
        self._root = _Builder(dt)(self.formula)
        self._names = sorted(_atom_names(self._root))
        self._preds = [compile_pred(spec.prop(n).pred) for n in self._names]
        plant = spec.plant
        self._periodic = {v.name for v in plant.state if v.periodic} if plant is not None else set()
        self.constant_time = not _growing(self._root)
        """Whether the work per sample stays bounded as the trace grows (module text)."""
        self.reset()

    def reset(self) -> None:
        """Forget every sample: the next :meth:`update` is sample 0."""
        self.k = -1
        self._cap = 0
        self._truth: dict[str, np.ndarray] = {n: np.zeros((self.R, 0), bool) for n in self._names}
        self._rob: dict[str, np.ndarray] = {n: np.zeros((self.R, 0)) for n in self._names}
        self._bool = _Engine(BOOL, self._truth, self.R)
        self._real = _Engine(REAL, self._rob, self.R)
        self.satisfied = np.zeros(self.R, dtype=bool)
        self.robustness = np.zeros(self.R)

    def _sample(self, x: Any) -> dict[str, np.ndarray]:
        env: dict[str, np.ndarray] = {}
        if isinstance(x, Mapping):
            missing = [n for n in self.needed if n not in x]
            if missing:
                raise InputError(f"no values for state variable{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
            for n in self.needed:
                a = np.asarray(x[n], dtype=float).reshape(-1)
                if a.shape != (self.R,):
                    raise InputError(f"state variable '{n}' must have {self.R} value(s), one per run, got {a.shape}")
                env[n] = a
        else:
            arr = np.asarray(x, dtype=float)
            if arr.ndim == 1:
                arr = arr[None, :]
            if arr.shape != (self.R, len(self.columns)):
                raise InputError(
                    f"a sample must have shape ({self.R}, {len(self.columns)}) "
                    f"(runs, {', '.join(self.columns) or 'no columns'}), got {arr.shape}"
                )
            for n in self.needed:
                env[n] = arr[:, self.columns.index(n)]
        for n, a in env.items():
            if not np.isfinite(a).all():
                r = int(np.flatnonzero(~np.isfinite(a))[0])
                raise InputError(f"state variable '{n}' is not finite (run {r}, sample {self.k + 1}: {a[r]})")
            if n in self._periodic:
                env[n] = wrap_angle(a)
        return {n: a[:, None] for n, a in env.items()}

    def update(self, x: Any) -> OnlineVerdict:
        """Add sample ``k + 1`` of every run; the verdict and robustness of the prefix so far."""
        env = self._sample(x)
        k = self.k + 1
        if k >= self._cap:  # grow the atom buffers by doubling: amortised constant
            cap = max(16, 2 * self._cap)
            for n in self._names:
                t, r = np.zeros((self.R, cap), bool), np.zeros((self.R, cap))
                t[:, : self._cap], r[:, : self._cap] = self._truth[n][:, : self._cap], self._rob[n][:, : self._cap]
                self._truth[n], self._rob[n] = t, r
            self._cap = cap
        with np.errstate(all="ignore"):
            for n, pred in zip(self._names, self._preds, strict=True):
                truth, rob = pred(env, (self.R, 1))
                self._truth[n][:, k] = truth[:, 0]
                self._rob[n][:, k] = rob[:, 0]
        self.k = k
        for eng in (self._bool, self._real):
            eng.advance(k)
        self.satisfied = self._bool.vals(self._root, 0, 0)[:, 0].copy()
        self.robustness = self._real.vals(self._root, 0, 0)[:, 0].astype(float)
        return OnlineVerdict(self.satisfied, self.robustness)


def _atom_names(n: _Node, seen: set[int] | None = None) -> set[str]:
    seen = set() if seen is None else seen
    if id(n) in seen:
        return set()
    seen.add(id(n))
    out = {n.name} if n.op == "atom" else set()
    for c in n.kids:
        out |= _atom_names(c, seen)
    return out
