"""Normal-form passes: pure functions ``Formula -> Formula``.

:func:`normal_form` runs :data:`RULES` in order: derived operators are
rewritten into primitives, then negation is pushed down to the atoms using the
dual of every operator (``!F = G!``, ``!G = F!``, ``!(a U b) = !a R !b``,
``!(a R b) = !a U !b``).  Weights stay on the subformula they were written on.

>>> from mitlc.spec.parse import parse_formula
>>> print(normal_form(parse_formula("!(F[0,2] a -> G b)")))
F[0,2] a & F !b
"""

from __future__ import annotations

from functools import singledispatch

from mitlc.errors import CompileError
from mitlc.spec import ast as A

__all__ = ["desugar", "push_negations", "normal_form", "RULES", "is_state_formula"]


@singledispatch
def desugar(f: A.Formula) -> A.Formula:
    """Rewrite ``->``, ``<->`` and ``W`` into ``!``, ``&``, ``|``, ``U`` and ``G``.

    ``a W_I b`` becomes ``(a U_I b) | G[0,sup I] a``.

    >>> from mitlc.spec.parse import parse_formula
    >>> print(desugar(parse_formula("a -> b W c")))
    !a | (b U c | G b)
    """
    raise CompileError(f"cannot compile formula node {type(f).__name__}")


@desugar.register
def _(f: A.Const) -> A.Formula:
    return f


@desugar.register
def _(f: A.Atom) -> A.Formula:
    return f


@desugar.register
def _(f: A.Not) -> A.Formula:
    return A.Not(desugar(f.child), pos=f.pos)


@desugar.register
def _(f: A.Weighted) -> A.Formula:
    return A.Weighted(f.weight, desugar(f.child), pos=f.pos)


@desugar.register
def _(f: A.Eventually) -> A.Formula:
    return A.Eventually(desugar(f.child), f.interval, pos=f.pos)


@desugar.register
def _(f: A.Globally) -> A.Formula:
    return A.Globally(desugar(f.child), f.interval, pos=f.pos)


@desugar.register
def _(f: A.And) -> A.Formula:
    return A.And(desugar(f.left), desugar(f.right), pos=f.pos)


@desugar.register
def _(f: A.Or) -> A.Formula:
    return A.Or(desugar(f.left), desugar(f.right), pos=f.pos)


@desugar.register
def _(f: A.Implies) -> A.Formula:
    return A.Or(A.Not(desugar(f.left)), desugar(f.right), pos=f.pos)


@desugar.register
def _(f: A.Iff) -> A.Formula:
    left, right = desugar(f.left), desugar(f.right)
    return A.And(A.Or(A.Not(left), right), A.Or(left, A.Not(right)), pos=f.pos)


@desugar.register
def _(f: A.Until) -> A.Formula:
    return A.Until(desugar(f.left), desugar(f.right), f.interval, pos=f.pos)


@desugar.register
def _(f: A.Release) -> A.Formula:
    return A.Release(desugar(f.left), desugar(f.right), f.interval, pos=f.pos)


@desugar.register
def _(f: A.WeakUntil) -> A.Formula:
    left, right = desugar(f.left), desugar(f.right)
    upto = A.Interval(0.0, f.interval.hi, True, f.interval.hi_closed)
    return A.Or(A.Until(left, right, f.interval, pos=f.pos), A.Globally(left, upto, pos=f.pos), pos=f.pos)


def push_negations(f: A.Formula, negate: bool = False) -> A.Formula:
    """Negation normal form: ``Not`` only directly above atoms.

    Expects a desugared formula (no ``->``, ``<->``, ``W``).

    >>> from mitlc.spec.parse import parse_formula
    >>> print(push_negations(parse_formula("!(a U[1,2] G !b)")))
    !a R[1,2] F b
    """
    if isinstance(f, A.Not):
        return push_negations(f.child, not negate)
    if isinstance(f, A.Const):
        return A.Const(f.value != negate, pos=f.pos)
    if isinstance(f, A.Atom):
        return A.Not(f, pos=f.pos) if negate else f
    if isinstance(f, A.Weighted):
        return A.Weighted(f.weight, push_negations(f.child, negate), pos=f.pos)
    if isinstance(f, (A.And, A.Or)):
        binary = f.__class__ if not negate else (A.Or if isinstance(f, A.And) else A.And)
        return binary(push_negations(f.left, negate), push_negations(f.right, negate), pos=f.pos)
    if isinstance(f, (A.Eventually, A.Globally)):
        unary = f.__class__ if not negate else (A.Globally if isinstance(f, A.Eventually) else A.Eventually)
        return unary(push_negations(f.child, negate), f.interval, pos=f.pos)
    if isinstance(f, (A.Until, A.Release)):
        timed = f.__class__ if not negate else (A.Release if isinstance(f, A.Until) else A.Until)
        return timed(push_negations(f.left, negate), push_negations(f.right, negate), f.interval, pos=f.pos)
    raise CompileError(f"cannot put {type(f).__name__} into negation normal form")


RULES = (desugar, push_negations)
"""The passes :func:`normal_form` runs, in order."""


def normal_form(f: A.Formula) -> A.Formula:
    """Run every pass of :data:`RULES`."""
    for rule in RULES:
        f = rule(f)
    return f


def is_state_formula(f: A.Formula) -> bool:
    """True if ``f`` has no temporal operator (only atoms, constants, ! & | and weights).

    >>> from mitlc.spec.parse import parse_formula
    >>> is_state_formula(parse_formula("a & !b")), is_state_formula(parse_formula("a & F b"))
    (True, False)
    """
    return all(isinstance(n, (A.Atom, A.Const, A.Not, A.And, A.Or, A.Weighted, A.Implies, A.Iff)) for n in A.walk(f))
