"""MITL monitor: Boolean verdicts and robustness of sampled trajectories.

The monitor judges finite, uniformly sampled traces ``x_0 .. x_N`` (sample
``k`` at time ``t_k = k * dt``) by the standard, *relative* MITL semantics: the
interval of a temporal operator evaluated at ``t_k`` is counted from ``t_k``.
Every node type of :mod:`mitlc.spec.ast` has one case in a
:func:`functools.singledispatch` function; an unknown node is a
:class:`~mitlc.errors.CompileError`.

Two answers per trace, computed by the same code over two lattices:

* the **verdict** over booleans (``or``/``and``, false/true), and
* the **robustness** over reals (``max``/``min``, -inf/+inf): for a comparison
  ``a < b`` it is ``b - a`` (``a > b``: ``a - b``; ``a == b``: ``-|a - b|``;
  ``a != b``: ``|a - b|``); a chained comparison takes the min over its links,
  ``and`` min, ``or`` max, ``not`` negation, and the temporal operators take
  min/max over their windows (the space robustness of STL/MITL).

Where the robustness is not 0 its sign is the verdict. At exactly 0 the
verdict is decided by the comparison itself (``q < 0.3`` is false and
``q <= 0.3`` true at ``q == 0.3``), so a robustness of 0 goes with either
verdict.

Finite-trace choices (see ``docs/monitor.md``):

* sample offset ``j`` is in interval ``I`` iff ``j * dt`` is in ``I``, ends open
  or closed as written, with a tolerance of 1e-9 (relative to the bound);
* windows are cut at the end of the trace;
* ``F``, ``U`` are *strong*: they need a witness inside the trace;
* ``G``, ``R`` are *weak*: they hold unless a counter-example is inside the trace;
* ``a W_I b`` is ``(a U_I b) | G[0, sup I] a`` (as in :mod:`mitlc.spec.passes`).

Interval operators use a van Herk/Gil-Werman sliding window and until uses a
blocked backward scan, all vectorised over runs, so the cost grows linearly
with the trace length, not with length x window.

>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec('''
... prop kappa = abs(x) < 0.5
... formula F[0,1] G kappa
... ''')
>>> res = monitor(spec, {"x": np.array([1.0, 0.5, 0.25, 0.125])}, dt=0.5)
>>> res.satisfied, res.robustness
(array([ True]), array([0.25]))
>>> res = monitor(spec, {"x": np.array([1.0, 1.0, 0.5, 0.125])}, dt=0.5)
>>> res.satisfied, res.robustness, res.violation_time, res.failing
(array([False]), array([0.]), array([1.]), ('F[0,1] G kappa',))
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import singledispatch
from typing import Any

import numpy as np

from mitlc.errors import CompileError, InputError, SpecError
from mitlc.monitor.kernels import BOOL, REAL, TIME_TOL, Lattice, offsets, until, window
from mitlc.plants.base import wrap_angle
from mitlc.spec import ast as A
from mitlc.spec import predicates as P
from mitlc.spec.grades import margin
from mitlc.spec.model import Spec

__all__ = [
    "MonitorResult",
    "monitor",
    "signals",
    "offsets",
    "state_columns",
    "needed_variables",
    "judged_formula",
    "mean_robustness",
    "credit_score",
    "window_mean",
    "TIME_TOL",
]


# ----------------------------------------------------------------- result


@dataclass(frozen=True)
class MonitorResult:
    """What :func:`monitor` says about a batch of ``R`` traces."""

    satisfied: np.ndarray
    """``(R,)`` bool: the verdict at time 0."""
    robustness: np.ndarray
    """``(R,)`` float: the robustness at time 0 (``±inf`` when no predicate bounds it)."""
    violation_time: np.ndarray
    """``(R,)`` float: first time (s) at which the verdict became certain-false, nan where satisfied."""
    failing: tuple[str | None, ...]
    """Per run: text of the smallest subformula responsible for the violation, None if satisfied
    (and None for every run when :func:`monitor` was asked for no blame)."""
    mean_robustness: np.ndarray | None = None
    """``(R,)`` float: :func:`mean_robustness` at time 0, when :func:`monitor` was asked for it (``mean=True``)."""


# ----------------------------------------------------------------- predicates


_CMP = P.COMPARISONS


PredFn = Callable[[Mapping[str, np.ndarray], tuple[int, int]], tuple[np.ndarray, np.ndarray]]
"""A compiled predicate: ``(env, shape) -> (truth, robustness)``, both of ``shape``."""


def compile_pred(p: P.Pred) -> PredFn:
    """Truth and robustness of a boolean predicate as one closure over an environment of
    state arrays (the offline monitor calls it once per trace, the online one per sample).

    >>> f = compile_pred(P.Compare((P.Var("x"), P.Num(1.0)), ("<",)))
    >>> f({"x": np.array([[0.5, 3.0]])}, (1, 2))
    (array([[ True, False]]), array([[ 0.5, -2. ]]))
    """
    if isinstance(p, P.Compare):
        ops = []
        for op in p.ops:
            if op not in _CMP:  # pragma: no cover - the grammar only has these
                raise CompileError(f"unknown comparison '{op}'")
            ops.append((_CMP[op], op))

        def column(name: str) -> Callable[[Any], np.ndarray]:
            return lambda e: np.asarray(e[name], dtype=float)

        reads = [P.compile_numpy(o, column) for o in p.operands]

        def compare(env: Mapping[str, np.ndarray], shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
            values = [np.broadcast_to(np.asarray(f(env), dtype=float), shape) for f in reads]
            truth = np.ones(shape, dtype=bool)
            rob = np.full(shape, np.inf)
            for (cmp, op), a, b in zip(ops, values, values[1:], strict=False):
                truth = truth & cmp(a, b)
                d = margin(op, a, b)
                rob = np.minimum(rob, np.where(np.isnan(d), 0.0, d))
            return truth, rob

        return compare
    if isinstance(p, (P.PAnd, P.POr)):
        fl, fr = compile_pred(p.left), compile_pred(p.right)
        both = isinstance(p, P.PAnd)

        def junction(env: Mapping[str, np.ndarray], shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
            (ta, ra), (tb, rb) = fl(env, shape), fr(env, shape)
            return (ta & tb, np.minimum(ra, rb)) if both else (ta | tb, np.maximum(ra, rb))

        return junction
    if isinstance(p, P.PNot):
        fa = compile_pred(p.arg)

        def negation(env: Mapping[str, np.ndarray], shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
            t, r = fa(env, shape)
            return ~t, -r

        return negation
    if P.is_boolean(p):  # pragma: no cover - every boolean node has a case
        raise CompileError(f"cannot monitor predicate node {type(p).__name__}")
    raise CompileError(f"'{p}' is a number, not a condition")


# ----------------------------------------------------------------- evaluation


class _Eval:
    """Signals of every subformula over one batch, computed once and cached."""

    def __init__(self, spec: Spec, env: dict[str, np.ndarray], dt: float, R: int, L: int) -> None:
        self.spec, self.env, self.dt, self.R, self.L = spec, env, dt, R, L
        self.N = L - 1
        self._atoms: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._cache: dict[tuple[str, A.Formula], np.ndarray] = {}

    def atom(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        if name not in self._atoms:
            with np.errstate(all="ignore"):
                self._atoms[name] = compile_pred(self.spec.prop(name).pred)(self.env, (self.R, self.L))
        return self._atoms[name]

    def sig(self, f: A.Formula, lat: Lattice) -> np.ndarray:
        out = self._cache.get((lat.name, f))
        if out is None:
            out = self._fill(f, lat.name, lambda node: _signal(node, self, lat))
        return out

    def settle(self, f: A.Formula) -> np.ndarray:
        out = self._cache.get(("settle", f))
        if out is None:
            out = self._fill(f, "settle", lambda node: _settle(node, self))
        return out

    def _fill(self, f: A.Formula, kind: str, compute: Callable[[A.Formula], np.ndarray]) -> np.ndarray:
        """``f``'s value of ``kind``, its subformulas' first (children before parents, from an
        explicit stack): each node's case then finds its operands cached, so the Python stack
        stays shallow however deep the formula is (the parser allows 256 levels)."""
        stack: list[tuple[A.Formula, bool]] = [(f, False)]
        while stack:
            node, ready = stack.pop()
            key = (kind, node)
            if key in self._cache:
                continue
            if ready:
                self._cache[key] = compute(node)
            else:
                stack.append((node, True))
                stack.extend((c, False) for c in node.children)
        return self._cache[(kind, f)]

    def offsets(self, interval: A.Interval) -> tuple[int, float]:
        return offsets(interval, self.dt)


@singledispatch
def _signal(f: A.Formula, ev: _Eval, lat: Lattice) -> np.ndarray:
    """The ``(R, N+1)`` signal of ``f`` over ``lat`` (truth or robustness)."""
    raise CompileError(f"cannot monitor formula node {type(f).__name__}")


@_signal.register
def _(f: A.Const, ev: _Eval, lat: Lattice) -> np.ndarray:
    return lat.full((ev.R, ev.L), lat.top if f.value else lat.bottom)


@_signal.register
def _(f: A.Atom, ev: _Eval, lat: Lattice) -> np.ndarray:
    truth, rob = ev.atom(f.name)
    return truth if lat is BOOL else rob


@_signal.register
def _(f: A.Not, ev: _Eval, lat: Lattice) -> np.ndarray:
    return lat.neg(ev.sig(f.child, lat))


@_signal.register
def _(f: A.Weighted, ev: _Eval, lat: Lattice) -> np.ndarray:
    return ev.sig(f.child, lat)


@_signal.register
def _(f: A.And, ev: _Eval, lat: Lattice) -> np.ndarray:
    return lat.meet(ev.sig(f.left, lat), ev.sig(f.right, lat))


@_signal.register
def _(f: A.Or, ev: _Eval, lat: Lattice) -> np.ndarray:
    return lat.join(ev.sig(f.left, lat), ev.sig(f.right, lat))


@_signal.register
def _(f: A.Implies, ev: _Eval, lat: Lattice) -> np.ndarray:
    return lat.join(lat.neg(ev.sig(f.left, lat)), ev.sig(f.right, lat))


@_signal.register
def _(f: A.Iff, ev: _Eval, lat: Lattice) -> np.ndarray:
    a, b = ev.sig(f.left, lat), ev.sig(f.right, lat)
    return lat.meet(lat.join(lat.neg(a), b), lat.join(a, lat.neg(b)))


@_signal.register
def _(f: A.Eventually, ev: _Eval, lat: Lattice) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    return window(ev.sig(f.child, lat), lo, hi, lat.join, lat.bottom)


@_signal.register
def _(f: A.Globally, ev: _Eval, lat: Lattice) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    return window(ev.sig(f.child, lat), lo, hi, lat.meet, lat.top)


@_signal.register
def _(f: A.Until, ev: _Eval, lat: Lattice) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    return until(ev.sig(f.left, lat), ev.sig(f.right, lat), lo, hi, lat)


@_signal.register
def _(f: A.Release, ev: _Eval, lat: Lattice) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    a, b = lat.neg(ev.sig(f.left, lat)), lat.neg(ev.sig(f.right, lat))
    return lat.neg(until(a, b, lo, hi, lat))


def _upto(interval: A.Interval) -> A.Interval:
    """``[0, sup I]`` with ``I``'s upper end: the ``G`` part of a weak until."""
    return A.Interval(0.0, interval.hi, True, interval.hi_closed)


