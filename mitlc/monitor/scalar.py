"""The online monitor of one run on Python numbers: :class:`ScalarOnlineMonitor`.

:class:`~mitlc.monitor.online.OnlineMonitor` judges ``R`` runs at once on numpy arrays; for one
run (the Gymnasium wrapper's ``info["verdict"]`` after every step) its small arrays cost more
than the work they hold. :class:`ScalarOnlineMonitor` is the same algorithm (the same core
nodes, the same sealed values and running aggregates, docs/monitor.md, "Online") on Python
floats, bools and lists, so it says what the offline monitor says about every prefix, bit for
bit (tests/test_scalar_monitor.py): the temporal operators only pick values (``max``/``min``,
``or``/``and``), and a proposition's truth and robustness come from the same numpy functions
of its operands and the same IEEE subtraction of the comparison's sides as
:func:`~mitlc.monitor.offline.compile_pred`.

>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec("prop up = abs(q) < 0.3\\nformula F[0,1] G up")
>>> mon = ScalarOnlineMonitor(spec, dt=0.5)
>>> [mon.update([q])[0] for q in (2.0, 0.1, 0.2, 0.0)]
[False, True, True, True]
>>> round(mon.robustness, 6), mon.constant_time
(0.1, True)
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from mitlc.errors import InputError
from mitlc.monitor.offline import judged_formula, needed_variables, sample_time, state_columns
from mitlc.monitor.online import _atom_names, _Builder, _growing, _Node
from mitlc.spec import ast as A
from mitlc.spec import predicates as P
from mitlc.spec.model import Spec

__all__ = ["ScalarOnlineMonitor"]

_INF = math.inf
_TWO_PI = 2 * np.pi  # wrap_angle's


class _Lat:
    """Booleans or floats with their join, meet, negation, bottom and top (one value each)."""

    __slots__ = ("join", "meet", "neg", "bottom", "top")

    def __init__(self, join: Callable, meet: Callable, neg: Callable, bottom: Any, top: Any) -> None:
        self.join, self.meet, self.neg, self.bottom, self.top = join, meet, neg, bottom, top


_BOOL = _Lat(operator.or_, operator.and_, operator.not_, False, True)
_REAL = _Lat(max, min, operator.neg, -_INF, _INF)


# ----------------------------------------------------------------- kernels on lists


def _suffix(x: list, op: Callable) -> list:
    """``y[i] = op(x[i .. end])``."""
    out = list(x)
    for i in range(len(out) - 2, -1, -1):
        out[i] = op(out[i], out[i + 1])
    return out


def _window(x: list, lo: int, hi: float, op: Callable, ident: Any) -> list:
    """``y[k] = op(x[k+lo .. min(k+hi, N)])``, ``ident`` where the window is empty
    (:func:`mitlc.monitor.kernels.window` on one run: van Herk/Gil-Werman blocks)."""
    L = len(x)
    out = [ident] * L
    if lo > L - 1 or hi < lo:
        return out
    w = int(min(hi, L - 1)) - lo + 1
    z = x[lo:]
    n = len(z)
    if w >= n:
        out[:n] = _suffix(z, op)
        return out
    if w == 1:
        out[:n] = z
        return out
    nb = -(-(n + w - 1) // w)
    padded = z + [ident] * (nb * w - n)
    prefix = list(padded)
    suffix = list(padded)
    for b in range(0, nb * w, w):
        for i in range(b + 1, b + w):
            prefix[i] = op(prefix[i - 1], prefix[i])
        for i in range(b + w - 2, b - 1, -1):
            suffix[i] = op(suffix[i], suffix[i + 1])
    out[:n] = [op(suffix[i], prefix[i + w - 1]) for i in range(n)]
    return out


def _until(phi: list, psi: list, lo: int, hi: float, lat: _Lat) -> list:
    """Strong ``phi U_[lo,hi] psi`` in sample offsets (:func:`mitlc.monitor.kernels.until` on one run)."""
    L = len(phi)
    if hi < lo or lo > L - 1:
        return [lat.bottom] * L
    join, meet = lat.join, lat.meet
    core = [lat.bottom] * L
    cur = lat.bottom
    for k in range(L - 1, -1, -1):  # U[k] = join(psi[k], meet(phi[k], U[k+1]))
        cur = join(psi[k], meet(phi[k], cur))
        core[k] = cur
    if hi - lo < L - 1:
        core = list(map(meet, core, _window(psi, 0, hi - lo, join, lat.bottom)))
    out = core[lo:] + [lat.bottom] * lo if lo else core
    if lo > 0:
        out = list(map(meet, out, _window(phi, 0, lo - 1, meet, lat.top)))
    return out


# ----------------------------------------------------------------- evaluation


class _Running:
    """An unbounded ``F`` or ``G`` over a bounded operand at the samples ``p ..``
    (:class:`mitlc.monitor.online._Running` on one run)."""

    def __init__(self, eng: _Engine, node: _Node, p: int) -> None:
        self.eng, self.node, self.p = eng, node, p
        lat = eng.lat
        self.op = lat.join if node.op == "F" else lat.meet
        self.ident = lat.bottom if node.op == "F" else lat.top
        self.f = p + node.lo - 1  # the operand's last sealed sample
        self.acc: list = []

    def values(self, e: int) -> list:
        eng, node, p, op = self.eng, self.node, self.p, self.op
        kid, lo, k = node.kids[0], node.lo, eng.k
        m = e - p + 1
        acc = self.acc
        if len(acc) < m:
            acc.extend([self.ident] * (m - len(acc)))
        f_new = k - int(kid.h)
        if f_new > self.f:
            first = self.f + 1
            suffix = _suffix(eng.vals(kid, first, f_new, fixed=False), op)
            for i in range(len(acc)):
                start = max(p + i + lo, first)
                if start <= f_new:
                    acc[i] = op(acc[i], suffix[start - first])
            self.f = f_new
        out = acc[:m]
        first = self.f + 1
        if first <= k:
            suffix = _suffix(eng.vals(kid, first, k, fixed=False), op)
            for i in range(m):
                start = max(p + i + lo, first)
                if start <= k:
                    out[i] = op(out[i], suffix[start - first])
        return out


class _RunningUntil:
    """An unbounded ``a U b`` over bounded operands at the samples ``p ..``
    (:class:`mitlc.monitor.online._RunningUntil` on one run)."""

    def __init__(self, eng: _Engine, node: _Node, p: int) -> None:
        self.eng, self.node, self.p = eng, node, p
        self.f = p - 1
        self.lm: list = []
        self.best: list = []

    def values(self, e: int) -> list:
        eng, node, p, lat = self.eng, self.node, self.p, self.eng.lat
        join, meet = lat.join, lat.meet
        left, right = node.kids
        lo, k = node.lo, eng.k
        m = e - p + 1
        lm, best = self.lm, self.best
        if len(lm) < m:
            best.extend([lat.bottom] * (m - len(lm)))
            lm.extend([lat.top] * (m - len(lm)))
        f_new = k - int(max(left.h, right.h))
        if f_new > self.f:
            first = self.f + 1
            a = eng.vals(left, first, f_new, fixed=False)
            b = eng.vals(right, first, f_new, fixed=False)
            n = len(lm)
            for i, j in enumerate(range(first, f_new + 1)):
                for t in range(min(j - lo - p + 1, n)):  # the t with j in their window
                    best[t] = join(best[t], meet(b[i], lm[t]))
                for t in range(min(j - p + 1, n)):  # the t whose left side reaches j
                    lm[t] = meet(lm[t], a[i])
            self.f = f_new
        out = best[:m]
        first = self.f + 1
        if first <= k:
            a = eng.vals(left, first, k, fixed=False)
            b = eng.vals(right, first, k, fixed=False)
            before = [lat.top] * len(a)  # a over the tail before each j
            for i in range(1, len(a)):
                before[i] = meet(before[i - 1], a[i - 1])
            suffix = _suffix(list(map(meet, b, before)), join)
            for i in range(min(e, self.f) - p + 1):  # t <= f: sealed left sides
                start = max(p + i + lo, first)
                if start <= k:
                    out[i] = join(out[i], meet(lm[i], suffix[start - first]))
            if e >= first:  # t in the tail: the offline until over the tail itself
                u = _until(a, b, lo, _INF, lat)
                out[first - p : e - p + 1] = u[: e - first + 1]
        return out


class _Engine:
    """Values of core nodes on the current prefix, in one lattice, as lists
    (:class:`mitlc.monitor.online._Engine` on one run)."""

    def __init__(self, lat: _Lat, atoms: dict[str, list]) -> None:
        self.lat, self.atoms = lat, atoms
        self.k = -1
        self.final: dict[tuple[int, int, float], list] = {}
        self.memo: dict[tuple[int, int, float], list] = {}
        self.states: dict[tuple[int, int, float], Any] = {}

    def vals(self, g: _Node, p: int, q: float, fixed: bool = True) -> list:
        """Values of ``g`` at the samples ``p .. min(q, k)``."""
        k = self.k
        e = int(min(q, k))
        if p > e:
            return []
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

    def _compute(self, g: _Node, p: int, q: float, e: int, fixed: bool) -> list:
        lat, k = self.lat, self.k
        if g.bounded:
            return self.slice(g, p, int(min(e + g.h, k)))[: e - p + 1]
        op = g.op
        if op == "not":
            return list(map(lat.neg, self.vals(g.kids[0], p, q, fixed)))
        if op in ("and", "or"):
            a, b = (self.vals(c, p, q, fixed) for c in g.kids)
            return list(map(lat.meet if op == "and" else lat.join, a, b))
        lo, hi = g.lo, g.hi
        if op in ("F", "G"):
            agg, ident = (lat.join, lat.bottom) if op == "F" else (lat.meet, lat.top)
            kid = g.kids[0]
            out = [ident] * (e - p + 1)
            live = min(e, k - lo) - p + 1  # samples whose window starts inside the prefix
            if live <= 0:
                return out
            if not math.isinf(hi):  # a bounded window over an unbounded operand
                c = self.vals(kid, p + lo, q + hi, fixed)
                out[:live] = _window(c, 0, hi - lo, agg, ident)[:live]
                return out
            if p == e == k:  # the last sample: its window is the sample itself, or empty
                if lo == 0:
                    out[0] = self.vals(kid, k, k, fixed=False)[0]
                return out
            if kid.mono in (1, -1, 2) and not kid.bounded:
                if (kid.mono == 1) == (op == "G") or kid.mono == 2:  # at the window's first sample
                    out[:live] = self.vals(kid, p + lo, q + lo, fixed)[:live]
                else:  # at its last, k
                    out[:live] = [self.vals(kid, k, k, fixed=False)[0]] * live
                return out
            if kid.bounded:
                return self._state(g, p, q, _Running).values(e)
        elif op == "U" and math.isinf(hi):
            if p == e == k:
                return [self.vals(g.kids[1], k, k, fixed=False)[0] if lo == 0 else lat.bottom]
            if all(c.bounded for c in g.kids):
                return self._state(g, p, q, _RunningUntil).values(e)
        elif op == "U":  # a bounded until over unbounded operands
            a = self.vals(g.kids[0], p, q + hi, fixed)
            b = self.vals(g.kids[1], p, q + hi, fixed)
            return _until(a, b, lo, hi, lat)[: e - p + 1]
        # an unbounded operator over an unbounded, non-monotone one: the whole prefix again
        return self.slice(g, p, k)[: e - p + 1]

    def _state(self, g: _Node, p: int, q: float, kind: type) -> Any:
        key = (id(g), p, q)
        st = self.states.get(key)
        if st is None:
            st = self.states[key] = kind(self, g, p)
        return st

    def slice(self, g: _Node, a: int, b: int) -> list:
        """``g`` evaluated on the samples ``a .. b`` as a trace of its own (the offline rule)."""
        memo: dict[int, list] = {}
        lat, L = self.lat, b - a + 1

        def ev(n: _Node) -> list:
            out = memo.get(id(n))
            if out is not None:
                return out
            op = n.op
            if op == "const":
                out = [lat.top if n.value else lat.bottom] * L
            elif op == "atom":
                out = self.atoms[n.name][a : b + 1]
            elif op == "not":
                out = list(map(lat.neg, ev(n.kids[0])))
            elif op == "and":
                out = list(map(lat.meet, ev(n.kids[0]), ev(n.kids[1])))
            elif op == "or":
                out = list(map(lat.join, ev(n.kids[0]), ev(n.kids[1])))
            elif op == "F":
                out = _window(ev(n.kids[0]), n.lo, n.hi, lat.join, lat.bottom)
            elif op == "G":
                out = _window(ev(n.kids[0]), n.lo, n.hi, lat.meet, lat.top)
            else:
                out = _until(ev(n.kids[0]), ev(n.kids[1]), n.lo, n.hi, lat)
            memo[id(n)] = out
            return out

        return ev(g)


# ----------------------------------------------------------------- the root at sample 0, directly


class _Plan:
    """The root's value at sample 0 as closures over one engine's atoms, for the shapes that
    need no lists: a proposition, ``not``/``and``/``or``, an unbounded ``F``/``G`` over a
    formula of one sample (a running aggregate), ``F``/``G`` over a monotone formula (its value
    at one end of the window), and any bounded formula once final. Every other node is asked of
    the engine (:meth:`_Engine.vals`), which holds the general rules; both give the same values.
    """

    def __init__(self, eng: _Engine) -> None:
        self.eng, self.lat = eng, eng.lat
        self.memo: dict[tuple[int, int], Callable[[], Any]] = {}
        self.lasts: dict[int, Callable[[], Any]] = {}

    def at(self, g: _Node, t: int) -> Callable[[], Any]:
        """``() -> value of g at sample t`` (called only once the prefix reaches t)."""
        key = (id(g), t)
        fn = self.memo.get(key)
        if fn is None:
            fn = self.memo[key] = self._at(g, t)
        return fn

    def _at(self, g: _Node, t: int) -> Callable[[], Any]:
        eng, lat, op = self.eng, self.lat, g.op
        if op == "const":
            v = lat.top if g.value else lat.bottom
            return lambda: v
        if op == "atom":
            atoms = eng.atoms[g.name]
            return lambda: atoms[t]
        if op in ("not", "and", "or"):
            kids = [self.at(c, t) for c in g.kids]
            if op == "not":
                neg, a = lat.neg, kids[0]
                return lambda: neg(a())
            f, a, b = lat.meet if op == "and" else lat.join, kids[0], kids[1]
            return lambda: f(a(), b())
        if g.bounded:  # final once the prefix holds its horizon
            return self._generic(g, t, final_at=t + int(g.h))
        lo, hi, kid = g.lo, g.hi, g.kids[0]
        if op in ("F", "G"):
            agg, ident = (lat.join, lat.bottom) if op == "F" else (lat.meet, lat.top)
            if math.isinf(hi) and _of_one_sample(kid):
                return self._running(kid, t + lo, agg, ident)
            if kid.mono in (1, -1, 2) and not kid.bounded:
                first = (kid.mono == 1) == (op == "G") or kid.mono == 2
                start = t + lo
                if first:
                    at_start = self.at(kid, start)
                    return lambda: at_start() if eng.k >= start else ident
                last = self.last(kid)
                if math.isinf(hi):
                    return lambda: last() if eng.k >= start else ident
                end = t + int(hi)
                at_end = self.at(kid, end)
                return lambda: ident if eng.k < start else last() if eng.k <= end else at_end()
        return self._generic(g, t, final_at=None)

    def _generic(self, g: _Node, t: int, final_at: int | None) -> Callable[[], Any]:
        eng = self.eng
        seen: list = []  # the final value, once there is one

        def value() -> Any:
            if seen:
                return seen[0]
            v = eng.vals(g, t, t)[0]
            if final_at is not None and eng.k >= final_at:
                seen.append(v)
            return v

        return value

    def _running(self, kid: _Node, start: int, agg: Callable, ident: Any) -> Callable[[], Any]:
        """``agg`` of a one-sample formula over the samples ``start .. k``, one more each sample."""
        eng, sample = self.eng, self.sample(kid)
        state = [ident, start]  # the aggregate so far, the next sample to add

        def value() -> Any:
            acc, j = state
            k = eng.k
            while j <= k:
                acc = agg(acc, sample(j))
                j += 1
            state[0], state[1] = acc, j
            return acc

        return value

    def sample(self, g: _Node) -> Callable[[int], Any]:
        """``j -> value of g at sample j`` for a formula of one sample (:func:`_of_one_sample`)."""
        lat, op = self.lat, g.op
        if op == "const":
            v = lat.top if g.value else lat.bottom
            return lambda j: v
        if op == "atom":
            return self.eng.atoms[g.name].__getitem__
        kids = [self.sample(c) for c in g.kids]
        if op == "not":
            neg, a = lat.neg, kids[0]
            return lambda j: neg(a(j))
        f, a, b = lat.meet if op == "and" else lat.join, kids[0], kids[1]
        return lambda j: f(a(j), b(j))

    def last(self, g: _Node) -> Callable[[], Any]:
        """``() -> value of g at the last sample k``: the formula on that one sample."""
        fn = self.lasts.get(id(g))
        if fn is None:
            fn = self.lasts[id(g)] = self._last(g)
        return fn

    def _last(self, g: _Node) -> Callable[[], Any]:
        lat, op = self.lat, g.op
        if op == "const":
            v = lat.top if g.value else lat.bottom
            return lambda: v
        if op == "atom":
            atoms = self.eng.atoms[g.name]
            return lambda: atoms[-1]
        if op == "not":
            neg, a = lat.neg, self.last(g.kids[0])
            return lambda: neg(a())
        if op in ("and", "or"):
            f, a, b = lat.meet if op == "and" else lat.join, self.last(g.kids[0]), self.last(g.kids[1])
            return lambda: f(a(), b())
        if g.lo > 0:  # the window starts past the trace: F and U fail, G holds
            v = lat.top if op == "G" else lat.bottom
            return lambda: v
        return self.last(g.kids[1] if op == "U" else g.kids[0])


def _of_one_sample(g: _Node) -> bool:
    """Whether ``g``'s value at a sample reads that sample alone (propositions and connectives)."""
    return g.op in ("const", "atom") or (g.op in ("not", "and", "or") and all(_of_one_sample(c) for c in g.kids))


