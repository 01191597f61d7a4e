"""Reward expressions over token counts now (``p``) and one step ago (``~p``).

The compiler builds the reward of a formula as a small expression tree.  It
prints as a readable formula and evaluates vectorised on batches of marking
pairs: ``prev`` is ``M_k`` and ``now`` is ``M_k+1``, both ``(R, places)``.

>>> import numpy as np
>>> kappa = Tokens((0,), ("p_kappa",))
>>> not_kappa = Tokens((1,), ("p_not_kappa",))
>>> r = Prod((Sum((Const(1.0), kappa.previous())), Sum((kappa, Neg(not_kappa)))))
>>> print(r)
(1 + ~p_kappa) * (p_kappa - p_not_kappa)
>>> prev = np.array([[1, 0], [1, 0]]); now = np.array([[1, 0], [0, 1]])
>>> r.evaluate(prev, now)
array([ 2., -2.])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mitlc.spec.ast import fmt_number

__all__ = [
    "bounds",
    "pair_bounds",
    "is_graded",
    "scale",
    "RExpr",
    "Const",
    "Tokens",
    "Graded",
    "Sum",
    "Prod",
    "Neg",
    "Min",
    "Max",
    "Gated",
    "ONE",
    "ZERO",
]


class RExpr:
    """Base class of reward expression nodes."""

    __slots__ = ()
    prec = 9

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        """Reward for each row: ``prev`` and ``now`` are ``(R, places)`` markings; ``grades``
        ``(R, atoms)`` the graded propositions at the new state (:class:`Graded`), where there are any."""
        raise NotImplementedError

    @property
    def children(self) -> tuple[RExpr, ...]:
        return ()


_SUM, _PROD, _NEG, _ATOM = 1, 2, 3, 9


def _wrap(e: RExpr, min_prec: int) -> str:
    text = str(e)
    return f"({text})" if e.prec < min_prec else text


@dataclass(frozen=True, slots=True)
class Const(RExpr):
    value: float
    prec = _ATOM

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        return np.full(prev.shape[0], self.value)

    def __str__(self) -> str:
        return fmt_number(self.value) if self.value >= 0 else f"({fmt_number(self.value)})"


ONE = Const(1.0)
ZERO = Const(0.0)


@dataclass(frozen=True, slots=True)
class Tokens(RExpr):
    """The number of tokens in a set of places, now or (``prev``) one step ago."""

    places: tuple[int, ...]
    names: tuple[str, ...]
    prev: bool = False
    prec = _ATOM

    def previous(self) -> Tokens:
        return Tokens(self.places, self.names, True)

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        m = prev if self.prev else now
        if len(self.places) == 1:
            return m[:, self.places[0]].astype(float)
        return m[:, list(self.places)].sum(axis=1).astype(float)

    def __str__(self) -> str:
        mark = "~" if self.prev else ""
        if len(self.names) == 1:
            return mark + self.names[0]
        return "(" + " + ".join(mark + n for n in self.names) + ")"


@dataclass(frozen=True, slots=True)
class Graded(RExpr):
    """An atomic proposition's graded value at the new state, in place of its flat reward
    ``flat = p_a - p_not_a`` (+1 where ``a`` holds, -1 where not): ``mix * flat + (1 - mix) * g_a``,
    with ``g_a`` the predicate's robustness normalised by the state bounds and clipped to ``[-1, 1]``
    (:mod:`mitlc.spec.grades`), read from column ``index`` of the ``grades`` that :meth:`evaluate`
    is given (negated for ``!a``). ``reward = graded`` is ``mix = 0`` (printed ``g_a``),
    ``reward = shaped`` is ``mix = 1/2`` (printed ``s_a``: the flat step at the boundary kept, half
    of it, and graded on either side).

    ``g_a`` has the sign of ``flat`` (a proposition that holds has robustness >= 0), so on a step
    whose markings say ``a`` holds the value lies in ``[mix, 1]`` and where not in ``[-1, -mix]``:
    :func:`pair_bounds` uses that.
    """

    atom: str
    index: int
    flat: RExpr
    negated: bool = False
    mix: float = 0.0
    prec = _ATOM

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        if grades is None:
            raise ValueError(f"the graded reward of '{self.atom}' needs the grades of the new state")
        g = np.asarray(grades[:, self.index], dtype=float)
        g = -g if self.negated else g
        if self.mix:
            return self.mix * self.flat.evaluate(prev, now) + (1.0 - self.mix) * g
        return g

    @property
    def children(self) -> tuple[RExpr, ...]:
        return (self.flat,)

    def __str__(self) -> str:
        return f"{'-' if self.negated else ''}{'s' if self.mix else 'g'}_{self.atom}"


@dataclass(frozen=True, slots=True)
class Sum(RExpr):
    terms: tuple[RExpr, ...]
    prec = _SUM

    @property
    def children(self) -> tuple[RExpr, ...]:
        return self.terms

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        out = self.terms[0].evaluate(prev, now, grades)
        for t in self.terms[1:]:
            out = out + t.evaluate(prev, now, grades)
        return out

    def __str__(self) -> str:
        parts = [_wrap(self.terms[0], _SUM)]
        for t in self.terms[1:]:
            if isinstance(t, Neg):
                parts.append(f"- {_wrap(t.arg, _PROD)}")
            else:
                parts.append(f"+ {_wrap(t, _SUM)}")
        return " ".join(parts)


@dataclass(frozen=True, slots=True)
class Prod(RExpr):
    factors: tuple[RExpr, ...]
    prec = _PROD

    @property
    def children(self) -> tuple[RExpr, ...]:
        return self.factors

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        out = self.factors[0].evaluate(prev, now, grades)
        for f in self.factors[1:]:
            out = out * f.evaluate(prev, now, grades)
        return out

    def __str__(self) -> str:
        return " * ".join(_wrap(f, _PROD + 1) for f in self.factors)


@dataclass(frozen=True, slots=True)
class Neg(RExpr):
    arg: RExpr
    prec = _NEG

    @property
    def children(self) -> tuple[RExpr, ...]:
        return (self.arg,)

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        return -self.arg.evaluate(prev, now, grades)

    def __str__(self) -> str:
        return "-" + _wrap(self.arg, _NEG + 1)


@dataclass(frozen=True, slots=True)
class Gated(RExpr):
    """``gate * expr`` where ``gate`` is a timing indicator: the term is *active* where gate > 0.

    Used for the timing factors of Table 4-2 (``~p_tau`` of F, the window of an
    interval, the phase of U), so that :class:`Min` can tell active terms apart.
    """

    gate: RExpr
    expr: RExpr
    prec = _PROD

    @property
    def children(self) -> tuple[RExpr, ...]:
        return (self.gate, self.expr)

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        return self.gate.evaluate(prev, now, grades) * self.expr.evaluate(prev, now, grades)

    def __str__(self) -> str:
        return f"{_wrap(self.gate, _PROD + 1)} * {_wrap(self.expr, _PROD + 1)}"


@dataclass(frozen=True, slots=True)
class Min(RExpr):
    """``min`` of the terms (the reward of ``&``).

    ``active=False`` is the thesis's literal reading: the min over all terms.
    ``active=True`` takes the min over the terms whose gate is open (a
    :class:`Gated` term whose gate is 0 is left out; ungated terms are always
    in); with no term open the reward is 0.
    """

    terms: tuple[RExpr, ...]
    active: bool = False
    prec = _ATOM

    @property
    def children(self) -> tuple[RExpr, ...]:
        return self.terms

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        values = np.stack([t.evaluate(prev, now, grades) for t in self.terms])
        if not self.active:
            return values.min(axis=0)
        open_ = np.stack([gate_open(t, prev, now) for t in self.terms])
        masked = np.where(open_, values, np.inf).min(axis=0)
        return np.where(open_.any(axis=0), masked, 0.0)

    def __str__(self) -> str:
        name = "min_active" if self.active else "min"
        return f"{name}({', '.join(str(t) for t in self.terms)})"


@dataclass(frozen=True, slots=True)
class Max(RExpr):
    """``max`` of the terms (the reward of ``|``)."""

    terms: tuple[RExpr, ...]
    prec = _ATOM

    @property
    def children(self) -> tuple[RExpr, ...]:
        return self.terms

    def evaluate(self, prev: np.ndarray, now: np.ndarray, grades: np.ndarray | None = None) -> np.ndarray:
        return np.stack([t.evaluate(prev, now, grades) for t in self.terms]).max(axis=0)

    def __str__(self) -> str:
        return f"max({', '.join(str(t) for t in self.terms)})"


def gate_open(t: RExpr, prev: np.ndarray, now: np.ndarray) -> np.ndarray:
    """Where the term ``t`` of a ``min_active`` is in, per row: a :class:`Gated` term where its
    gate is positive, a sum of gated terms where any of theirs is, any other term everywhere."""
    if isinstance(t, Gated):
        return np.asarray(t.gate.evaluate(prev, now) > 0)
    if isinstance(t, Sum) and all(isinstance(u, Gated) for u in t.terms):
        return np.any([gate_open(u, prev, now) for u in t.terms], axis=0)
    return np.ones(prev.shape[0], bool)


def scale(w: float, e: RExpr) -> RExpr:
    """``w * e`` with the constant folded where possible."""
    if w == 1.0:
        return e
    if isinstance(e, Prod):
        if isinstance(e.factors[0], Const):
            return Prod((Const(w * e.factors[0].value),) + e.factors[1:])
        return Prod((Const(w),) + e.factors)
    return Prod((Const(w), e))


def bounds(e: RExpr) -> tuple[float, float]:
    """Interval bounds of ``e`` when every token count is 0 or 1 (one token per sub-net).

    >>> bounds(Prod((Sum((ONE, Tokens((0,), ("a",), True))), Sum((Tokens((0,), ("a",)), Neg(Tokens((1,), ("b",))))))))
    (-2.0, 2.0)
    """
    if isinstance(e, Const):
        return e.value, e.value
    if isinstance(e, Tokens):
        return 0.0, 1.0
    if isinstance(e, Graded):
        return -1.0, 1.0
    if isinstance(e, Neg):
        lo, hi = bounds(e.arg)
        return -hi, -lo
    if isinstance(e, Sum):
        pairs = [bounds(t) for t in e.terms]
        return sum(p[0] for p in pairs), sum(p[1] for p in pairs)
    if isinstance(e, (Prod, Gated)):
        lo, hi = 1.0, 1.0
        for f in e.children:
            flo, fhi = bounds(f)
            corners = (lo * flo, lo * fhi, hi * flo, hi * fhi)
            lo, hi = min(corners), max(corners)
        return lo, hi
    if isinstance(e, Min):
        pairs = [bounds(t) for t in e.terms]
        lo, hi = min(p[0] for p in pairs), min(p[1] for p in pairs)
        if e.active:  # a closed term leaves the min, and with none open the reward is 0
            lo, hi = min(lo, 0.0), max(max(p[1] for p in pairs), 0.0)
        return lo, hi
    if isinstance(e, Max):
        pairs = [bounds(t) for t in e.terms]
        return max(p[0] for p in pairs), max(p[1] for p in pairs)
    raise TypeError(f"not a reward expression: {e!r}")


def is_graded(e: RExpr) -> bool:
    """Whether ``e`` reads graded propositions (then it needs the new state, not only markings)."""
    return isinstance(e, Graded) or any(is_graded(c) for c in e.children)


def pair_bounds(e: RExpr, prev: np.ndarray, now: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of ``e`` on each marking pair over every state the pair allows: exact values where
    ``e`` reads only tokens, and for a :class:`Graded` leaf the hull of ``mix`` times its flat value
    and its flat value (interval arithmetic over the tree, so the bounds are sound, if not always
    tight).

    >>> a, na = Tokens((0,), ("p_a",)), Tokens((1,), ("p_not_a",))
    >>> g = Graded("a", 0, Sum((a, Neg(na))))
    >>> lo, hi = pair_bounds(Prod((Const(2.0), g)), np.array([[1, 0], [1, 0]]), np.array([[1, 0], [0, 1]]))
    >>> lo.tolist(), hi.tolist()
    ([0.0, -2.0], [2.0, 0.0])
    """
    if not is_graded(e):
        v = np.asarray(e.evaluate(prev, now), dtype=float)
        v = np.broadcast_to(v, (prev.shape[0],))
        return v, v
    if isinstance(e, Graded):
        f = np.asarray(e.flat.evaluate(prev, now), dtype=float)
        inner = e.mix * f + 0.0  # no negative zero
        return np.minimum(f, inner), np.maximum(f, inner)
    if isinstance(e, Neg):
        lo, hi = pair_bounds(e.arg, prev, now)
        return -hi, -lo
    if isinstance(e, Sum):
        parts = [pair_bounds(t, prev, now) for t in e.terms]
        return sum(p[0] for p in parts), sum(p[1] for p in parts)  # type: ignore[return-value]
    if isinstance(e, (Prod, Gated)):
        lo, hi = pair_bounds(e.children[0], prev, now)
        for factor in e.children[1:]:
            flo, fhi = pair_bounds(factor, prev, now)
            corners = np.stack([lo * flo, lo * fhi, hi * flo, hi * fhi])
            lo, hi = corners.min(axis=0), corners.max(axis=0)
        return lo, hi
    if isinstance(e, Min):
        parts = [pair_bounds(t, prev, now) for t in e.terms]
        los, his = np.stack([p[0] for p in parts]), np.stack([p[1] for p in parts])
        if not e.active:
            return los.min(axis=0), his.min(axis=0)
        open_ = np.stack([gate_open(t, prev, now) for t in e.terms])
        any_open = open_.any(axis=0)
        lo = np.where(any_open, np.where(open_, los, np.inf).min(axis=0), 0.0)
        hi = np.where(any_open, np.where(open_, his, np.inf).min(axis=0), 0.0)
        return lo, hi
    if isinstance(e, Max):
        parts = [pair_bounds(t, prev, now) for t in e.terms]
        return np.stack([p[0] for p in parts]).max(axis=0), np.stack([p[1] for p in parts]).max(axis=0)
    raise TypeError(f"not a reward expression: {e!r}")