@_signal.register
def _(f: A.WeakUntil, ev: _Eval, lat: Lattice) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    a, b = ev.sig(f.left, lat), ev.sig(f.right, lat)
    glo, ghi = ev.offsets(_upto(f.interval))
    return lat.join(until(a, b, lo, hi, lat), window(a, glo, ghi, lat.meet, lat.top))


# ----------------------------------------------------------------- explanations
#
# The settle signal of a node: S[r, k] is a sample from which the node's value
# at sample k (true or false) can no longer change, whatever the later samples
# of the same trace are. It is built compositionally, like the robustness (so
# for parts that depend on each other, as in `F a & G !a`, it may be later than
# the earliest such sample), with
# values and windows of sample indices: a G is refuted by its earliest settled
# counter-example, an F by the last settled sample of its window, an & by its
# earliest refuted side, an | only when both sides are refuted, an until by
# either its left side failing or its window passing without a witness. The
# violation time of a run is S[r, 0] * dt.
#
# `_blame` descends from a false formula to the smallest subformula responsible.


def _settled(x: np.ndarray, ev: _Eval) -> np.ndarray:
    """An operator whose window holds no sample of the trace (it starts after
    the end, or no sample offset lies in the interval) is settled at once: its
    value follows from the length of the trace alone."""
    return np.where(np.isinf(x), np.arange(ev.L, dtype=float), x)