# ----------------------------------------------------------------- propositions on floats

_COMPARE: dict[str, Callable[[float, float], bool]] = {
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
    "==": operator.eq,
    "!=": operator.ne,
}


def _margin(op: str) -> Callable[[float, float], float]:
    """:func:`mitlc.spec.grades.margin` on floats: the same IEEE subtraction, nan read as 0."""
    if op in ("<", "<="):
        return lambda a, b: 0.0 if (r := b - a) != r else r
    if op in (">", ">="):
        return lambda a, b: 0.0 if (r := a - b) != r else r
    if op == "==":
        return lambda a, b: 0.0 if (r := -abs(a - b)) != r else r
    return lambda a, b: 0.0 if (r := abs(a - b)) != r else r


PredFn1 = Callable[[Sequence[float]], tuple[bool, float]]
"""A proposition on one state (floats by column): ``x -> (truth, robustness)``."""


def _may_warn(p: P.Pred) -> bool:
    """Whether numpy may warn computing ``p``'s operands on floats (a function out of its domain,
    overflow): the functions :func:`_operand` leaves to numpy."""
    if not isinstance(p, P.Num) and not P.is_boolean(p) and P.const_value(p) is not None:
        return False  # folded before any sample
    if isinstance(p, P.Call) and p.fn not in ("abs", "sqrt"):
        return True
    return isinstance(p, P.BinOp) and p.op == "/" or any(_may_warn(c) for c in p.children)


