"""The offline monitor of one run on Python numbers: :class:`ScalarTraceMonitor`.

:func:`~mitlc.monitor.offline.monitor` judges ``R`` traces at once on numpy arrays; for one short
trace (the Gymnasium wrapper's verdict at the end of an episode, 60 samples: a fifth of the
offline monitor's time) its calls cost more than the work they hold. :class:`ScalarTraceMonitor`
is the same rules (:mod:`mitlc.monitor.offline`: each node's signal over both lattices, its settle
signal, the blame's descent) on Python lists, so it gives the offline monitor's ``satisfied``,
``robustness``, ``violation_time`` and ``failing`` (tests/test_scalar_trace_monitor.py): the
operators only pick values and sample indices, and a proposition's truth and robustness are
:class:`~mitlc.monitor.scalar.ScalarOnlineMonitor`'s. The same floats to the bit, but for the sign
of a zero: of two equal values the operators here may pick the other one than numpy's SIMD
loops do, so a robustness or violation time of 0 may be -0.0 where the offline monitor's is 0.0
(or the reverse); a caller that needs those bits asks the offline monitor there, as
:class:`~mitlc.gym.MitlRewardWrapper` does. ``F``/``G`` at the root are evaluated at sample 0
alone.

>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec("prop up = abs(q) < 0.3\\nformula G[0,1] !up")
>>> satisfied, robustness, violation_time, failing = ScalarTraceMonitor(spec, dt=0.5).judge([[2.0], [1.0], [0.25]])
>>> satisfied, round(robustness, 6), violation_time, failing
(False, -0.05, 1.0, '!up')
"""

from __future__ import annotations

import contextlib
import math
import operator
from collections.abc import Callable, Sequence
from itertools import accumulate
from typing import Any

import numpy as np

from mitlc.errors import CompileError, InputError
from mitlc.monitor.offline import judged_formula, needed_variables, sample_time, state_columns
from mitlc.monitor.scalar import _BOOL, _REAL, _Lat, _may_warn, _pred_compiled
from mitlc.spec import ast as A
from mitlc.spec.model import Spec

__all__ = ["ScalarTraceMonitor"]

_INF = math.inf
_TWO_PI = 2 * math.pi


# ----------------------------------------------------------------- kernels on lists
#
# mitlc.monitor.scalar's kernels with the lattices' operations written out as comparisons (a call
# of the builtin max costs more than the loop around it) and the booleans' scans found by
# list.index; of two equal values they may pick the other one than numpy does, so only a zero's
# sign can differ (the wrapper asks the offline monitor where a verdict's robustness or violation
# time is 0)


def _pairwise(op: Callable, a: list, b: list) -> list:
    """``[op(x, y) for x, y in zip(a, b)]``."""
    if op is max:
        return [x if x >= y else y for x, y in zip(a, b, strict=True)]
    if op is min:
        return [x if x <= y else y for x, y in zip(a, b, strict=True)]
    if op is operator.or_:
        return [x or y for x, y in zip(a, b, strict=True)]
    if op is operator.and_:
        return [x and y for x, y in zip(a, b, strict=True)]
    return list(map(op, a, b))


def _suffix(x: list, op: Callable) -> list:
    """``y[i] = op(x[i .. end])``."""
    n = len(x)
    if op is operator.or_ or op is operator.and_:  # true (or) / false (and) up to the last such sample
        hit = op is operator.or_
        back = x[::-1]
        if hit not in back:
            return [not hit] * n
        last = n - 1 - back.index(hit)
        return [hit] * (last + 1) + [not hit] * (n - 1 - last)
    out = list(x)
    if not n:
        return out
    cur = out[-1]
    if op is max:
        for i in range(n - 2, -1, -1):
            v = out[i]
            if cur > v:
                out[i] = cur
            else:
                cur = v
    elif op is min:
        for i in range(n - 2, -1, -1):
            v = out[i]
            if cur < v:
                out[i] = cur
            else:
                cur = v
    else:
        out = list(accumulate(reversed(x), op))
        out.reverse()
    return out