_INF = np.inf


@singledispatch
def _settle(f: A.Formula, ev: _Eval) -> np.ndarray:
    """``(R, N+1)`` float array of sample indices: when ``f``'s value at each sample settles."""
    raise CompileError(f"cannot monitor formula node {type(f).__name__}")


@_settle.register
def _(f: A.Const, ev: _Eval) -> np.ndarray:
    return np.broadcast_to(np.arange(ev.L, dtype=float), (ev.R, ev.L))


_settle.register(A.Atom, _settle.dispatch(A.Const))


@_settle.register
def _(f: A.Not, ev: _Eval) -> np.ndarray:
    return ev.settle(f.child)


@_settle.register
def _(f: A.Weighted, ev: _Eval) -> np.ndarray:
    return ev.settle(f.child)


def _junction(value: np.ndarray, decisive: bool, sides: tuple[A.Formula, ...], ev: _Eval) -> np.ndarray:
    """An & (decisive value False) or an | (True): settled by its earliest
    decisive side when it has that value, else when both sides are settled."""
    s = [ev.settle(x) for x in sides]
    v = [ev.sig(x, BOOL) for x in sides]
    earliest = np.minimum(*(np.where(vi == decisive, si, _INF) for vi, si in zip(v, s, strict=True)))
    return np.where(value == decisive, earliest, np.maximum(*s))


@_settle.register
def _(f: A.And, ev: _Eval) -> np.ndarray:
    return _junction(ev.sig(f, BOOL), False, (f.left, f.right), ev)


@_settle.register
def _(f: A.Or, ev: _Eval) -> np.ndarray:
    return _junction(ev.sig(f, BOOL), True, (f.left, f.right), ev)


@_settle.register
def _(f: A.Implies, ev: _Eval) -> np.ndarray:
    return ev.settle(A.Or(A.Not(f.left), f.right))


@_settle.register
def _(f: A.Iff, ev: _Eval) -> np.ndarray:
    return np.maximum(ev.settle(f.left), ev.settle(f.right))


def _settle_window(f: A.Eventually | A.Globally, decisive: bool, ev: _Eval) -> np.ndarray:
    """F (decisive child value True) or G (False): settled by the earliest
    decisive sample of the window, else when every sample of it is settled."""
    lo, hi = ev.offsets(f.interval)
    s, v = ev.settle(f.child), ev.sig(f.child, BOOL)
    hit = window(np.where(v == decisive, s, _INF), lo, hi, np.minimum, _INF)
    every = window(s, lo, hi, np.maximum, -_INF)
    out = np.where(ev.sig(f, BOOL) == decisive, hit, every)
    return _settled(out, ev)


@_settle.register
def _(f: A.Eventually, ev: _Eval) -> np.ndarray:
    return _settle_window(f, True, ev)


@_settle.register
def _(f: A.Globally, ev: _Eval) -> np.ndarray:
    return _settle_window(f, False, ev)


@_settle.register
def _(f: A.Until, ev: _Eval) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    sl, sr = ev.settle(f.left), ev.settle(f.right)
    vl, vr = ev.sig(f.left, BOOL), ev.sig(f.right, BOOL)
    # true: the earliest witness j with right settled true at k+j and left settled true before
    true_at = -until(-np.where(vl, sl, _INF), -np.where(vr, sr, _INF), lo, hi, REAL)
    # false: every j of the window is refuted, by right settled false at k+j or left before it
    false_at = until(np.where(vl, _INF, sl), np.where(vr, _INF, sr), lo, hi, REAL)
    return _settled(np.where(ev.sig(f, BOOL), true_at, false_at), ev)


