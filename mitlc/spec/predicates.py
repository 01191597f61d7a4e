"""Predicates over a plant's state: syntax trees, vectorised evaluation, regions.

A proposition such as ``prop psi = 0.3 < q < pi/2 + 0.5`` is parsed into the
small expression tree below.  It is *data*: it is evaluated by walking the tree
with numpy (never with ``eval``), on whole batches of states at once.

:func:`region` computes, by interval analysis, the set of states where a
predicate holds as a union of boxes, when it can; :func:`provably_disjoint`
uses it to decide whether propositions can share one region net.

>>> import numpy as np
>>> from mitlc.spec.predicates import Var, Num, Compare, Call, evaluate
>>> kappa = Compare((Call("abs", (Var("q"),)), Num(0.3)), ("<",))
>>> print(kappa)
abs(q) < 0.3
>>> evaluate(kappa, {"q": np.array([0.1, -0.5])})
array([ True, False])
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

from mitlc.spec.ast import Pos, fmt_number

__all__ = [
    "Pred",
    "Num",
    "Var",
    "Neg",
    "BinOp",
    "Call",
    "Compare",
    "PAnd",
    "POr",
    "PNot",
    "FUNCTIONS",
    "CONSTANTS",
    "COMPARISONS",
    "evaluate",
    "compile_numpy",
    "variables",
    "is_boolean",
    "const_value",
    "IntervalSet",
    "Box",
    "Region",
    "Domains",
    "region",
    "regions_disjoint",
    "provably_disjoint",
    "provably_empty",
    "readable_name",
]


class Pred:
    """Base class of predicate expression nodes."""

    __slots__ = ()

    @property
    def children(self) -> tuple[Pred, ...]:
        return ()


_P_OR, _P_AND, _P_NOT, _P_CMP, _P_ADD, _P_MUL, _P_NEG, _P_ATOM = range(1, 9)


def _wrap(node: Pred, min_prec: int) -> str:
    text = str(node)
    return f"({text})" if node.prec < min_prec else text  # type: ignore[attr-defined]


@dataclass(frozen=True, slots=True)
class Num(Pred):
    value: float
    name: str | None = field(default=None, compare=False)  # "pi" prints as pi
    prec = _P_ATOM

    def __str__(self) -> str:
        return self.name or fmt_number(self.value)


@dataclass(frozen=True, slots=True)
class Var(Pred):
    name: str
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _P_ATOM

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True, slots=True)
class Neg(Pred):
    arg: Pred
    prec = _P_NEG

    @property
    def children(self) -> tuple[Pred, ...]:
        return (self.arg,)

    def __str__(self) -> str:
        return "-" + _wrap(self.arg, _P_NEG)


@dataclass(frozen=True, slots=True)
class BinOp(Pred):
    op: str  # one of + - * /
    left: Pred
    right: Pred

    @property
    def prec(self) -> int:
        return _P_ADD if self.op in "+-" else _P_MUL

    @property
    def children(self) -> tuple[Pred, ...]:
        return (self.left, self.right)

    def __str__(self) -> str:
        p = self.prec
        return f"{_wrap(self.left, p)} {self.op} {_wrap(self.right, p + 1)}"


FUNCTIONS: dict[str, tuple[int, Callable[..., np.ndarray]]] = {
    "abs": (1, np.abs),
    "sqrt": (1, np.sqrt),
    "sin": (1, np.sin),
    "cos": (1, np.cos),
    "tan": (1, np.tan),
    "exp": (1, np.exp),
    "min": (2, np.minimum),
    "max": (2, np.maximum),
    "atan2": (2, np.arctan2),
}
"""Functions a predicate may call: name -> (arity, vectorised implementation)."""

CONSTANTS: dict[str, float] = {"pi": math.pi, "e": math.e}
"""Named constants a predicate may use (``inf`` is a keyword)."""


@dataclass(frozen=True, slots=True)
class Call(Pred):
    fn: str
    args: tuple[Pred, ...]
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _P_ATOM

    @property
    def children(self) -> tuple[Pred, ...]:
        return self.args

    def __str__(self) -> str:
        return f"{self.fn}({', '.join(str(a) for a in self.args)})"


COMPARISONS: dict[str, Callable[[np.ndarray | float, np.ndarray | float], np.ndarray]] = {
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
    "==": np.equal,
    "!=": np.not_equal,
}
"""The comparison operators of the spec language and their numpy functions."""
_CMP = COMPARISONS


@dataclass(frozen=True, slots=True)
class Compare(Pred):
    """A chained comparison ``a < b <= c``: true where every link holds."""

    operands: tuple[Pred, ...]
    ops: tuple[str, ...]
    prec = _P_CMP

    @property
    def children(self) -> tuple[Pred, ...]:
        return self.operands

    def __str__(self) -> str:
        out = [_wrap(self.operands[0], _P_ADD)]
        for op, rhs in zip(self.ops, self.operands[1:], strict=True):
            out += [op, _wrap(rhs, _P_ADD)]
        return " ".join(out)


@dataclass(frozen=True, slots=True)
class PAnd(Pred):
    left: Pred
    right: Pred
    prec = _P_AND

    @property
    def children(self) -> tuple[Pred, ...]:
        return (self.left, self.right)

    def __str__(self) -> str:
        return f"{_wrap(self.left, _P_AND)} and {_wrap(self.right, _P_AND + 1)}"


@dataclass(frozen=True, slots=True)
class POr(Pred):
    left: Pred
    right: Pred
    prec = _P_OR

    @property
    def children(self) -> tuple[Pred, ...]:
        return (self.left, self.right)

    def __str__(self) -> str:
        return f"{_wrap(self.left, _P_OR)} or {_wrap(self.right, _P_OR + 1)}"


@dataclass(frozen=True, slots=True)
class PNot(Pred):
    arg: Pred
    prec = _P_NOT

    @property
    def children(self) -> tuple[Pred, ...]:
        return (self.arg,)

    def __str__(self) -> str:
        return "not " + _wrap(self.arg, _P_NOT)


def walk(p: Pred) -> Iterator[Pred]:
    stack = [p]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(reversed(node.children))


def variables(p: Pred) -> tuple[Var, ...]:
    """The variable references of ``p`` in order of appearance."""
    return tuple(n for n in walk(p) if isinstance(n, Var))


def is_boolean(p: Pred) -> bool:
    """True if ``p`` is a truth-valued expression (comparison or connective)."""
    return isinstance(p, (Compare, PAnd, POr, PNot))


_S = TypeVar("_S")  # whatever the compiled closure reads state variables from


def compile_numpy(
    p: Pred, var: Callable[[str], Callable[[_S], np.ndarray | float]]
) -> Callable[[_S], np.ndarray | float]:
    """Turn a predicate tree into one closure over a batch of states.

    ``var(name)`` returns how to read a state variable from the closure's
    argument (a column of an array, an entry of a dict).  Constant subtrees
    are folded and each node becomes one numpy call.  Floating-point warnings
    are the caller's business (see :func:`evaluate`).

    >>> f = compile_numpy(Compare((Var("x"), Num(1.0)), ("<",)), lambda name: lambda x: x[:, 0])
    >>> f(np.array([[0.5], [2.0]]))
    array([ True, False])
    """
    return _compile(p, var, fold=True)


def _compile(
    p: Pred, var: Callable[[str], Callable[[_S], np.ndarray | float]], fold: bool
) -> Callable[[_S], np.ndarray | float]:
    value = p.value if isinstance(p, Num) else const_value(p) if fold else None
    if value is not None:

        def constant(x: _S, v: float = float(value)) -> float:
            return v

        return constant
    if isinstance(p, Var):
        return var(p.name)
    if isinstance(p, Neg):
        f = _compile(p.arg, var, fold)
        return lambda x: np.negative(f(x))
    if isinstance(p, BinOp):
        op = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide}[p.op]
        fl, fr = _compile(p.left, var, fold), _compile(p.right, var, fold)
        return lambda x: op(fl(x), fr(x))
    if isinstance(p, Call):
        _, fn = FUNCTIONS[p.fn]
        fs = [_compile(a, var, fold) for a in p.args]
        if len(fs) == 1:
            f0 = fs[0]
            return lambda x: fn(f0(x))
        return lambda x: fn(*(f(x) for f in fs))
    if isinstance(p, Compare):
        fs = [_compile(o, var, fold) for o in p.operands]
        cmps = [COMPARISONS[op] for op in p.ops]
        if len(cmps) == 1:
            c0, a0, b0 = cmps[0], fs[0], fs[1]
            return lambda x: c0(a0(x), b0(x))

        def chain(x: _S) -> np.ndarray:
            values = [f(x) for f in fs]
            out = cmps[0](values[0], values[1])
            for c, a, b in zip(cmps[1:], values[1:], values[2:], strict=False):
                out = out & c(a, b)
            return out

        return chain
    if isinstance(p, (PAnd, POr)):
        conn = np.logical_and if isinstance(p, PAnd) else np.logical_or
        fl, fr = _compile(p.left, var, fold), _compile(p.right, var, fold)
        return lambda x: conn(fl(x), fr(x))
    if isinstance(p, PNot):
        f = _compile(p.arg, var, fold)
        return lambda x: np.logical_not(f(x))
    raise TypeError(f"not a predicate node: {p!r}")


def evaluate(p: Pred, env: Mapping[str, np.ndarray | float]) -> np.ndarray:
    """Evaluate ``p`` elementwise over arrays of state values (broadcasting)."""
    f: Callable[[Mapping[str, np.ndarray | float]], np.ndarray | float]
    f = compile_numpy(p, lambda name: lambda e: np.asarray(e[name], dtype=float))
    with np.errstate(all="ignore"):  # IEEE arithmetic: exp(exp(q)) past 1e308 is inf, and inf > 5 holds
        return np.asarray(f(env))


def const_value(p: Pred) -> float | None:
    """The value of a variable-free arithmetic expression, else None."""
    if variables(p) or is_boolean(p):
        return None
    if isinstance(p, Num):
        return float(p.value)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        f: Callable[[None], np.ndarray | float] = _compile(p, lambda name: lambda e: np.nan, fold=False)
        return float(f(None))


# ----------------------------------------------------------------- regions


@dataclass(frozen=True, slots=True)
class IntervalSet:
    """A finite union of real intervals, kept sorted and merged.

    Each piece is ``(lo, hi, lo_closed, hi_closed)``.

    >>> a = IntervalSet.of(-0.3, 0.3, False, False)
    >>> b = IntervalSet.of(0.3, 2.07, False, False)
    >>> a.intersect(b).is_empty
    True
    >>> str(a.complement())
    '(-inf,-0.3] u [0.3,inf)'
    """

    pieces: tuple[tuple[float, float, bool, bool], ...]

    @staticmethod
    def of(lo: float, hi: float, lo_closed: bool = True, hi_closed: bool = True) -> IntervalSet:
        return IntervalSet._norm([(lo, hi, lo_closed, hi_closed)])

    @staticmethod
    def full() -> IntervalSet:
        return IntervalSet.of(-math.inf, math.inf, False, False)

    @staticmethod
    def empty() -> IntervalSet:
        return IntervalSet(())

    @staticmethod
    def _norm(pieces: Sequence[tuple[float, float, bool, bool]]) -> IntervalSet:
        keep = []
        for lo, hi, lc, hc in pieces:
            lc = lc and not math.isinf(lo)
            hc = hc and not math.isinf(hi)
            if lo < hi or (lo == hi and lc and hc):
                keep.append((lo, hi, lc, hc))
        keep.sort(key=lambda p: (p[0], not p[2]))
        merged: list[tuple[float, float, bool, bool]] = []
        for piece in keep:
            if merged:
                lo, hi, lc, hc = merged[-1]
                nlo, nhi, nlc, nhc = piece
                if nlo < hi or (nlo == hi and (hc or nlc)):
                    if nhi > hi or (nhi == hi and nhc):
                        merged[-1] = (lo, nhi, lc, nhc)
                    continue
            merged.append(piece)
        return IntervalSet(tuple(merged))

    @property
    def is_empty(self) -> bool:
        return not self.pieces

    def union(self, other: IntervalSet) -> IntervalSet:
        return IntervalSet._norm(self.pieces + other.pieces)

    def intersect(self, other: IntervalSet) -> IntervalSet:
        out = []
        for lo1, hi1, lc1, hc1 in self.pieces:
            for lo2, hi2, lc2, hc2 in other.pieces:
                lo, lc = (lo1, lc1) if (lo1 > lo2 or (lo1 == lo2 and not lc1)) else (lo2, lc2)
                hi, hc = (hi1, hc1) if (hi1 < hi2 or (hi1 == hi2 and not hc1)) else (hi2, hc2)
                out.append((lo, hi, lc, hc))
        return IntervalSet._norm(out)

    def complement(self) -> IntervalSet:
        out = []
        lo, lc = -math.inf, False
        for plo, phi, plc, phc in self.pieces:
            out.append((lo, plo, lc, not plc))
            lo, lc = phi, not phc
        out.append((lo, math.inf, lc, False))
        return IntervalSet._norm(out)

    def __str__(self) -> str:
        if not self.pieces:
            return "{}"
        return " u ".join(
            f"{'[' if lc else '('}{fmt_number(lo) if not math.isinf(lo) else '-inf'},"
            f"{fmt_number(hi)}{']' if hc else ')'}"
            for lo, hi, lc, hc in self.pieces
        )


Box = tuple[tuple[str, IntervalSet], ...]
"""A box: constrained variables with their interval sets (others unconstrained)."""

Region = tuple[Box, ...]
"""A union of boxes; ``()`` is the empty set, ``((),)`` the whole space."""

Domains = Mapping[str, IntervalSet]


def _box_get(box: Box, var: str, domains: Domains) -> IntervalSet:
    for name, s in box:
        if name == var:
            return s
    return domains.get(var, IntervalSet.full())


def _box_intersect(a: Box, b: Box, domains: Domains) -> Box | None:
    names = sorted({n for n, _ in a} | {n for n, _ in b})
    out = []
    for n in names:
        s = _box_get(a, n, domains).intersect(_box_get(b, n, domains))
        if s.is_empty:
            return None
        out.append((n, s))
    return tuple(out)


def _linear(p: Pred) -> tuple | None:
    """Classify an arithmetic expression as const, a*v+b, or a*|v|+b."""
    if isinstance(p, Num):
        return ("const", p.value)
    if isinstance(p, Var):
        return ("lin", p.name, 1.0, 0.0)
    if isinstance(p, Neg):
        inner = _linear(p.arg)
        return None if inner is None else _scale(inner, -1.0)
    if isinstance(p, Call):
        c = const_value(p)
        if c is not None:
            return ("const", c)
        if p.fn == "abs":
            inner = _linear(p.args[0])
            if inner and inner[0] == "lin" and inner[3] == 0.0:
                return ("abs", inner[1], abs(inner[2]), 0.0)
        return None
    if isinstance(p, BinOp):
        a, b = _linear(p.left), _linear(p.right)
        if a is None or b is None:
            return None
        if p.op in "+-":
            sign = 1.0 if p.op == "+" else -1.0
            if b[0] == "const":
                return _shift(a, sign * b[1])
            if a[0] == "const":
                return _shift(_scale(b, sign), a[1])
            if a[0] == b[0] == "lin" and a[1] == b[1]:
                return ("lin", a[1], a[2] + sign * b[2], a[3] + sign * b[3])
            return None
        if p.op == "*":
            if a[0] == "const":
                return _scale(b, a[1])
            if b[0] == "const":
                return _scale(a, b[1])
            return None
        if b[0] == "const" and b[1] != 0:
            return _scale(a, 1.0 / b[1])
    return None


def _scale(form: tuple, k: float) -> tuple:
    if form[0] == "const":
        return ("const", form[1] * k)
    return (form[0], form[1], form[2] * k, form[3] * k)


def _shift(form: tuple, d: float) -> tuple:
    if form[0] == "const":
        return ("const", form[1] + d)
    return (form[0], form[1], form[2], form[3] + d)


_FLIP = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}


def _half(op: str, k: float) -> IntervalSet:
    """The set ``{v : v op k}``."""
    if op == "<":
        return IntervalSet.of(-math.inf, k, False, False)
    if op == "<=":
        return IntervalSet.of(-math.inf, k, False, True)
    if op == ">":
        return IntervalSet.of(k, math.inf, False, False)
    if op == ">=":
        return IntervalSet.of(k, math.inf, True, False)
    point = IntervalSet.of(k, k)
    return point if op == "==" else point.complement()


def _compare_region(lhs: Pred, op: str, rhs: Pred, domains: Domains) -> Region | None:
    a, b = _linear(lhs), _linear(rhs)
    if a is None or b is None:
        return None
    if a[0] == "const" and b[0] == "const":
        return ((),) if bool(_CMP[op](a[1], b[1])) else ()
    if a[0] == "const":
        a, b, op = b, a, _FLIP[op]
    if b[0] != "const":
        if a[0] == b[0] == "lin" and a[1] == b[1]:
            a, b = ("lin", a[1], a[2] - b[2], a[3] - b[3]), ("const", 0.0)
            if a[2] == 0:
                return ((),) if bool(_CMP[op](a[3], 0.0)) else ()
        else:
            return None
    kind, var, coef, off = a
    if coef == 0:
        return ((),) if bool(_CMP[op](off, b[1])) else ()
    k = (b[1] - off) / coef
    if coef < 0:
        op = _FLIP[op]
    if kind == "lin":
        s = _half(op, k)
    elif op in ("<", "<="):  # |v| < k  is  -k < v < k
        s = _half(op, k).intersect(_half(_FLIP[op], -k))
    elif op in (">", ">="):  # |v| > k  is  not (|v| <= k)
        weak = {">": "<=", ">=": "<"}[op]
        s = _half(weak, k).intersect(_half(_FLIP[weak], -k)).complement()
    else:
        points = IntervalSet.of(k, k).union(IntervalSet.of(-k, -k)) if k >= 0 else IntervalSet.empty()
        s = points if op == "==" else points.complement()
    s = s.intersect(domains.get(var, IntervalSet.full()))
    return () if s.is_empty else (((var, s),),)


def _and(a: Region, b: Region, domains: Domains) -> Region:
    out = []
    for x in a:
        for y in b:
            box = _box_intersect(x, y, domains)
            if box is not None:
                out.append(box)
    return tuple(out)


def _not(a: Region, domains: Domains) -> Region | None:
    if not a:
        return ((),)
    names = {n for box in a for n, _ in box}
    if not names:
        return ()  # complement of everything
    if len(names) > 1:
        return None
    (var,) = names
    union = IntervalSet.empty()
    for box in a:
        union = union.union(_box_get(box, var, domains))
    s = union.complement().intersect(domains.get(var, IntervalSet.full()))
    return () if s.is_empty else (((var, s),),)


def region(p: Pred, domains: Domains | None = None) -> Region | None:
    """The set where boolean predicate ``p`` holds, as a union of boxes, or None.

    None means the analysis cannot tell (a nonlinear or multi-variable comparison).
    ``domains`` bounds each variable (for the pendulum, ``q`` in ``[-pi, pi]``).

    >>> from mitlc.spec.predicates import Compare, Var, Num
    >>> r = region(Compare((Num(0.3), Var("q"), Num(2.0)), ("<", "<")))
    >>> [(v, str(s)) for box in r for v, s in box]
    [('q', '(0.3,2)')]
    """
    doms: Domains = domains or {}
    if isinstance(p, Compare):
        out: Region = ((),)
        for lhs, op, rhs in zip(p.operands, p.ops, p.operands[1:], strict=False):
            r = _compare_region(lhs, op, rhs, doms)
            if r is None:
                return None
            out = _and(out, r, doms)
        return out
    if isinstance(p, PAnd):
        a, b = region(p.left, doms), region(p.right, doms)
        return None if a is None or b is None else _and(a, b, doms)
    if isinstance(p, POr):
        a, b = region(p.left, doms), region(p.right, doms)
        return None if a is None or b is None else a + b
    if isinstance(p, PNot):
        a = region(p.arg, doms)
        return None if a is None else _not(a, doms)
    return None


def provably_disjoint(a: Pred, b: Pred, domains: Domains | None = None) -> bool:
    """True if interval analysis proves that ``a`` and ``b`` never hold together.

    >>> from mitlc.spec.predicates import Compare, Var, Num, Call
    >>> kappa = Compare((Call("abs", (Var("q"),)), Num(0.3)), ("<",))
    >>> psi = Compare((Num(0.3), Var("q"), Num(2.07)), ("<", "<"))
    >>> upsilon = Compare((Call("abs", (Var("qdot"),)), Num(10.0)), ("<",))
    >>> provably_disjoint(kappa, psi), provably_disjoint(kappa, upsilon)
    (True, False)
    """
    doms: Domains = domains or {}
    ra, rb = region(a, doms), region(b, doms)
    if ra is None or rb is None:
        return False
    return regions_disjoint(ra, rb, doms)


def regions_disjoint(a: Region, b: Region, domains: Domains | None = None) -> bool:
    """True if no box of ``a`` meets a box of ``b`` (:func:`region`'s results)."""
    return not _and(a, b, domains or {})


def provably_empty(p: Pred, domains: Domains | None = None) -> bool:
    """True if interval analysis proves that ``p`` holds nowhere in the domains.

    >>> from mitlc.spec.predicates import Compare, Var, Num, PNot
    >>> provably_empty(PNot(Compare((Var("q"), Num(9.0)), ("<",))), {"q": IntervalSet.of(-3.2, 3.2)})
    True
    """
    r = region(p, domains or {})
    return r is not None and not r


_WORDS = {"<=": "le", ">=": "ge", "==": "eq", "!=": "ne", "<": "lt", ">": "gt", "+": "plus", "-": "minus"}
_WORDS.update({"*": "times", "/": "over"})
_NAME_MAX = 24


def readable_name(p: Pred) -> str:
    """A proposition name for an inline predicate, read off its text.

    Operators become words and a decimal point ``p``; past 24 characters the
    name keeps its first whole words and ends in four hex digits of the whole
    text (still unique).

    >>> from mitlc.spec.parse import parse_predicate
    >>> readable_name(parse_predicate("abs(q) < 0.3"))
    'abs_q_lt_0p3'
    >>> readable_name(parse_predicate("x >= -0.45"))
    'x_ge_minus_0p45'
    >>> readable_name(parse_predicate("0.3 < q < pi/2 + 0.5"))
    'c_0p3_lt_q_lt_pi_d095'
    """
    import hashlib
    import re

    text = str(p)
    parts = []
    for tok in re.findall(r"<=|>=|==|!=|[<>+\-*/]|[A-Za-z_][A-Za-z0-9_]*|[0-9.]+(?:e[+-]?[0-9]+)?|\[[0-9]+\]", text):
        if tok in _WORDS:
            parts.append(_WORDS[tok])
        elif tok.startswith("["):
            parts.append(tok[1:-1])
        else:
            parts.append(tok.replace(".", "p").replace("+", "").replace("-", "m"))
    if not (parts[0][:1].isalpha() or parts[0][:1] == "_"):
        parts.insert(0, "c")
    name = "_".join(parts)
    if len(name) > _NAME_MAX:  # whole words up to the limit, then a digest of the whole text
        kept: list[str] = []
        for part in parts:
            if len("_".join([*kept, part])) > _NAME_MAX - 5:
                break
            kept.append(part)
        name = "_".join(kept or [parts[0][: _NAME_MAX - 5]]) + "_" + hashlib.sha1(text.encode()).hexdigest()[:4]
    return name