def _prefix(x: list, op: Callable) -> list:
    """``y[i] = op(x[0 .. i])``."""
    n = len(x)
    if op is operator.or_ or op is operator.and_:  # false (or) / true (and) before the first such sample
        hit = op is operator.or_
        if hit not in x:
            return [not hit] * n
        first = x.index(hit)
        return [not hit] * first + [hit] * (n - first)
    out = list(x)
    if not n:
        return out
    cur = out[0]
    if op is max:
        for i in range(1, n):
            v = out[i]
            if cur > v:
                out[i] = cur
            else:
                cur = v
    elif op is min:
        for i in range(1, n):
            v = out[i]
            if cur < v:
                out[i] = cur
            else:
                cur = v
    else:
        out = list(accumulate(x, op))
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
    prefix: list = []
    suffix: list = []
    for b in range(0, nb * w, w):
        block = padded[b : b + w]
        prefix.extend(_prefix(block, op))
        suffix.extend(_suffix(block, op))
    out[:n] = _pairwise(op, suffix[:n], prefix[w - 1 : w - 1 + n])
    return out


def _until(phi: list, psi: list, lo: int, hi: float, lat: _Lat) -> list:
    """Strong ``phi U_[lo,hi] psi`` in sample offsets (:func:`mitlc.monitor.kernels.until` on one run)."""
    L = len(phi)
    if hi < lo or lo > L - 1:
        return [lat.bottom] * L
    join, meet = lat.join, lat.meet
    core = [lat.bottom] * L
    cur = lat.bottom
    if lat is _REAL:
        for k in range(L - 1, -1, -1):  # U[k] = max(psi[k], min(phi[k], U[k+1]))
            a = phi[k]
            m = a if a <= cur else cur
            b = psi[k]
            cur = b if b >= m else m
            core[k] = cur
    else:
        for k in range(L - 1, -1, -1):  # U[k] = psi[k] or (phi[k] and U[k+1])
            cur = psi[k] or (phi[k] and cur)
            core[k] = cur
    if hi - lo < L - 1:
        core = _pairwise(meet, core, _window(psi, 0, hi - lo, join, lat.bottom))
    out = core[lo:] + [lat.bottom] * lo if lo else core
    if lo > 0:
        out = _pairwise(meet, out, _window(phi, 0, lo - 1, meet, lat.top))
    return out


def _upto(interval: A.Interval) -> A.Interval:
    """``[0, sup I]``: the ``G`` part of a weak until (:func:`mitlc.monitor.offline._upto`)."""
    return A.Interval(0.0, interval.hi, True, interval.hi_closed)


def _first(row: list, a: int, b: int, value: bool) -> int | None:
    """First index in ``[a, b]`` where ``row`` equals ``value``, else None."""
    for i in range(a, min(b, len(row) - 1) + 1):
        if row[i] == value:
            return i
    return None


def _settled(x: list[float]) -> list[float]:
    """An infinite settle sample (a window with no sample in the trace) is the sample itself."""
    return [v if -_INF < v < _INF else float(i) for i, v in enumerate(x)]