@_settle.register
def _(f: A.Release, ev: _Eval) -> np.ndarray:
    return ev.settle(A.Until(A.Not(f.left), A.Not(f.right), f.interval))


@_settle.register
def _(f: A.WeakUntil, ev: _Eval) -> np.ndarray:
    return ev.settle(A.Or(A.Until(f.left, f.right, f.interval), A.Globally(f.left, _upto(f.interval))))


def _first(row: np.ndarray, a: int, b: int, value: bool) -> int | None:
    """First index in ``[a, b]`` where ``row`` equals ``value``, else None."""
    b = min(b, len(row) - 1)
    if a > b:
        return None
    seg = row[a : b + 1] == value
    i = int(np.argmax(seg))
    return a + i if seg[i] else None


def _span(ev: _Eval, interval: A.Interval, k: int) -> tuple[int, int]:
    """First and last sample of the window at ``k`` (first > last if it is empty)."""
    lo, hi = ev.offsets(interval)
    if hi < lo:
        return k + lo, k + lo - 1
    return k + lo, int(min(k + hi, ev.N))


_Blame = A.Formula | tuple[A.Formula, int]
"""A step of :func:`_blame`: the responsible subformula, or where to look next (a part false at a sample)."""


def _blame_root(f: A.Formula, ev: _Eval, r: int, k: int) -> A.Formula:
    """For ``f`` false at sample ``k`` of run ``r``: the smallest subformula responsible, found by
    descending one :func:`_blame` step at a time (a loop, not a recursion: any depth)."""
    while True:
        step = _blame(f, ev, r, k)
        if isinstance(step, A.Formula):
            return step
        f, k = step


@singledispatch
def _blame(f: A.Formula, ev: _Eval, r: int, k: int) -> _Blame:
    """One step down from ``f``, false at sample ``k`` of run ``r``: ``f`` itself when it is the
    smallest part responsible, else ``(part, sample)``, a part false there to look into."""
    raise CompileError(f"cannot monitor formula node {type(f).__name__}")


def _self(f: A.Formula, ev: _Eval, r: int, k: int) -> _Blame:
    return f


# Nodes that are themselves the smallest responsible part when they fail: an
# atom, a constant, a negation, an | (both sides failed), an <->, an F (no
# witness in its window).
for _node_type in (A.Const, A.Atom, A.Not, A.Or, A.Iff, A.Eventually):
    _blame.register(_node_type, _self)
del _node_type


@_blame.register
def _(f: A.Weighted, ev: _Eval, r: int, k: int) -> _Blame:
    return f.child, k


@_blame.register
def _(f: A.And, ev: _Eval, r: int, k: int) -> _Blame:
    failed = [s for s in (f.left, f.right) if not ev.sig(s, BOOL)[r, k]]
    side = min(failed, key=lambda s: ev.settle(s)[r, k])
    return side, k


@_blame.register
def _(f: A.Implies, ev: _Eval, r: int, k: int) -> _Blame:
    return f.right, k


@_blame.register
def _(f: A.Globally, ev: _Eval, r: int, k: int) -> _Blame:
    first, last = _span(ev, f.interval, k)
    failed = ~ev.sig(f.child, BOOL)[r, first : last + 1]
    when = np.where(failed, ev.settle(f.child)[r, first : last + 1], _INF)
    return f.child, first + int(np.argmin(when))


@_blame.register
def _(f: A.Until, ev: _Eval, r: int, k: int) -> _Blame:
    first, last = _span(ev, f.interval, k)
    stop = _first(ev.sig(f.left, BOOL)[r], k, ev.N, False)
    if first <= last and stop is not None and stop < last:
        return f.left, stop  # left failed before right came
    return f  # the window passed without a witness


@_blame.register
def _(f: A.Release, ev: _Eval, r: int, k: int) -> _Blame:
    first, last = _span(ev, f.interval, k)
    stop = _first(ev.sig(f.left, BOOL)[r], k, ev.N, True)
    end = last if stop is None else min(last, stop)
    witness = _first(ev.sig(f.right, BOOL)[r], first, end, False)
    if witness is None:  # pragma: no cover - f is false, so !left U !right has a witness
        return f
    return f.right, witness


@_blame.register
def _(f: A.WeakUntil, ev: _Eval, r: int, k: int) -> _Blame:
    _, last = _span(ev, _upto(f.interval), k)
    stop = _first(ev.sig(f.left, BOOL)[r], k, last, False)
    if stop is None:  # pragma: no cover - f is false, so G[0,sup I] left fails
        return f
    return f.left, stop


# ----------------------------------------------------------------- inputs


def state_columns(spec: Spec) -> tuple[str, ...]:
    """Column order of a states array: the plant's state variables, or without a
    plant the sorted names of the variables the propositions use.

    >>> from mitlc.spec.parse import parse_spec
    >>> state_columns(parse_spec("prop a = y < 1 and x > 0\\nformula F a"))
    ('x', 'y')
    """
    plant = spec.plant
    if plant is not None:
        return plant.state_names
    return tuple(sorted({v.name for p in spec.props for v in P.variables(p.pred)}))