def _divide(a: float, b: float) -> float:
    return a / b if b else float(np.divide(a, b))  # x / 0: inf or nan, as numpy gives


def _sqrt(a: float) -> float:
    return math.sqrt(a) if a >= 0.0 else math.nan  # nan below 0, as numpy gives


_ARITH: dict[str, Callable[[float, float], float]] = {
    "+": operator.add,
    "-": operator.sub,
    "*": operator.mul,
    "/": _divide,
}


def _operand(p: P.Pred, columns: dict[str, int]) -> Callable[[Sequence[float]], float]:
    """A numeric predicate node on one state of floats, numpy's value to the bit: constants folded
    as :func:`~mitlc.spec.predicates.compile_numpy` folds them, Python's ``+ - * /``, ``abs`` and
    ``sqrt`` (IEEE operations, as numpy's), numpy's own function for the rest."""
    value = p.value if isinstance(p, P.Num) else P.const_value(p)
    if value is not None:
        v = float(value)
        return lambda x: v
    if isinstance(p, P.Var):
        i = columns[p.name]
        return lambda x: x[i]
    if isinstance(p, P.Neg):
        f = _operand(p.arg, columns)
        return lambda x: -f(x)
    if isinstance(p, P.BinOp):
        op, fl, fr = _ARITH[p.op], _operand(p.left, columns), _operand(p.right, columns)
        return lambda x: op(fl(x), fr(x))
    if isinstance(p, P.Call):
        fs = [_operand(a, columns) for a in p.args]
        if p.fn in ("abs", "sqrt"):
            fn1, f0 = abs if p.fn == "abs" else _sqrt, fs[0]
            return lambda x: fn1(f0(x))
        fn = P.FUNCTIONS[p.fn][1]
        return lambda x: float(fn(*(f(x) for f in fs)))
    raise InputError(f"'{p}' is not a number")  # pragma: no cover - the parser checks operand types


