"""Checks on parsed trees that the parser's entry points share: the nesting limits
(:data:`MAX_DEPTH`, :data:`MAX_TREE`), the weights of a formula, constant arguments (a
parameter, a bound) and the words a spec reserves (:data:`RESERVED`).
"""

from __future__ import annotations

import math
from typing import Any

from lark import Token

from mitlc.errors import SpecError
from mitlc.spec import ast as A
from mitlc.spec import predicates as P
from mitlc.spec.transform import token_pos

__all__ = ["MAX_DEPTH", "MAX_TREE", "RESERVED", "check_depth", "check_weights", "constant", "too_deep"]

MAX_DEPTH = 64
"""Deepest formula or predicate nesting accepted, in levels: a chain of one associative
operator (``a & b & c``) is one level (:func:`mitlc.spec.ast.nesting`)."""

MAX_TREE = 256
"""Deepest syntax tree accepted, counting each operand of a chain: what keeps every
recursive pass of the compiler, monitor and exports far from Python's stack limit."""

RESERVED = frozenset(
    [
        "F",
        "G",
        "U",
        "R",
        "W",
        "X",
        "true",
        "false",
        "True",
        "False",
        "inf",
        "infty",
        "not",
        "and",
        "or",
        "implies",
        "iff",
        "eventually",
        "always",
        "until",
        "release",
        "weak_until",
        "prop",
        "formula",
        "check",
        "plant",
        "init",
        "horizon",
        "option",
        "in",
        "pi",
        "e",
        "setpoint",
        "require",
        "band",
        "state",
    ]
)


def too_deep(tree: Any, what: str) -> str | None:
    """Why ``tree`` is refused for its shape (:data:`MAX_DEPTH`, :data:`MAX_TREE`), or None."""
    levels, depth = A.nesting(tree)  # iterative: safe on the deepest input
    if levels > MAX_DEPTH:
        return f"{what} nesting too deep (more than {MAX_DEPTH} levels)"
    if depth > MAX_TREE:
        return (
            f"{what} too long: its tree is more than {MAX_TREE} operators deep (a chain such as a & b & ... "
            "counts one per operand); split it into propositions or shorter parts"
        )
    return None


def check_depth(f: A.Formula) -> None:
    """A :class:`SpecError` at ``f`` if :func:`too_deep` refuses it."""
    problem = too_deep(f, "formula")
    if problem is not None:
        pos = getattr(f, "pos", None)
        raise SpecError(
            problem,
            line=pos.line if pos else None,
            column=pos.column if pos else None,
        )


def check_weights(f: A.Formula, text: str) -> None:
    """The weights of ``f``: their products along each path must stay finite (an infinite
    reward), and ``10 * q < 1``, which reads as the weight 10 on ``q < 1``, must say so with
    parentheses. The overflow is looked for first, over the whole formula."""
    lines = text.split("\n")

    def offset(pos: A.Pos) -> int:
        return sum(len(line) + 1 for line in lines[: pos.line - 1]) + pos.column - 1

    stack: list[tuple[A.Formula, float]] = [(f, 1.0)]  # the product of the weights above each node
    while stack:
        node, w = stack.pop()
        if isinstance(node, A.Weighted):
            w *= node.weight
            if not math.isfinite(w):
                pos = node.pos or A.Pos(1, 1)
                raise SpecError(
                    f"the weights multiply to more than the largest number ({A.fmt_number(node.weight)} * ...): "
                    "a reward that large is infinite",
                    line=pos.line,
                    column=pos.column,
                )
        stack.extend((c, w) for c in node.children)
    for node in A.walk(f):
        if not (isinstance(node, A.Weighted) and isinstance(node.child, A.Atom) and node.child.pred is not None):
            continue
        if node.pos is None or node.child.pos is None:
            continue
        if "(" not in text[offset(node.pos) : offset(node.child.pos)]:
            wt, pred = A.fmt_number(node.weight), node.child.pred
            raise SpecError(
                f"'{wt} * {pred}' is ambiguous: write {wt} * ({pred}) for a weighted proposition; a product "
                "inside a comparison puts the number after the name (q * 2 < 1)",
                line=node.child.pos.line,
                column=node.child.pos.column,
            )


def constant(p: P.Pred, what: str, pos: Token) -> float:
    """The value of ``p``, a constant expression (``what``: a parameter, a bound), or a SpecError at ``pos``."""
    problem = too_deep(p, f"{what}:")
    if problem is not None:
        raise SpecError(problem, line=pos.line, column=pos.column)
    if P.is_boolean(p):
        raise SpecError(f"{what} must be a number, not a condition", line=pos.line, column=pos.column)
    names = P.variables(p)
    if names:
        v = names[0]
        where = v.pos or token_pos(pos)
        raise SpecError(f"{what} must be a constant, but uses '{v.name}'", line=where.line, column=where.column)
    value = P.const_value(p)
    assert value is not None
    if math.isnan(value):
        raise SpecError(f"{what} is not a number", line=pos.line, column=pos.column)
    return value