def needed_variables(spec: Spec, f: A.Formula) -> tuple[str, ...]:
    """State variables the propositions of ``f`` read; a :class:`SpecError` for an undefined proposition.

    >>> from mitlc.spec.parse import parse_spec, parse_formula
    >>> spec = parse_spec("prop a = y < 1\\nprop b = x > 0\\nformula F a")
    >>> needed_variables(spec, parse_formula("b U a"))
    ('x', 'y')
    """
    names: dict[str, None] = {}
    defined = {p.name for p in spec.props}
    for node in A.walk(f):
        if isinstance(node, A.Atom):
            if node.name not in defined:
                pos = node.pos
                hint = f"defined: {', '.join(sorted(defined))}" if defined else "the spec defines no proposition"
                raise SpecError(
                    f"undefined proposition '{node.name}'",
                    line=pos.line if pos else None,
                    column=pos.column if pos else None,
                    hint=hint,
                )
            for v in P.variables(spec.prop(node.name).pred):
                names.setdefault(v.name)
    return tuple(names)


def _as_batch(a: Any, what: str) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2:
        raise InputError(f"{what} must have shape (R, N+1) or (N+1,), got {arr.shape}")
    return arr


def _environment(spec: Spec, states: Any, needed: tuple[str, ...]) -> tuple[dict[str, np.ndarray], int, int]:
    env: dict[str, np.ndarray] = {}
    if isinstance(states, Mapping):
        missing = [n for n in needed if n not in states]
        if missing:
            raise InputError(
                f"no values for state variable{'s' if len(missing) > 1 else ''} {', '.join(missing)}",
                hint=f"given: {', '.join(map(str, states)) or 'nothing'}",
            )
        for n in needed:
            env[n] = _as_batch(states[n], f"state variable '{n}'")
        shapes = {a.shape for a in env.values()}
        if len(shapes) > 1:
            raise InputError(f"state variables have different shapes: {sorted(shapes)}")
        shape = shapes.pop() if shapes else _shape_of_mapping(states)
    else:
        arr = np.asarray(states, dtype=float)
        if arr.ndim == 2:
            arr = arr[None]
        if arr.ndim != 3:
            raise InputError(f"states must have shape (R, N+1, n) or (N+1, n), got {arr.shape}")
        cols = state_columns(spec)
        if arr.shape[2] != len(cols):
            raise InputError(
                f"states have {arr.shape[2]} column{'s' if arr.shape[2] != 1 else ''}, "
                f"expected {len(cols)} ({', '.join(cols) or 'none'})"
            )
        for n in needed:
            env[n] = arr[:, :, cols.index(n)]
        shape = arr.shape[:2]
    R, L = shape
    if L < 1:
        raise InputError("a trace needs at least one sample")
    for n, a in env.items():
        if not np.isfinite(a).all():
            r, k = np.argwhere(~np.isfinite(a))[0]
            raise InputError(f"state variable '{n}' is not finite (run {r}, sample {k}: {a[r, k]})")
    plant = spec.plant
    if plant is not None:
        for v in plant.state:
            if v.periodic and v.name in env:
                env[v.name] = wrap_angle(env[v.name])
    return env, int(R), int(L)


def _shape_of_mapping(states: Mapping[str, Any]) -> tuple[int, int]:
    for n, a in states.items():
        try:
            return _as_batch(a, f"state variable '{n}'").shape
        except (TypeError, ValueError):
            continue
    raise InputError("no state values given: cannot tell the trace length")


def judged_formula(spec: Spec, formula: A.Formula | None = None) -> A.Formula:
    """What a trace is judged by: ``formula`` if given, else the spec's ``check`` line, else its
    ``formula``; a :class:`SpecError` when there is none (a spec of ``require`` lines only)."""
    f = spec.monitor_formula if formula is None else formula
    if f is None:
        raise SpecError(
            "the spec has no 'formula' nor 'check' line to judge a trace by; pass a formula", file=spec.path
        )
    return f


def sample_time(dt: Any) -> float:
    """``dt`` as a positive finite float, else an :class:`InputError` (both monitors check it so)."""
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise InputError(f"sample time must be a number, got {dt!r}") from None
    if not (math.isfinite(dt) and dt > 0):
        raise InputError(f"sample time must be positive and finite, got {dt}")
    return dt


def _prepare(spec: Spec, states: Any, dt: float, formula: A.Formula | None) -> tuple[_Eval, A.Formula]:
    dt = sample_time(dt)
    f = judged_formula(spec, formula)
    needed = needed_variables(spec, f)
    env, R, L = _environment(spec, states, needed)
    return _Eval(spec, env, dt, R, L), f


# ----------------------------------------------------------------- averaged robustness
#
# The robustness of G is its window's worst sample: a trace that holds a condition for all but one
# instant scores as low as one that never holds it. A search for a controller needs to tell those
# apart (a swing-up that reaches the top and falls back against one that never leaves the bottom),
# so the averaged robustness takes G's window *mean* instead (the window cut at the trace's end, as
# the monitor's windows are) and every other operator as the robustness does. It is a score, not a
# verdict: its sign need not agree with satisfaction. (Averaged temporal operators for
# falsification: Akazaki and Hasuo, "Time robustness in MTL and expressivity in hybrid system
# falsification", CAV 2015.)

MEAN_BOUND = 1e9
"""Robustness beyond this (an unbounded predicate's or a constant's ``±inf``) counts as this in a mean."""