def _pred(p: P.Pred, columns: dict[str, int]) -> PredFn1:
    """Truth and robustness of a boolean predicate on one state, as
    :func:`~mitlc.monitor.offline.compile_pred` gives them: the operands by :func:`_operand`, then
    Python's comparisons and subtractions, which are numpy's on float64."""
    if isinstance(p, P.Compare):
        reads = [_operand(o, columns) for o in p.operands]
        links = [(_COMPARE[op], _margin(op)) for op in p.ops]
        if len(links) == 1:  # one comparison: its margin is the robustness (min with inf)
            (cmp1, margin1), fa, fb = links[0], reads[0], reads[1]

            def compare1(x: Sequence[float]) -> tuple[bool, float]:
                a, b = fa(x), fb(x)
                return cmp1(a, b), margin1(a, b)

            return compare1

        def compare(x: Sequence[float]) -> tuple[bool, float]:
            values = [f(x) for f in reads]
            truth, rob = True, _INF
            for (cmp, margin), a, b in zip(links, values, values[1:], strict=False):
                truth = cmp(a, b) and truth
                rob = min(rob, margin(a, b))
            return truth, rob

        return compare
    if isinstance(p, (P.PAnd, P.POr)):
        fl, fr = _pred(p.left, columns), _pred(p.right, columns)
        if isinstance(p, P.PAnd):
            return lambda x: ((a := fl(x))[0] & (b := fr(x))[0], min(a[1], b[1]))
        return lambda x: ((a := fl(x))[0] | (b := fr(x))[0], max(a[1], b[1]))
    if isinstance(p, P.PNot):
        inner = _pred(p.arg, columns)
        return lambda x: (not (a := inner(x))[0], -a[1])
    raise InputError(f"'{p}' is a number, not a condition")


