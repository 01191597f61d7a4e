"""The grammar's transformer: :class:`Build` turns what the parser reads into formula and
predicate trees (:mod:`mitlc.spec.ast`, :mod:`mitlc.spec.predicates`) and spec statements, while
the LALR parser runs, so deeply nested input cannot exhaust the Python stack. An interval's
problems (negative, inverted, empty) are a located :class:`~mitlc.errors.SpecError` here.
"""

from __future__ import annotations

import math
from typing import Any

from lark import Token, Transformer

from mitlc.errors import SpecError
from mitlc.spec import ast as A
from mitlc.spec import predicates as P

__all__ = ["Build", "as_pred", "token_pos"]


def token_pos(tok: Token) -> A.Pos:
    """Where ``tok`` stands in the text (line and column 1 when lark gives none)."""
    return A.Pos(tok.line or 1, tok.column or 1)


def _num(tok: Token) -> float:
    return float(tok)


class _Bound:
    __slots__ = ("value", "pos")

    def __init__(self, value: float, pos: A.Pos) -> None:
        self.value, self.pos = value, pos


class _RawInterval:
    __slots__ = ("lo", "hi", "lo_closed", "hi_closed")

    def __init__(self, lo: _Bound, hi: _Bound, lo_closed: bool, hi_closed: bool) -> None:
        self.lo, self.hi, self.lo_closed, self.hi_closed = lo, hi, lo_closed, hi_closed


def _interval(raw: _RawInterval | None) -> A.Interval:
    if raw is None:
        return A.UNBOUNDED
    lo, hi = raw.lo.value, raw.hi.value
    text = f"{'[' if raw.lo_closed else '('}{A.fmt_number(lo)},{A.fmt_number(hi)}{']' if raw.hi_closed else ')'}"
    where = raw.lo.pos
    if lo < 0:
        raise SpecError(f"negative interval {text}: time starts at 0", line=where.line, column=where.column)
    if math.isinf(lo):
        raise SpecError(f"interval {text} starts at infinity", line=where.line, column=where.column)
    if lo > hi:
        raise SpecError(
            f"inverted interval {text}: the lower end must not exceed the upper",
            line=where.line,
            column=where.column,
        )
    if lo == hi and not (raw.lo_closed and raw.hi_closed):
        raise SpecError(f"empty interval {text}", line=where.line, column=where.column)
    # [a, inf] is read as [a, inf): infinity is never reached
    return A.Interval(lo, hi, raw.lo_closed, raw.hi_closed and not math.isinf(hi))