def window_mean(x: np.ndarray, lo: int, hi: float) -> np.ndarray:
    """``y[:, k] = mean(x[:, k+lo .. min(k+hi, N)])``, ``+inf`` where the window is empty (G's identity),
    values clipped to ``±MEAN_BOUND`` first.

    >>> window_mean(np.array([[3.0, 1.0, 4.0, 1.0]]), 1, 2)
    array([[2.5, 2.5, 1. , inf]])
    """
    R, L = x.shape
    out = np.full((R, L), np.inf)
    first = np.arange(L) + lo
    last = np.minimum(np.arange(L) + min(hi, L), L - 1)
    ok = (first <= L - 1) & (first <= last)
    if not ok.any():
        return out
    c = np.zeros((R, L + 1))
    np.cumsum(np.clip(x, -MEAN_BOUND, MEAN_BOUND), axis=1, out=c[:, 1:])
    a, b = first[ok], last[ok]
    out[:, ok] = (c[:, b + 1] - c[:, a]) / (b - a + 1)
    return out


def _robustness_shaped(
    kind: str, globally: Callable[[np.ndarray, int, float], np.ndarray]
) -> tuple[Any, Callable[[A.Formula, _Eval], np.ndarray]]:
    """``(node, sig)`` of a score shaped as the robustness: ``node(f, ev)`` the ``(R, N+1)`` signal of ``f``
    (a ``singledispatch`` function with every operator registered but the implication and the
    equivalence, which each score registers itself), ``sig(f, ev)`` it cached under ``kind``. Every
    operator is the robustness's but ``G``'s window (and ``W``'s ``G`` part): ``globally(x, lo, hi)``."""

    @singledispatch
    def node(f: A.Formula, ev: _Eval) -> np.ndarray:
        raise CompileError(f"cannot monitor formula node {type(f).__name__}")

    def sig(f: A.Formula, ev: _Eval) -> np.ndarray:
        out = ev._cache.get((kind, f))
        if out is None:
            out = ev._fill(f, kind, lambda n: node(n, ev))
        return out

    @node.register
    def _(f: A.Const, ev: _Eval) -> np.ndarray:
        return REAL.full((ev.R, ev.L), np.inf if f.value else -np.inf)

    @node.register
    def _(f: A.Atom, ev: _Eval) -> np.ndarray:
        return ev.atom(f.name)[1].astype(float)

    @node.register
    def _(f: A.Not, ev: _Eval) -> np.ndarray:
        return -sig(f.child, ev)

    @node.register
    def _(f: A.Weighted, ev: _Eval) -> np.ndarray:
        return sig(f.child, ev)

    @node.register
    def _(f: A.And, ev: _Eval) -> np.ndarray:
        return np.minimum(sig(f.left, ev), sig(f.right, ev))

    @node.register
    def _(f: A.Or, ev: _Eval) -> np.ndarray:
        return np.maximum(sig(f.left, ev), sig(f.right, ev))

    @node.register
    def _(f: A.Eventually, ev: _Eval) -> np.ndarray:
        lo, hi = ev.offsets(f.interval)
        return window(sig(f.child, ev), lo, hi, np.maximum, -np.inf)

    @node.register
    def _(f: A.Globally, ev: _Eval) -> np.ndarray:
        lo, hi = ev.offsets(f.interval)
        return globally(sig(f.child, ev), lo, hi)

    @node.register
    def _(f: A.Until, ev: _Eval) -> np.ndarray:
        lo, hi = ev.offsets(f.interval)
        return until(sig(f.left, ev), sig(f.right, ev), lo, hi, REAL)

    @node.register
    def _(f: A.Release, ev: _Eval) -> np.ndarray:
        lo, hi = ev.offsets(f.interval)
        return -until(-sig(f.left, ev), -sig(f.right, ev), lo, hi, REAL)

    @node.register
    def _(f: A.WeakUntil, ev: _Eval) -> np.ndarray:
        lo, hi = ev.offsets(f.interval)
        a, b = sig(f.left, ev), sig(f.right, ev)
        glo, ghi = ev.offsets(_upto(f.interval))
        return np.maximum(until(a, b, lo, hi, REAL), globally(a, glo, ghi))

    return node, sig


_mean, _msig = _robustness_shaped("mean", window_mean)
"""The averaged robustness signal of a formula (``_msig``: cached): G's window mean."""


@_mean.register
def _(f: A.Implies, ev: _Eval) -> np.ndarray:
    return np.maximum(-_msig(f.left, ev), _msig(f.right, ev))


@_mean.register
def _(f: A.Iff, ev: _Eval) -> np.ndarray:
    a, b = _msig(f.left, ev), _msig(f.right, ev)
    return np.minimum(np.maximum(-a, b), np.maximum(a, -b))


def mean_robustness(spec: Spec, states: Any, dt: float, formula: A.Formula | None = None) -> np.ndarray:
    """The averaged robustness at time 0 of each trace ``(R,)`` (the section above): the robustness
    with every ``G``'s minimum over its window replaced by the window's mean (``W``'s ``G`` part too).
    ``states``, ``dt`` and ``formula`` as :func:`monitor`'s.

    >>> from mitlc.spec.parse import parse_spec
    >>> spec = parse_spec("prop up = abs(q) < 0.5\\nformula G[0,1.5] up")
    >>> mean_robustness(spec, np.array([[0.0], [0.0], [0.0], [1.5]]), dt=0.5)
    array([0.125])
    """
    ev, f = _prepare(spec, states, dt, formula)
    return _msig(f, ev)[:, 0].astype(float)