_MARGIN_SOURCE = {
    "<": "{b} - {a}",
    "<=": "{b} - {a}",
    ">": "{a} - {b}",
    ">=": "{a} - {b}",
    "==": "-abs({a} - {b})",
    "!=": "abs({a} - {b})",
}
_COMPARE_SOURCE = {op: "{a} " + op + " {b}" for op in _MARGIN_SOURCE}
_BINARY_SOURCE = {"+": "({} + {})", "-": "({} - {})", "*": "({} * {})", "/": "_divide({}, {})"}
"""The generated predicate functions' text for each operator, looked up, never copied from the tree
(as :mod:`mitlc.runtime.atoms`): an operator the parser would not give fails here, not in ``exec``."""


def _literal(v: float) -> str:
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "(-inf)"
    return repr(v)


def _operand_source(p: P.Pred, columns: dict[str, int]) -> str:
    """:func:`_operand` as a Python expression over ``x``: the same operations in the same order."""
    value = p.value if isinstance(p, P.Num) else P.const_value(p)
    if value is not None:
        return _literal(float(value))
    if isinstance(p, P.Var):
        return f"x[{int(columns[p.name])}]"
    if isinstance(p, P.Neg):
        return f"(-{_operand_source(p.arg, columns)})"
    if isinstance(p, P.BinOp):
        return _BINARY_SOURCE[p.op].format(_operand_source(p.left, columns), _operand_source(p.right, columns))
    if isinstance(p, P.Call):
        args = [_operand_source(a, columns) for a in p.args]
        if p.fn in ("abs", "sqrt"):
            return f"{'abs' if p.fn == 'abs' else '_sqrt'}({args[0]})"
        if p.fn not in P.FUNCTIONS:
            raise KeyError(p.fn)
        return f"float(_fn_{p.fn}({', '.join(args)}))"
    raise InputError(f"'{p}' is not a number")  # pragma: no cover - the parser checks operand types