class Build(Transformer):
    """Builds formula and predicate trees; one method per grammar alias."""

    # ---------------------------------------------------------- formulas
    def atom(self, children: list[Any]) -> A.Formula:
        (tok,) = children
        return A.Atom(str(tok), pos=token_pos(tok))

    def inline_pred(self, children: list[Any]) -> A.Formula:
        pred = self.compare(children)
        pos = _first_pos(pred)
        return A.Atom(P.readable_name(pred), pos=pos, pred=pred)

    def true_(self, children: list[Any]) -> A.Formula:
        return A.Const(True, pos=token_pos(children[0]))

    def false_(self, children: list[Any]) -> A.Formula:
        return A.Const(False, pos=token_pos(children[0]))

    def not_(self, children: list[Any]) -> A.Formula:
        op, child = children
        return A.Not(child, pos=token_pos(op))

    def weighted(self, children: list[Any]) -> A.Formula:
        tok, child = children
        w = _num(tok)
        if not (math.isfinite(w) and w > 0):
            raise SpecError(f"weight {tok} must be positive and finite", line=tok.line, column=tok.column)
        return A.Weighted(w, child, pos=token_pos(tok))

    def eventually(self, children: list[Any]) -> A.Formula:
        op, interval, child = children
        return A.Eventually(child, _interval(interval), pos=token_pos(op))

    def always(self, children: list[Any]) -> A.Formula:
        op, interval, child = children
        return A.Globally(child, _interval(interval), pos=token_pos(op))

    def _timed_binary(self, cls: type, children: list[Any]) -> A.Formula:
        left, op, interval, right = children
        return cls(left, right, _interval(interval), pos=token_pos(op))

    def until(self, children: list[Any]) -> A.Formula:
        return self._timed_binary(A.Until, children)

    def release(self, children: list[Any]) -> A.Formula:
        return self._timed_binary(A.Release, children)

    def weak_until(self, children: list[Any]) -> A.Formula:
        return self._timed_binary(A.WeakUntil, children)

    def _binary(self, cls: type, children: list[Any]) -> A.Formula:
        left, op, right = children
        return cls(left, right, pos=token_pos(op))

    def and_(self, children: list[Any]) -> A.Formula:
        return self._binary(A.And, children)

    def or_(self, children: list[Any]) -> A.Formula:
        return self._binary(A.Or, children)

    def implies(self, children: list[Any]) -> A.Formula:
        return self._binary(A.Implies, children)

    def iff(self, children: list[Any]) -> A.Formula:
        return self._binary(A.Iff, children)

    # intervals: children are the two bounds
    def closed_closed(self, c: list[Any]) -> _RawInterval:
        return _RawInterval(c[0], c[1], True, True)

    def open_closed(self, c: list[Any]) -> _RawInterval:
        return _RawInterval(c[0], c[1], False, True)

    def closed_open(self, c: list[Any]) -> _RawInterval:
        return _RawInterval(c[0], c[1], True, False)

    def open_open(self, c: list[Any]) -> _RawInterval:
        return _RawInterval(c[0], c[1], False, False)

    # ---------------------------------------------------------- predicates
    # num/inf_ serve both interval bounds and arithmetic: they return _Bound for
    # bounds; the arithmetic rules unwrap it.
    def num(self, children: list[Any]) -> _Bound:
        (tok,) = children
        return _Bound(_num(tok), token_pos(tok))

    def inf_(self, children: list[Any]) -> _Bound:
        (tok,) = children
        return _Bound(math.inf, token_pos(tok))

    def var(self, children: list[Any]) -> P.Pred:
        (tok,) = children
        name = str(tok)
        if name in P.CONSTANTS:
            return P.Num(P.CONSTANTS[name], name=name)
        return P.Var(name, pos=token_pos(tok))

    def call(self, children: list[Any]) -> P.Pred:
        tok, *args = children
        name = str(tok)
        if name not in P.FUNCTIONS:
            known = ", ".join(sorted(P.FUNCTIONS))
            raise SpecError(f"unknown function '{name}' (known: {known})", line=tok.line, column=tok.column)
        arity, _ = P.FUNCTIONS[name]
        if len(args) != arity:
            raise SpecError(
                f"{name}() takes {arity} argument{'s' if arity > 1 else ''}, got {len(args)}",
                line=tok.line,
                column=tok.column,
            )
        return P.Call(name, tuple(as_pred(a) for a in args), pos=token_pos(tok))

    def index(self, children: list[Any]) -> P.Pred:
        tok, num = children
        i = float(num)
        if not i.is_integer() or i >= 2**31:
            raise SpecError(
                f"an observation index is a whole number below 2**31, got '{num}'", line=num.line, column=num.column
            )
        if str(tok) != "obs":
            raise SpecError(
                f"'{tok}[...]': only the observation is indexed, as obs[i] in a 'state' line",
                line=tok.line,
                column=tok.column,
            )
        return P.Var(f"obs[{int(i)}]", pos=token_pos(tok))

    def neg(self, children: list[Any]) -> P.Pred:
        (arg,) = children
        return P.Neg(as_pred(arg))

    def binop(self, children: list[Any]) -> P.Pred:
        left, op, right = children
        return P.BinOp(str(op), as_pred(left), as_pred(right))

    def compare(self, children: list[Any]) -> P.Pred:
        operands = tuple(as_pred(c) for c in children[0::2])
        ops = tuple(str(t) for t in children[1::2])
        return P.Compare(operands, ops)

    def p_and(self, children: list[Any]) -> P.Pred:
        return P.PAnd(as_pred(children[0]), as_pred(children[2]))

    def p_or(self, children: list[Any]) -> P.Pred:
        return P.POr(as_pred(children[0]), as_pred(children[2]))

    def p_not(self, children: list[Any]) -> P.Pred:
        return P.PNot(as_pred(children[1]))

    # ---------------------------------------------------------- statements
    def prop_def(self, children: list[Any]) -> tuple:
        tok, pred = children
        return ("prop", tok, as_pred(pred))

    def formula_def(self, children: list[Any]) -> tuple:
        return ("formula", children[0])

    def check_def(self, children: list[Any]) -> tuple:
        return ("check", children[0])

    def param(self, children: list[Any]) -> tuple:
        tok, value = children
        return (tok, as_pred(value))

    def plant_def(self, children: list[Any]) -> tuple:
        tok, *params = children
        return ("plant", tok, [p for p in params if p is not None])

    def state_item(self, children: list[Any]) -> tuple:
        tok, expr, lo, hi = children
        return (tok, as_pred(expr), None if lo is None else as_pred(lo), None if hi is None else as_pred(hi))

    def state_def(self, children: list[Any]) -> tuple:
        return ("state", children)

    def init_range(self, children: list[Any]) -> tuple:
        tok, lo, hi = children
        return (tok, as_pred(lo), as_pred(hi))

    def init_point(self, children: list[Any]) -> tuple:
        tok, value = children
        v = as_pred(value)
        return (tok, v, v)

    def init_def(self, children: list[Any]) -> tuple:
        return ("init", children)

    def horizon_def(self, children: list[Any]) -> tuple:
        return ("horizon", as_pred(children[1]), children[0])

    def setpoint_def(self, children: list[Any]) -> tuple:
        return ("setpoint", as_pred(children[1]), children[0])

    def require_bound(self, children: list[Any]) -> tuple:
        tok, cmp, value, band = children
        if str(cmp) not in ("<=", "<"):
            raise SpecError(
                f"a requirement is an upper bound ('require {tok} <= value') or a range "
                f"('require {tok} in [a, b]'), not '{cmp}'",
                line=cmp.line,
                column=cmp.column,
            )
        return ("require", tok, None, as_pred(value), None if band is None else as_pred(band))

    def require_range(self, children: list[Any]) -> tuple:
        tok, lo, hi, band = children
        return ("require", tok, as_pred(lo), as_pred(hi), None if band is None else as_pred(band))

    def option_def(self, children: list[Any]) -> tuple:
        tok, value = children
        return ("option", tok, value)

    def start(self, children: list[Any]) -> list:
        return children


def _first_pos(p: P.Pred) -> A.Pos | None:
    """Where a predicate starts in the text: its leftmost node that knows (else its first variable's)."""
    node: P.Pred | None = p
    while node is not None:
        pos = getattr(node, "pos", None)
        if pos is not None:
            return pos
        kids = node.children
        node = kids[0] if kids else None
    for v in P.variables(p):
        if v.pos is not None:
            return v.pos
    return None


def as_pred(x: Any) -> P.Pred:
    """``x`` as a predicate: a number read as an interval bound becomes a :class:`~mitlc.spec.predicates.Num`."""
    if isinstance(x, _Bound):
        return P.Num(x.value)
    return x