# ----------------------------------------------------------------- API


def monitor(
    spec: Spec, states: Any, dt: float, formula: A.Formula | None = None, blame: bool = True, mean: bool = False
) -> MonitorResult:
    """Judge a batch of sampled traces by ``formula`` (default ``spec.monitor_formula``).

    ``states`` is an array ``(R, N+1, n)`` (or one trace ``(N+1, n)``) with
    columns in :func:`state_columns` order, or a mapping from state variable
    name to ``(R, N+1)`` (or ``(N+1,)``) arrays. Sample ``k`` is at ``k * dt``
    seconds. Periodic state variables of the spec's plant are wrapped to
    ``[-pi, pi)`` first. ``blame=False`` leaves ``failing`` None for every run: naming the
    failing part walks the formula once per violated run in Python (a sixth of the judging of a
    cart-pole search's first candidates, ``bench/bench_search.py``); a policy search needs only
    the verdict, the robustness and the violation time (the same numbers either way). ``mean=True``
    adds the averaged robustness (:func:`mean_robustness`, the policy search's score of a violation).

    >>> from mitlc.spec.parse import parse_spec
    >>> spec = parse_spec("prop up = abs(q) < 0.3\\nformula G[0,1] !up")
    >>> res = monitor(spec, np.array([[2.0], [1.0], [0.25], [0.0]]), dt=0.5)
    >>> res.satisfied, res.violation_time, res.failing
    (array([False]), array([1.]), ('!up',))
    """
    ev, f = _prepare(spec, states, dt, formula)
    truth = ev.sig(f, BOOL)
    rob = ev.sig(f, REAL)
    satisfied = truth[:, 0].copy()
    robustness = rob[:, 0].astype(float)
    violation = np.full(ev.R, np.nan)
    failing: list[str | None] = [None] * ev.R
    if not satisfied.all():
        violation = np.where(satisfied, np.nan, ev.settle(f)[:, 0] * ev.dt)
    texts: dict[int, str] = {}  # a part's text by its identity: a few parts blamed over many runs
    for r in np.flatnonzero(~satisfied) if blame else ():
        part = _blame_root(f, ev, int(r), 0)
        if id(part) not in texts:
            texts[id(part)] = str(part)
        failing[r] = texts[id(part)]
    averaged = _msig(f, ev)[:, 0].astype(float) if mean else None
    return MonitorResult(satisfied, robustness, violation, tuple(failing), averaged)