class _Run:
    """Signals of one trace's subformulas, computed once (:class:`mitlc.monitor.offline._Eval` on lists)."""

    def __init__(self, mon: ScalarTraceMonitor, truth: dict[str, list], rob: dict[str, list], L: int) -> None:
        self.mon, self.truth, self.rob, self.L, self.N = mon, truth, rob, L, L - 1
        self.cache: dict[tuple[int, int], list] = {}

    def offsets(self, interval: A.Interval) -> tuple[int, float]:
        return self.mon.offsets(interval)

    # ------------------------------------------------------------ signals
    def sig(self, f: A.Formula, lat: _Lat) -> list:
        key = (id(f), lat is _REAL)
        out = self.cache.get(key)
        if out is None:
            out = self.cache[key] = self._sig(f, lat)
        return out

    def _sig(self, f: A.Formula, lat: _Lat) -> list:
        if isinstance(f, A.Atom):
            return (self.rob if lat is _REAL else self.truth)[f.name]
        if isinstance(f, A.Const):
            return [lat.top if f.value else lat.bottom] * self.L
        if isinstance(f, A.Not):
            return list(map(lat.neg, self.sig(f.child, lat)))
        if isinstance(f, A.Weighted):
            return self.sig(f.child, lat)
        if isinstance(f, A.And):
            return _pairwise(lat.meet, self.sig(f.left, lat), self.sig(f.right, lat))
        if isinstance(f, A.Or):
            return _pairwise(lat.join, self.sig(f.left, lat), self.sig(f.right, lat))
        if isinstance(f, A.Implies):
            return _pairwise(lat.join, list(map(lat.neg, self.sig(f.left, lat))), self.sig(f.right, lat))
        if isinstance(f, A.Iff):
            a, b = self.sig(f.left, lat), self.sig(f.right, lat)
            join, meet, neg = lat.join, lat.meet, lat.neg
            return [meet(join(neg(x), y), join(x, neg(y))) for x, y in zip(a, b, strict=True)]
        if isinstance(f, A.Eventually):
            lo, hi = self.offsets(f.interval)
            return _window(self.sig(f.child, lat), lo, hi, lat.join, lat.bottom)
        if isinstance(f, A.Globally):
            lo, hi = self.offsets(f.interval)
            return _window(self.sig(f.child, lat), lo, hi, lat.meet, lat.top)
        if isinstance(f, A.Until):
            lo, hi = self.offsets(f.interval)
            return _until(self.sig(f.left, lat), self.sig(f.right, lat), lo, hi, lat)
        if isinstance(f, A.Release):
            lo, hi = self.offsets(f.interval)
            a, b = list(map(lat.neg, self.sig(f.left, lat))), list(map(lat.neg, self.sig(f.right, lat)))
            return list(map(lat.neg, _until(a, b, lo, hi, lat)))
        if isinstance(f, A.WeakUntil):
            lo, hi = self.offsets(f.interval)
            a, b = self.sig(f.left, lat), self.sig(f.right, lat)
            glo, ghi = self.offsets(_upto(f.interval))
            return _pairwise(lat.join, _until(a, b, lo, hi, lat), _window(a, glo, ghi, lat.meet, lat.top))
        raise CompileError(f"cannot monitor formula node {type(f).__name__}")

    # ------------------------------------------------------------ settle signals
    def settle(self, f: A.Formula) -> list[float]:
        key = (id(f), 2)
        out = self.cache.get(key)
        if out is None:
            out = self.cache[key] = self._settle(f)
        return out

    def _settle(self, f: A.Formula) -> list[float]:
        if isinstance(f, (A.Const, A.Atom)):
            return self.mon.indices(self.L)
        if isinstance(f, (A.Not, A.Weighted)):
            return self.settle(f.child)
        if isinstance(f, (A.And, A.Or)):
            decisive = isinstance(f, A.Or)
            sides = [(self.sig(s, _BOOL), self.settle(s)) for s in (f.left, f.right)]
            return _junction(self.sig(f, _BOOL), decisive, sides)
        if isinstance(f, A.Implies):  # !left | right
            sides = [([not v for v in self.sig(f.left, _BOOL)], self.settle(f.left))]
            sides.append((self.sig(f.right, _BOOL), self.settle(f.right)))
            return _junction(self.sig(f, _BOOL), True, sides)
        if isinstance(f, A.Iff):
            return _pairwise(max, self.settle(f.left), self.settle(f.right))
        if isinstance(f, (A.Eventually, A.Globally)):
            decisive = isinstance(f, A.Eventually)
            lo, hi = self.offsets(f.interval)
            s, v = self.settle(f.child), self.sig(f.child, _BOOL)
            hit = _window([si if vi == decisive else _INF for vi, si in zip(v, s, strict=True)], lo, hi, min, _INF)
            every = _window(s, lo, hi, max, -_INF)
            value = self.sig(f, _BOOL)
            return _settled([h if x == decisive else e for x, h, e in zip(value, hit, every, strict=True)])
        if isinstance(f, A.Until):
            return self._settle_until(f.interval, self.sig(f.left, _BOOL), self.sig(f.right, _BOOL), f.left, f.right)
        if isinstance(f, A.Release):  # !left U !right
            left = [not v for v in self.sig(f.left, _BOOL)]
            right = [not v for v in self.sig(f.right, _BOOL)]
            return self._settle_until(f.interval, left, right, f.left, f.right)
        if isinstance(f, A.WeakUntil):  # (left U right) | G[0, sup I] left
            lo, hi = self.offsets(f.interval)
            vl, vr = self.sig(f.left, _BOOL), self.sig(f.right, _BOOL)
            u = _until(vl, vr, lo, hi, _BOOL)
            su = self._settle_until(f.interval, vl, vr, f.left, f.right, u)
            glo, ghi = self.offsets(_upto(f.interval))
            g = _window(vl, glo, ghi, _BOOL.meet, _BOOL.top)
            sl = self.settle(f.left)
            hit = _window([_INF if vi else si for vi, si in zip(vl, sl, strict=True)], glo, ghi, min, _INF)
            every = _window(sl, glo, ghi, max, -_INF)
            sg = _settled([e if x else h for x, h, e in zip(g, hit, every, strict=True)])
            return _junction(_pairwise(_BOOL.join, u, g), True, [(u, su), (g, sg)])
        raise CompileError(f"cannot monitor formula node {type(f).__name__}")

    def _settle_until(
        self,
        interval: A.Interval,
        vl: list,
        vr: list,
        left: A.Formula,
        right: A.Formula,
        value: list | None = None,
    ) -> list[float]:
        lo, hi = self.offsets(interval)
        sl, sr = self.settle(left), self.settle(right)
        neg = _REAL.neg
        # true: the earliest witness j with right settled true at k+j and left settled true before
        true_at = [
            neg(v)
            for v in _until(
                [neg(s if v else _INF) for v, s in zip(vl, sl, strict=True)],
                [neg(s if v else _INF) for v, s in zip(vr, sr, strict=True)],
                lo,
                hi,
                _REAL,
            )
        ]
        # false: every j of the window is refuted, by right settled false at k+j or left before it
        false_at = _until(
            [_INF if v else s for v, s in zip(vl, sl, strict=True)],
            [_INF if v else s for v, s in zip(vr, sr, strict=True)],
            lo,
            hi,
            _REAL,
        )
        if value is None:
            value = _until(vl, vr, lo, hi, _BOOL)
        return _settled([t if x else f for x, t, f in zip(value, true_at, false_at, strict=True)])

    # ------------------------------------------------------------ one sample of the root
    def _window_span(self, interval: A.Interval, k: int) -> tuple[int, int] | None:
        """The samples of an ``F``/``G`` window at ``k`` as :func:`_window` cuts them, None if empty."""
        lo, hi = self.offsets(interval)
        N = self.N
        if hi < lo or k + lo > N:
            return None
        return k + lo, min(k + int(min(hi, N)), N)

    def value_at(self, f: A.Formula, lat: _Lat, k: int) -> Any:
        """``sig(f, lat)[k]``; an ``F``/``G`` not yet computed over its window at ``k`` alone."""
        out = self.cache.get((id(f), lat is _REAL))
        if out is not None or not isinstance(f, (A.Eventually, A.Globally)):
            return (out if out is not None else self.sig(f, lat))[k]
        eventually = isinstance(f, A.Eventually)
        span = self._window_span(f.interval, k)
        if span is None:
            return lat.bottom if eventually else lat.top
        seg = self.sig(f.child, lat)[span[0] : span[1] + 1]
        if lat is _REAL:
            return max(seg) if eventually else min(seg)
        return (True in seg) if eventually else (False not in seg)

    def settle_at(self, f: A.Formula, k: int) -> float:
        """``settle(f)[k]``; an ``F``/``G`` not yet computed over its window at ``k`` alone."""
        out = self.cache.get((id(f), 2))
        if out is not None or not isinstance(f, (A.Eventually, A.Globally)):
            return (out if out is not None else self.settle(f))[k]
        decisive = isinstance(f, A.Eventually)
        span = self._window_span(f.interval, k)
        if span is None:
            return float(k)
        s, v = self.settle(f.child), self.sig(f.child, _BOOL)
        first, last = span
        if self.value_at(f, _BOOL, k) == decisive:  # its earliest decisive sample (one there is)
            at = min(s[j] for j in range(first, last + 1) if v[j] == decisive)
        else:  # every sample of the window settled
            at = max(s[first : last + 1])
        return at if -_INF < at < _INF else float(k)

    # ------------------------------------------------------------ blame
    def span(self, interval: A.Interval, k: int) -> tuple[int, int]:
        lo, hi = self.offsets(interval)
        if hi < lo:
            return k + lo, k + lo - 1
        return k + lo, int(min(k + hi, self.N))

    def blame(self, f: A.Formula, k: int) -> A.Formula:
        """For ``f`` false at sample ``k``: the smallest subformula responsible
        (:func:`mitlc.monitor.offline._blame_root`)."""
        while True:
            if isinstance(f, A.Weighted):
                f = f.child
            elif isinstance(f, A.And):
                failed = [s for s in (f.left, f.right) if not self.sig(s, _BOOL)[k]]
                f = min(failed, key=lambda s: self.settle(s)[k])
            elif isinstance(f, A.Implies):
                f = f.right
            elif isinstance(f, A.Globally):
                first, last = self.span(f.interval, k)
                truth, settle = self.sig(f.child, _BOOL), self.settle(f.child)
                when = [_INF if truth[j] else settle[j] for j in range(first, last + 1)]
                k = first + when.index(min(when))
                f = f.child
            elif isinstance(f, A.Until):
                first, last = self.span(f.interval, k)
                stop = _first(self.sig(f.left, _BOOL), k, self.N, False)
                if first <= last and stop is not None and stop < last:
                    f, k = f.left, stop  # left failed before right came
                else:
                    return f  # the window passed without a witness
            elif isinstance(f, A.Release):
                first, last = self.span(f.interval, k)
                stop = _first(self.sig(f.left, _BOOL), k, self.N, True)
                end = last if stop is None else min(last, stop)
                witness = _first(self.sig(f.right, _BOOL), first, end, False)
                if witness is None:  # pragma: no cover - f is false, so !left U !right has a witness
                    return f
                f, k = f.right, witness
            elif isinstance(f, A.WeakUntil):
                _, last = self.span(_upto(f.interval), k)
                stop = _first(self.sig(f.left, _BOOL), k, last, False)
                if stop is None:  # pragma: no cover - f is false, so G[0,sup I] left fails
                    return f
                f, k = f.left, stop
            elif isinstance(f, (A.Const, A.Atom, A.Not, A.Or, A.Iff, A.Eventually)):
                return f
            else:
                raise CompileError(f"cannot monitor formula node {type(f).__name__}")


