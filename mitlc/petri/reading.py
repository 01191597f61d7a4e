"""How the compiler reads a formula in normal form: release rewritten into until and
always, weights peeled, chains flattened, recurrences and until triggers recognised.

Pure functions ``Formula -> Formula`` (or its parts), used by the builders.
"""

from __future__ import annotations

from mitlc.errors import CompileError
from mitlc.spec import ast as A
from mitlc.spec.passes import is_state_formula, push_negations

__all__ = [
    "negate_state",
    "reward_reading",
    "strip_weights",
    "peel_weights",
    "flatten",
    "recurrence",
    "conjoin",
    "disjoin",
    "trigger",
]


def reward_reading(f: A.Formula) -> A.Formula:
    """Rewrite release into until and always, the operators the net implements.

    ``a R_I b`` becomes ``(b U_I (a & b)) | G_I b``, exact for the untimed
    operator (``a R b = b W (a & b)``) and the net's reading for intervals.

    >>> from mitlc.spec.parse import parse_formula
    >>> print(reward_reading(parse_formula("a R b")))
    b U (a & b) | G b
    """
    if isinstance(f, A.Release):
        left, right = reward_reading(f.left), reward_reading(f.right)
        return A.Or(A.Until(right, A.And(left, right), f.interval), A.Globally(right, f.interval), pos=f.pos)
    if not f.children:
        return f
    kids = [reward_reading(c) for c in f.children]
    if isinstance(f, (A.And, A.Or)):
        return f.__class__(kids[0], kids[1], pos=f.pos)
    if isinstance(f, A.Until):
        return A.Until(kids[0], kids[1], f.interval, pos=f.pos)
    if isinstance(f, A.Not):
        return A.Not(kids[0], pos=f.pos)
    if isinstance(f, A.Weighted):
        return A.Weighted(f.weight, kids[0], pos=f.pos)
    if isinstance(f, (A.Eventually, A.Globally)):
        return f.__class__(kids[0], f.interval, pos=f.pos)
    raise CompileError(f"cannot compile {type(f).__name__} (run normal_form first)")


def strip_weights(f: A.Formula) -> A.Formula:
    """Drop weights (they do not change truth)."""
    if isinstance(f, A.Weighted):
        return strip_weights(f.child)
    if isinstance(f, A.Not):
        return A.Not(strip_weights(f.child))
    if isinstance(f, (A.And, A.Or)):
        return f.__class__(strip_weights(f.left), strip_weights(f.right))
    return f


def peel_weights(f: A.Formula) -> tuple[float, A.Formula]:
    """``w1 * w2 * f`` -> ``(w1 w2, f)``."""
    w = 1.0
    while isinstance(f, A.Weighted):
        w *= f.weight
        f = f.child
    return w, f


def flatten(f: A.Formula, cls: type) -> list[A.Formula]:
    """The operands of a chain of ``cls`` (``And`` or ``Or``), left to right."""
    if isinstance(f, cls):
        return flatten(f.left, cls) + flatten(f.right, cls)  # type: ignore[attr-defined]
    return [f]


def recurrence(f: A.Formula) -> tuple[float, A.Formula] | None:
    """``w * G F phi`` with both untimed and phi a state formula -> (w, phi)."""
    w1, g = peel_weights(f)
    if not (isinstance(g, A.Globally) and g.interval.is_unbounded):
        return None
    w2, ev = peel_weights(g.child)
    if not (isinstance(ev, A.Eventually) and ev.interval.is_unbounded and is_state_formula(ev.child)):
        return None
    return w1 * w2, ev.child


def conjoin(a: A.Formula, b: A.Formula) -> A.Formula:
    """``a & b`` with ``true`` dropped."""
    if a == A.Const(True):
        return b
    if b == A.Const(True):
        return a
    return A.And(a, b)


def disjoin(a: A.Formula, b: A.Formula) -> A.Formula:
    """``a | b``, ``true`` if either is."""
    if A.Const(True) in (a, b):
        return A.Const(True)
    return A.Or(a, b)


def trigger(f: A.Formula) -> A.Formula:
    """A state condition that must hold at time t for ``f`` to hold at t (true if none).

    It guards the switch of an untimed until from its left to its right phase.
    """
    w, f = peel_weights(f)
    if is_state_formula(f):
        return strip_weights(f)
    if isinstance(f, A.And):
        return conjoin(trigger(f.left), trigger(f.right))
    if isinstance(f, A.Or):
        return disjoin(trigger(f.left), trigger(f.right))
    if isinstance(f, A.Globally):
        return trigger(f.child) if f.interval.lo == 0 and f.interval.lo_closed else A.Const(True)
    if isinstance(f, A.Until):
        if f.interval.lo == 0 and f.interval.lo_closed:
            return disjoin(trigger(f.left), trigger(f.right))
        return trigger(f.left)
    return A.Const(True)


def negate_state(f: A.Formula) -> A.Formula:
    """``!f`` in negation normal form (``f`` a state formula)."""
    return push_negations(A.Not(f))
