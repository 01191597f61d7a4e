"""Immutable syntax trees of MITL formulas.

A handful of frozen, slotted node types.  Every node has ``children`` and
prints as MITL text that parses back to an equal tree (``parse(str(f)) == f``).
Source positions are kept for error messages but do not take part in equality.

>>> from mitlc.spec.ast import Atom, Eventually, Globally, Not, And, Weighted
>>> f = And(Eventually(Globally(Atom("kappa"))), Weighted(10.0, Globally(Not(Atom("psi")))))
>>> print(f)
F G kappa & 10 * G !psi
>>> (Atom("a") & ~Atom("b")) | Atom("c")
Or(left=And(left=Atom(name='a'), right=Not(child=Atom(name='b'))), right=Atom(name='c'))
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field

__all__ = [
    "Pos",
    "Interval",
    "TIME_TOL",
    "offsets",
    "Formula",
    "Const",
    "Atom",
    "Not",
    "And",
    "Or",
    "Implies",
    "Iff",
    "Eventually",
    "Globally",
    "Until",
    "Release",
    "WeakUntil",
    "Weighted",
    "UNBOUNDED",
    "fmt_number",
    "walk",
    "atoms",
    "depth",
    "nesting",
    "size",
]


@dataclass(frozen=True, slots=True)
class Pos:
    """A position in the spec text (1-based line and column)."""

    line: int
    column: int


def fmt_number(x: float) -> str:
    """Print a number so that it parses back to the same float.

    >>> fmt_number(2.0), fmt_number(0.5), fmt_number(math.inf)
    ('2', '0.5', 'inf')
    """
    if math.isinf(x):
        return "inf"
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return repr(float(x))


@dataclass(frozen=True, slots=True)
class Interval:
    """A time interval with open or closed ends; ``hi`` may be ``inf``.

    >>> str(Interval(1, 2, lo_closed=False))
    '(1,2]'
    >>> Interval(0, math.inf).is_unbounded
    True
    """

    lo: float
    hi: float
    lo_closed: bool = True
    hi_closed: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "lo", float(self.lo))
        object.__setattr__(self, "hi", float(self.hi))
        if math.isinf(self.hi):
            object.__setattr__(self, "hi_closed", False)

    @property
    def is_unbounded(self) -> bool:
        """True for ``[0, inf)``, the interval of the untimed operators."""
        return self.lo == 0 and self.lo_closed and math.isinf(self.hi)

    def contains(self, t: float) -> bool:
        lo_ok = t >= self.lo if self.lo_closed else t > self.lo
        hi_ok = t <= self.hi if self.hi_closed else t < self.hi
        return lo_ok and hi_ok

    def __str__(self) -> str:
        left = "[" if self.lo_closed else "("
        right = "]" if self.hi_closed else ")"
        return f"{left}{fmt_number(self.lo)},{fmt_number(self.hi)}{right}"


UNBOUNDED = Interval(0.0, math.inf)


TIME_TOL = 1e-9
"""Tolerance (seconds, relative to the bound when it exceeds 1) when a sample
time is compared with an interval end."""


_BEYOND = 2**62  # a sample offset no trace reaches


def offsets(interval: Interval, dt: float) -> tuple[int, float]:
    """Sample offsets ``(lo, hi)`` of ``interval``: ``j`` is in it iff ``lo <= j <= hi``.

    ``hi`` is ``inf`` for an unbounded interval; ``lo > hi`` means no sample
    offset falls in the interval.

    >>> offsets(Interval(1, 2, lo_closed=False), 0.5)
    (3, 4)
    >>> offsets(Interval(0, 1, hi_closed=False), 0.5)
    (0, 1)
    >>> offsets(Interval(0.3, 0.6), 0.1)
    (3, 6)
    >>> offsets(Interval(0.1, 0.2, False, False), 0.5)
    (1, 0)
    >>> offsets(UNBOUNDED, 0.03)
    (0, inf)
    """
    lo_tol = TIME_TOL * max(1.0, abs(interval.lo))
    q = (interval.lo - lo_tol if interval.lo_closed else interval.lo + lo_tol) / dt
    if not q < _BEYOND:  # past any trace (1e308 s at 0.03 s): no sample offset reaches it
        return _BEYOND, math.inf if math.isinf(interval.hi) else float(_BEYOND - 1)
    lo = math.ceil(q) if interval.lo_closed else math.floor(q) + 1
    lo = max(lo, 0)
    if math.isinf(interval.hi):
        return lo, math.inf
    hi_tol = TIME_TOL * max(1.0, abs(interval.hi))
    if interval.hi_closed:
        x = (interval.hi + hi_tol) / dt
        if not x < _BEYOND:  # past any trace: as good as unbounded
            return lo, math.inf
        hi = math.floor(x)
    else:
        x = (interval.hi - hi_tol) / dt
        if not x < _BEYOND:
            return lo, math.inf
        hi = math.ceil(x) - 1
    return lo, hi


# Binding strength used by the printer; higher binds tighter.
_PREC_IFF, _PREC_IMPLIES, _PREC_OR, _PREC_AND, _PREC_TEMPORAL, _PREC_UNARY, _PREC_ATOM = range(1, 8)


class Formula:
    """Base class of formula nodes."""

    __slots__ = ()
    prec: int = _PREC_ATOM

    @property
    def children(self) -> tuple[Formula, ...]:
        return ()

    def __and__(self, other: Formula) -> Formula:
        return And(self, other)

    def __or__(self, other: Formula) -> Formula:
        return Or(self, other)

    def __invert__(self) -> Formula:
        return Not(self)

    def __str__(self) -> str:
        return _text(self)

    def _show(self, kids: list[str]) -> str:  # pragma: no cover - every node overrides
        """This node's text, given its children's."""
        raise NotImplementedError


def _text(f: Formula) -> str:
    """``f`` as MITL text, built children first from an explicit stack (no recursion, so any
    depth prints; node ids are keys, safe while ``f`` holds its nodes)."""
    done: dict[int, str] = {}
    stack: list[tuple[Formula, bool]] = [(f, False)]
    while stack:
        node, ready = stack.pop()
        if id(node) in done:
            continue
        if ready:
            done[id(node)] = node._show([done[id(c)] for c in node.children])
        else:
            stack.append((node, True))
            stack.extend((c, False) for c in node.children)
    return done[id(f)]


def _wrap(f: Formula, text: str, min_prec: int) -> str:
    return f"({text})" if f.prec < min_prec else text


def _interval_text(interval: Interval | None) -> str:
    if interval is None or interval == UNBOUNDED:
        return ""
    return str(interval)


@dataclass(frozen=True, slots=True)
class Const(Formula):
    value: bool
    pos: Pos | None = field(default=None, compare=False, repr=False)

    def _show(self, kids: list[str]) -> str:
        return "true" if self.value else "false"


@dataclass(frozen=True, slots=True)
class Atom(Formula):
    """A proposition by name; an inline predicate (``G (abs(q) < 0.3)``) also carries
    its predicate and prints as it (the name is chosen from it: ``abs_q_lt_0p3``)."""

    name: str
    pos: Pos | None = field(default=None, compare=False, repr=False)
    pred: object | None = field(default=None, compare=False, repr=False)

    def _show(self, kids: list[str]) -> str:
        return self.name if self.pred is None else f"({self.pred})"


@dataclass(frozen=True, slots=True)
class Not(Formula):
    child: Formula
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _PREC_UNARY

    @property
    def children(self) -> tuple[Formula, ...]:
        return (self.child,)

    def _show(self, kids: list[str]) -> str:
        return "!" + _wrap(self.child, kids[0], _PREC_UNARY)


@dataclass(frozen=True, slots=True)
class Weighted(Formula):
    """``w * phi``: the reward of ``phi`` multiplied by ``w`` (no effect on truth)."""

    weight: float
    child: Formula
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _PREC_UNARY

    def __post_init__(self) -> None:
        object.__setattr__(self, "weight", float(self.weight))

    @property
    def children(self) -> tuple[Formula, ...]:
        return (self.child,)

    def _show(self, kids: list[str]) -> str:
        return f"{fmt_number(self.weight)} * {_wrap(self.child, kids[0], _PREC_UNARY)}"


@dataclass(frozen=True, slots=True)
class Eventually(Formula):
    child: Formula
    interval: Interval = UNBOUNDED
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _PREC_UNARY

    @property
    def children(self) -> tuple[Formula, ...]:
        return (self.child,)

    def _show(self, kids: list[str]) -> str:
        return f"F{_interval_text(self.interval)} {_wrap(self.child, kids[0], _PREC_UNARY)}"


@dataclass(frozen=True, slots=True)
class Globally(Formula):
    child: Formula
    interval: Interval = UNBOUNDED
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _PREC_UNARY

    @property
    def children(self) -> tuple[Formula, ...]:
        return (self.child,)

    def _show(self, kids: list[str]) -> str:
        return f"G{_interval_text(self.interval)} {_wrap(self.child, kids[0], _PREC_UNARY)}"


class _Binary(Formula):
    __slots__ = ()
    symbol = "?"
    right_assoc = False

    @property
    def children(self) -> tuple[Formula, ...]:
        return (self.left, self.right)  # type: ignore[attr-defined]

    def _op_text(self) -> str:
        return self.symbol

    def _show(self, kids: list[str]) -> str:
        left_min = self.prec + 1 if self.right_assoc else self.prec
        right_min = self.prec if self.right_assoc else self.prec + 1
        left = _wrap(self.left, kids[0], left_min)  # type: ignore[attr-defined]
        right = _wrap(self.right, kids[1], right_min)  # type: ignore[attr-defined]
        return f"{left} {self._op_text()} {right}"


@dataclass(frozen=True, slots=True)
class And(_Binary):
    left: Formula
    right: Formula
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _PREC_AND
    symbol = "&"


@dataclass(frozen=True, slots=True)
class Or(_Binary):
    left: Formula
    right: Formula
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _PREC_OR
    symbol = "|"


@dataclass(frozen=True, slots=True)
class Implies(_Binary):
    left: Formula
    right: Formula
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _PREC_IMPLIES
    symbol = "->"
    right_assoc = True


@dataclass(frozen=True, slots=True)
class Iff(_Binary):
    left: Formula
    right: Formula
    pos: Pos | None = field(default=None, compare=False, repr=False)
    prec = _PREC_IFF
    symbol = "<->"


class _TimedBinary(_Binary):
    __slots__ = ()
    prec = _PREC_TEMPORAL
    right_assoc = True

    def _op_text(self) -> str:
        return self.symbol + _interval_text(self.interval)  # type: ignore[attr-defined]


@dataclass(frozen=True, slots=True)
class Until(_TimedBinary):
    """``left U_I right``: right holds at some t in I, left holds before t."""

    left: Formula
    right: Formula
    interval: Interval = UNBOUNDED
    pos: Pos | None = field(default=None, compare=False, repr=False)
    symbol = "U"


@dataclass(frozen=True, slots=True)
class Release(_TimedBinary):
    """``left R_I right``, the dual of until: ``!(!left U_I !right)``."""

    left: Formula
    right: Formula
    interval: Interval = UNBOUNDED
    pos: Pos | None = field(default=None, compare=False, repr=False)
    symbol = "R"


@dataclass(frozen=True, slots=True)
class WeakUntil(_TimedBinary):
    """``left W_I right``: ``(left U_I right) | G[0,sup I] left``."""

    left: Formula
    right: Formula
    interval: Interval = UNBOUNDED
    pos: Pos | None = field(default=None, compare=False, repr=False)
    symbol = "W"


def walk(f: Formula) -> Iterator[Formula]:
    """All nodes of ``f``, parents before children."""
    stack = [f]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(reversed(node.children))


def atoms(f: Formula) -> tuple[str, ...]:
    """Proposition names in order of first appearance.

    >>> atoms(Atom("b") & (Atom("a") | Atom("b")))
    ('b', 'a')
    """
    seen: dict[str, None] = {}
    for node in walk(f):
        if isinstance(node, Atom):
            seen.setdefault(node.name)
    return tuple(seen)


def depth(f: Formula) -> int:
    """Nesting depth (an atom has depth 1); works on any tree whose nodes have ``children``.

    >>> depth(Not(Not(Atom("a"))))
    3
    """
    best, stack = 0, [(f, 1)]
    while stack:
        node, d = stack.pop()
        best = max(best, d)
        stack.extend((c, d + 1) for c in node.children)
    return best


_CHAINS = frozenset({"And", "Or", "PAnd", "POr", "BinOp"})


def nesting(tree: object) -> tuple[int, int]:
    """``(levels, depth)`` of a formula or predicate tree.

    ``levels`` counts nesting as a reader sees it: a chain of one associative
    operator (``a & b & c``, ``x + y + z``) is one level, however many operands
    it has; ``depth`` is the tree's own depth (what a recursive pass descends).
    Iterative, so safe on any input.

    >>> f = And(And(And(Atom("a"), Atom("b")), Atom("c")), Not(Atom("d")))
    >>> nesting(f), depth(f)
    ((3, 4), 4)
    """
    best_levels = best_depth = 0
    stack: list[tuple[object, int, int]] = [(tree, 1, 1)]
    while stack:
        node, levels, d = stack.pop()
        best_levels, best_depth = max(best_levels, levels), max(best_depth, d)
        kind, op = type(node).__name__, getattr(node, "op", None)
        for c in node.children:  # type: ignore[attr-defined]
            same = kind in _CHAINS and type(c) is type(node) and getattr(c, "op", None) == op
            stack.append((c, levels if same else levels + 1, d + 1))
    return best_levels, best_depth


def size(f: Formula) -> int:
    """Number of operator nodes (atoms and constants not counted)."""
    return sum(1 for node in walk(f) if node.children)