def verdict(spec: Spec, states: Any, dt: float, formula: A.Formula | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`monitor`'s ``satisfied`` and ``robustness`` ``(R,)`` alone (no blame, no violation time):
    what the reward designs of :mod:`mitlc.monitor.rewards` pay from."""
    ev, f = _prepare(spec, states, dt, formula)
    return ev.sig(f, BOOL)[:, 0].copy(), ev.sig(f, REAL)[:, 0].astype(float)


def signals(spec: Spec, states: Any, dt: float, formula: A.Formula | None = None) -> dict[str, np.ndarray]:
    """Robustness signal ``(R, N+1)`` of every subformula, keyed by its text.

    >>> from mitlc.spec.parse import parse_spec
    >>> spec = parse_spec("prop a = x > 0\\nformula F[0,1] a")
    >>> s = signals(spec, {"x": np.array([-1.0, 2.0, -3.0])}, dt=1.0)
    >>> s["a"], s["F[0,1] a"]
    (array([[-1.,  2., -3.]]), array([[ 2.,  2., -3.]]))
    """
    ev, f = _prepare(spec, states, dt, formula)
    return {str(node): ev.sig(node, REAL) for node in A.walk(f)}


# ----------------------------------------------------------------- credit and the non-vacuous robustness
#
# Two more scores for a policy search (mitlc.learn.search, ``score = credit``), where the robustness and its
# average fail a bounded response ``G (a -> F[0,d] b)``: a search paid by the robustness hugs a boundary
# (skims ``a``'s region from outside, or grazes it and never goes on to ``b``: ``max(-rho(a), rho(F b))`` is
# ``a``'s small depth there, whatever the trace does after), and paid by the violation time it postpones
# the trigger ``a``, which postpones the deadline.
#
# * The **credit** of a trace is in [0, 1]: an atom's truth (0 or 1), ``!`` one less the child's, ``&`` the
#   mean of its sides' (each conjunct met counts), ``|`` the larger, ``F`` the largest over its window (0 where
#   it is empty: strong), ``G`` the window's mean (1 where it is empty: weak), ``U`` the monitor's max-min
#   until over credits, and ``a -> b`` ``b``'s credit where ``a`` holds and one half where it does not (a
#   vacuous instance earns half: no more than an instance whose response was met, no less than one missed).
# * The **non-vacuous robustness** is the robustness with ``a -> b`` scored by ``b``'s robustness where ``a``
#   holds (how near the response came: a trace that reaches ``a`` and heads for ``b`` gains as it nears it)
#   and as the robustness does elsewhere.
#
# Neither is a verdict (the search orders satisfied traces above all others by the verdict itself).

VACUOUS_CREDIT = 0.5
"""The credit of an implication's instance whose antecedent does not hold."""


@singledispatch
def _credit(f: A.Formula, ev: _Eval) -> np.ndarray:
    """The ``(R, N+1)`` credit signal of ``f`` (its operands' from the cache)."""
    raise CompileError(f"cannot monitor formula node {type(f).__name__}")


def _csig(f: A.Formula, ev: _Eval) -> np.ndarray:
    out = ev._cache.get(("credit", f))
    if out is None:
        out = ev._fill(f, "credit", lambda node: _credit(node, ev))
    return out


def _credit_window_mean(x: np.ndarray, lo: int, hi: float) -> np.ndarray:
    out = window_mean(x, lo, hi)
    return np.where(np.isinf(out), 1.0, out)


def _credit_until(a: np.ndarray, b: np.ndarray, lo: int, hi: float) -> np.ndarray:
    return np.clip(until(a, b, lo, hi, REAL), 0.0, 1.0)


@_credit.register
def _(f: A.Const, ev: _Eval) -> np.ndarray:
    return np.full((ev.R, ev.L), 1.0 if f.value else 0.0)


@_credit.register
def _(f: A.Atom, ev: _Eval) -> np.ndarray:
    return ev.atom(f.name)[0].astype(float)


@_credit.register
def _(f: A.Not, ev: _Eval) -> np.ndarray:
    return 1.0 - _csig(f.child, ev)


@_credit.register
def _(f: A.Weighted, ev: _Eval) -> np.ndarray:
    return _csig(f.child, ev)


@_credit.register
def _(f: A.And, ev: _Eval) -> np.ndarray:
    return (_csig(f.left, ev) + _csig(f.right, ev)) / 2.0


@_credit.register
def _(f: A.Or, ev: _Eval) -> np.ndarray:
    return np.maximum(_csig(f.left, ev), _csig(f.right, ev))


@_credit.register
def _(f: A.Implies, ev: _Eval) -> np.ndarray:
    return np.where(ev.sig(f.left, BOOL), _csig(f.right, ev), VACUOUS_CREDIT)


@_credit.register
def _(f: A.Iff, ev: _Eval) -> np.ndarray:
    a, b = ev.sig(f.left, BOOL), ev.sig(f.right, BOOL)
    ca, cb = _csig(f.left, ev), _csig(f.right, ev)
    return (np.where(a, cb, VACUOUS_CREDIT) + np.where(b, ca, VACUOUS_CREDIT)) / 2.0


@_credit.register
def _(f: A.Eventually, ev: _Eval) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    return np.maximum(window(_csig(f.child, ev), lo, hi, np.maximum, -np.inf), 0.0)


@_credit.register
def _(f: A.Globally, ev: _Eval) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    return _credit_window_mean(_csig(f.child, ev), lo, hi)


@_credit.register
def _(f: A.Until, ev: _Eval) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    return _credit_until(_csig(f.left, ev), _csig(f.right, ev), lo, hi)


@_credit.register
def _(f: A.Release, ev: _Eval) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    return 1.0 - _credit_until(1.0 - _csig(f.left, ev), 1.0 - _csig(f.right, ev), lo, hi)


@_credit.register
def _(f: A.WeakUntil, ev: _Eval) -> np.ndarray:
    lo, hi = ev.offsets(f.interval)
    a, b = _csig(f.left, ev), _csig(f.right, ev)
    glo, ghi = ev.offsets(_upto(f.interval))
    return np.maximum(_credit_until(a, b, lo, hi), _credit_window_mean(a, glo, ghi))


_nonvac, _nsig = _robustness_shaped("nonvacuous", lambda x, lo, hi: window(x, lo, hi, np.minimum, np.inf))
"""The non-vacuous robustness signal of a formula (``_nsig``: cached): the robustness's, but at an
implication (below)."""


def _implied(f: A.Formula, left: A.Formula, right: A.Formula, ev: _Eval) -> np.ndarray:
    a, b = _nsig(left, ev), _nsig(right, ev)
    return np.where(ev.sig(left, BOOL), b, np.maximum(-a, b))


@_nonvac.register
def _(f: A.Implies, ev: _Eval) -> np.ndarray:
    return _implied(f, f.left, f.right, ev)


@_nonvac.register
def _(f: A.Iff, ev: _Eval) -> np.ndarray:
    return np.minimum(_implied(f, f.left, f.right, ev), _implied(f, f.right, f.left, ev))


def credit_score(spec: Spec, states: Any, dt: float, formula: A.Formula | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The credit and the non-vacuous robustness at time 0 of each trace, two ``(R,)`` arrays (the section
    above). ``states``, ``dt`` and ``formula`` as :func:`monitor`'s.

    >>> from mitlc.spec.parse import parse_spec
    >>> spec = parse_spec("prop a = x > 1\\nprop b = y > 1\\nformula G[0,1] (a -> F[0,1] b)")
    >>> trace = {"x": np.array([[0.0, 1.2, 0.0]]), "y": np.array([[0.0, 0.0, -3.0]])}
    >>> c, n = credit_score(spec, trace, dt=0.5)
    >>> c.round(4).tolist(), n.round(4).tolist()   # one instance missed, two vacuous; b's best is 1 short
    ([0.3333], [-1.0])
    >>> monitor(spec, trace, dt=0.5).robustness.round(4).tolist()   # the robustness: a's depth alone
    [-0.2]
    """
    ev, f = _prepare(spec, states, dt, formula)
    return _csig(f, ev)[:, 0].astype(float), _nsig(f, ev)[:, 0].astype(float)