def _pred_lines(p: P.Pred, columns: dict[str, int], lines: list[str], names: list[int]) -> tuple[str, str]:
    """Statements computing :func:`_pred`'s truth and robustness of ``p`` into fresh variables, whose
    names it returns."""
    names[0] += 1
    t, r = f"t{names[0]}", f"r{names[0]}"
    if isinstance(p, P.Compare):
        values = []
        for o in p.operands:  # every operand first, left to right, as _pred's list
            names[0] += 1
            v = f"v{names[0]}"
            lines.append(f"{v} = {_operand_source(o, columns)}")
            values.append(v)
        if len(p.ops) == 1:
            op, a, b = p.ops[0], values[0], values[1]
            lines += [
                f"{t} = {_COMPARE_SOURCE[op].format(a=a, b=b)}",
                f"{r} = {_MARGIN_SOURCE[op].format(a=a, b=b)}",
                f"if {r} != {r}: {r} = 0.0",
            ]
            return t, r
        lines += [f"{t} = True", f"{r} = inf"]
        for op, a, b in zip(p.ops, values, values[1:], strict=False):
            names[0] += 1
            m = f"m{names[0]}"
            lines += [
                f"{t} = ({_COMPARE_SOURCE[op].format(a=a, b=b)}) and {t}",
                f"{m} = {_MARGIN_SOURCE[op].format(a=a, b=b)}",
                f"if {m} != {m}: {m} = 0.0",
                f"{r} = min({r}, {m})",
            ]
        return t, r
    if isinstance(p, (P.PAnd, P.POr)):
        ta, ra = _pred_lines(p.left, columns, lines, names)
        tb, rb = _pred_lines(p.right, columns, lines, names)
        if isinstance(p, P.PAnd):
            lines += [f"{t} = {ta} & {tb}", f"{r} = min({ra}, {rb})"]
        else:
            lines += [f"{t} = {ta} | {tb}", f"{r} = max({ra}, {rb})"]
        return t, r
    if isinstance(p, P.PNot):
        ta, ra = _pred_lines(p.arg, columns, lines, names)
        lines += [f"{t} = not {ta}", f"{r} = -{ra}"]
        return t, r
    raise InputError(f"'{p}' is a number, not a condition")