def _junction(value: list, decisive: bool, sides: list[tuple[list, list[float]]]) -> list[float]:
    """An & (decisive value False) or an | (True): settled by its earliest decisive side when it
    has that value, else when both sides are settled."""
    (va, sa), (vb, sb) = sides
    out = []
    for x, a, s1, b, s2 in zip(value, va, sa, vb, sb, strict=True):
        if x == decisive:
            e1 = s1 if a == decisive else _INF
            e2 = s2 if b == decisive else _INF
            out.append(e1 if e1 <= e2 else e2)
        else:
            out.append(s1 if s1 >= s2 else s2)
    return out


class ScalarTraceMonitor:
    """Judge whole traces of one run by ``formula`` (default: the spec's ``check`` line, else its
    ``formula``) as :func:`~mitlc.monitor.offline.monitor` judges them, on Python numbers.

    ``dt`` is the sample time in seconds; :meth:`judge` takes the samples as rows of floats in
    ``columns`` order (default: :func:`~mitlc.monitor.offline.state_columns`), or each
    proposition's truth and robustness signals already computed on them
    (:meth:`judge_signals`, what :class:`~mitlc.monitor.scalar.ScalarOnlineMonitor` keeps).
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
        self.names = sorted({f.name for f in A.walk(self.formula) if isinstance(f, A.Atom)})
        where = {n: i for i, n in enumerate(self.columns)}
        self._preds: list[tuple[str, Callable[[Sequence[float]], tuple[bool, float]]]] = [
            (n, _pred_compiled(spec.prop(n).pred, where)) for n in self.names
        ]
        self._quiet = any(_may_warn(spec.prop(n).pred) for n in self.names)
        plant = spec.plant
        periodic = {v.name for v in plant.state if v.periodic} if plant is not None else set()
        self._wrap = [where[n] for n in self.needed if n in periodic]
        self._check = [(where[n], n) for n in self.needed]
        self._offsets: dict[A.Interval, tuple[int, float]] = {}
        self._texts: dict[int, str] = {}
        self._indices: list[float] = []

    def indices(self, length: int) -> list[float]:
        """``[0.0, 1.0, .. length - 1]``: when each sample of a proposition settles (one list, read only)."""
        if len(self._indices) != length:
            self._indices = [float(i) for i in range(length)]
        return self._indices

    def offsets(self, interval: A.Interval) -> tuple[int, float]:
        out = self._offsets.get(interval)
        if out is None:
            out = self._offsets[interval] = A.offsets(interval, self.dt)
        return out

    def judge(self, rows: Sequence[Sequence[float]]) -> tuple[bool, float, float | None, str | None]:
        """``satisfied``, ``robustness``, ``violation_time`` (None where satisfied) and ``failing``
        (None where satisfied) of the trace ``rows`` (samples ``0 .. N``)."""
        if not len(rows):
            raise InputError("a trace needs at least one sample")
        columns = list(zip(*rows, strict=True))
        for i, n in self._check:
            if not all(map(math.isfinite, columns[i])):
                k = next(k for k, v in enumerate(columns[i]) if not math.isfinite(v))
                raise InputError(f"state variable '{n}' is not finite (run 0, sample {k}: {columns[i][k]})")
        if self._wrap:  # wrap_angle's operations on a float (numpy's remainder is Python's %)
            for i in self._wrap:
                columns[i] = tuple([(v + math.pi) % _TWO_PI - math.pi for v in columns[i]])
            rows = list(zip(*columns, strict=True))
        truth: dict[str, list] = {}
        rob: dict[str, list] = {}
        with np.errstate(all="ignore") if self._quiet else contextlib.nullcontext():
            for n, pred in self._preds:
                both = [pred(x) for x in rows]
                truth[n] = [t for t, _ in both]
                rob[n] = [r for _, r in both]
        return self.judge_signals(truth, rob, len(rows))

    def judge_signals(
        self, truth: dict[str, list], rob: dict[str, list], length: int
    ) -> tuple[bool, float, float | None, str | None]:
        """:meth:`judge` from each proposition's truth and robustness on the ``length`` samples
        (lists keyed by proposition, every proposition of the formula)."""
        run = _Run(self, truth, rob, length)
        f = self.formula
        satisfied = bool(run.value_at(f, _BOOL, 0))
        robustness = float(run.value_at(f, _REAL, 0))
        if satisfied:
            return True, robustness, None, None
        violation = run.settle_at(f, 0) * self.dt
        part = run.blame(f, 0)
        text = self._texts.get(id(part))
        if text is None:
            text = self._texts[id(part)] = str(part)
        return False, robustness, violation, text