def _pred_compiled(p: P.Pred, columns: dict[str, int]) -> PredFn1:
    """:func:`_pred` as one generated Python function (no closure per node): the same operations
    on the same floats in the same order, so the same truth and robustness to the bit
    (tests/test_scalar_trace_monitor.py compares them)."""
    lines: list[str] = []
    t, r = _pred_lines(p, columns, lines, [0])
    source = "def pred(x):\n" + "".join(f"    {line}\n" for line in lines) + f"    return {t}, {r}\n"
    namespace: dict[str, Any] = {"inf": _INF, "nan": math.nan, "_divide": _divide, "_sqrt": _sqrt}
    namespace.update({f"_fn_{name}": fn for name, (_, fn) in P.FUNCTIONS.items()})
    exec(compile(source, "<mitlc scalar predicate>", "exec"), namespace)  # generated from the tree
    fn: PredFn1 = namespace["pred"]
    return fn


# ----------------------------------------------------------------- the monitor


class ScalarOnlineMonitor:
    """Judge one growing trace by ``formula`` (default: the spec's ``check`` line, else its
    ``formula``), one sample at a time, as the offline monitor judges each prefix.

    ``dt`` is the sample time in seconds. :meth:`update` takes sample ``k``: a sequence of
    floats in ``columns`` order (default: :func:`~mitlc.monitor.offline.state_columns`).
    Periodic state variables are wrapped to ``[-pi, pi)`` first.
    """

    def __init__(
        self, spec: Spec, dt: float, formula: A.Formula | None = None, columns: Sequence[str] | None = None
    ) -> None:
        self.spec, self.dt = spec, sample_time(dt)
        self.formula = judged_formula(spec, formula)
        self.columns = tuple(state_columns(spec) if columns is None else columns)
        self.needed = needed_variables(spec, self.formula)
        missing = [n for n in self.needed if n not in self.columns]
        if missing:
            raise InputError(f"no column for state variable{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
        self._root = _Builder(self.dt)(self.formula)
        self._names = sorted(_atom_names(self._root))
        where = {n: i for i, n in enumerate(self.columns)}
        self._preds = [_pred_compiled(spec.prop(n).pred, where) for n in self._names]
        self._quiet = any(_may_warn(spec.prop(n).pred) for n in self._names)
        plant = spec.plant
        periodic = {v.name for v in plant.state if v.periodic} if plant is not None else set()
        self._wrap = [where[n] for n in self.needed if n in periodic]
        self._check = [(where[n], n) for n in self.needed]
        self._width = len(self.columns)
        self.constant_time = not _growing(self._root)
        """Whether the work per sample stays bounded as the trace grows."""
        self.reset()

    def reset(self) -> None:
        """Forget every sample: the next :meth:`update` is sample 0."""
        self.k = -1
        self._truth: dict[str, list[bool]] = {n: [] for n in self._names}
        self._rob: dict[str, list[float]] = {n: [] for n in self._names}
        self._sinks = [(pred, self._truth[n], self._rob[n]) for n, pred in zip(self._names, self._preds, strict=True)]
        self._bool = _Engine(_BOOL, self._truth)
        self._real = _Engine(_REAL, self._rob)
        self._root_bool = _Plan(self._bool).at(self._root, 0)
        self._root_real = _Plan(self._real).at(self._root, 0)
        self.satisfied = False
        self.robustness = 0.0

    def signals(self) -> tuple[dict[str, list[bool]], dict[str, list[float]]]:
        """Each proposition's truth and robustness on the samples so far, keyed by proposition (the
        monitor's own lists, for reading: :meth:`mitlc.monitor.scalar_offline.ScalarTraceMonitor.judge_signals`)."""
        return self._truth, self._rob

    def _push(self, x: Sequence[float]) -> None:
        """Each proposition's truth and robustness on ``x``, appended to its signals."""
        for pred, truths, robs in self._sinks:
            truth, rob = pred(x)
            truths.append(truth)
            robs.append(rob)

    def update(self, x: Sequence[float]) -> tuple[bool, float]:
        """Add sample ``k + 1``; the verdict and robustness of the prefix so far."""
        if len(x) != self._width:
            raise InputError(
                f"a sample must have {len(self.columns)} values ({', '.join(self.columns) or 'no columns'}), "
                f"got {len(x)}"
            )
        for i, n in self._check:
            if not math.isfinite(x[i]):
                raise InputError(f"state variable '{n}' is not finite (sample {self.k + 1}: {x[i]})")
        return self.update_checked(x)

    def update_checked(self, x: Sequence[float]) -> tuple[bool, float]:
        """:meth:`update` of a sample the caller has checked: as many values as columns, every
        needed one finite (the Gymnasium wrapper's reader checks each observation so)."""
        if self._wrap:
            x = list(x)
            for i in self._wrap:  # wrap_angle's operations (on a float: numpy's remainder to the bit)
                x[i] = float((x[i] + math.pi) % _TWO_PI - math.pi)
        if self._quiet:  # IEEE arithmetic, as the offline monitor computes it: no warnings
            with np.errstate(all="ignore"):
                self._push(x)
        else:
            for pred, truths, robs in self._sinks:
                truth, rob = pred(x)
                truths.append(truth)
                robs.append(rob)
        self.k = k = self.k + 1
        engine_bool, engine_real = self._bool, self._real
        engine_bool.k = engine_real.k = k
        if engine_bool.memo:
            engine_bool.memo.clear()
        if engine_real.memo:
            engine_real.memo.clear()
        satisfied = self.satisfied = bool(self._root_bool())
        robustness = self.robustness = float(self._root_real())
        return satisfied, robustness
