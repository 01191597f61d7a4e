"""Guards of a hybrid automaton: comparisons of linear forms, and their conjunctions and
disjunctions, as data evaluated with numpy over a leading run axis (never ``eval``).

>>> g = all_of(Cmp("q", ">", Lin((("q0", 0.9),))), Cmp("t", "<", Lin((), 0.6)))
>>> print(g)
q > 0.9*q0 & t < 0.6
>>> print(negate(g))
q <= 0.9*q0 | t >= 0.6
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.errors import InputError, SpecError
from mitlc.spec.ast import fmt_number

VARS = ("q", "qdot", "q0", "t", "tau")
"""Variables a guard or reward may read: position, velocity, the memory ``(q0, t)``
(initial position, mode clock) and ``tau``, the time since the start of the trial."""

_OPS: dict[str, Callable[[Any, Any], Any]] = {
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
}
_NEG = {"<": ">=", "<=": ">", ">": "<=", ">=": "<"}
_STRICT = {"<": "<", "<=": "<", ">": ">", ">=": ">"}


def fmt_const(x: float) -> str:
    """A constant as guards and rewards print it (rounded to 12 digits)."""
    return fmt_number(round(float(x), 12))


# ---------------------------------------------------------------- linear forms


@dataclass(frozen=True, slots=True)
class Lin:
    """A linear form ``const + sum(c * var)`` over :data:`VARS` (a guard threshold).

    >>> print(Lin((("q0", 0.05),)))
    0.05*q0
    >>> print(Lin((("q0", 0.1),), 0.9))
    0.1*q0 + 0.9
    >>> print(Lin((), -0.5))
    -0.5
    """

    terms: tuple[tuple[str, float], ...] = ()
    const: float = 0.0

    def value(self, env: Mapping[str, Any]) -> Any:
        out: Any = self.const
        for var, c in self.terms:
            out = out + c * env[var]
        return out

    def __str__(self) -> str:
        parts: list[tuple[float, str]] = []
        for var, c in self.terms:
            mag = abs(c)
            parts.append((c, var if mag == 1 else f"{fmt_const(mag)}*{var}"))
        if self.const != 0 or not parts:
            parts.append((self.const, fmt_const(abs(self.const))))
        out = ""
        for i, (c, text) in enumerate(parts):
            if i == 0:
                out = ("-" if c < 0 else "") + text
            else:
                out += (" - " if c < 0 else " + ") + text
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"terms": {v: c for v, c in self.terms}, "const": self.const}

    @staticmethod
    def from_dict(d: Mapping[str, Any]) -> Lin:
        return Lin(tuple((str(v), float(c)) for v, c in dict(d.get("terms", {})).items()), float(d.get("const", 0.0)))


# ---------------------------------------------------------------- guards


@dataclass(frozen=True, slots=True)
class Cmp:
    """``var op rhs``, e.g. ``q > 0.05*q0``."""

    var: str
    op: str
    rhs: Lin = Lin()

    def __post_init__(self) -> None:
        if self.var not in VARS:
            raise SpecError(f"unknown guard variable '{self.var}' (known: {', '.join(VARS)})")
        if self.op not in _OPS:
            raise SpecError(f"unknown comparison '{self.op}'")

    def __str__(self) -> str:
        return f"{self.var} {self.op} {self.rhs}"


@dataclass(frozen=True, slots=True)
class AllOf:
    """Conjunction; ``AllOf(())`` is true."""

    args: tuple[Guard, ...] = ()

    def __str__(self) -> str:
        if not self.args:
            return "true"
        return " & ".join(parenthesized(a) for a in self.args)


@dataclass(frozen=True, slots=True)
class AnyOf:
    """Disjunction; ``AnyOf(())`` is false."""

    args: tuple[Guard, ...] = ()

    def __str__(self) -> str:
        if not self.args:
            return "false"
        return " | ".join(parenthesized(a) for a in self.args)


Guard = Cmp | AllOf | AnyOf
TRUE: Guard = AllOf(())
FALSE: Guard = AnyOf(())


def parenthesized(g: Guard) -> str:
    """``g`` as an operand of ``&`` or ``|``: in parentheses when it is itself a junction."""
    return f"({g})" if isinstance(g, (AllOf, AnyOf)) and len(g.args) > 1 else str(g)


def _join(cls: type[AllOf] | type[AnyOf], absorbing: Guard, gs: tuple[Guard, ...]) -> Guard:
    """``cls`` (AllOf or AnyOf) of ``gs``, flattened and deduplicated; ``absorbing`` decides it at once."""
    out: list[Guard] = []
    for g in gs:
        if isinstance(g, cls):
            out.extend(a for a in g.args if a not in out)
        elif g == absorbing:
            return absorbing
        elif g not in out:
            out.append(g)
    return out[0] if len(out) == 1 else cls(tuple(out))


def all_of(*gs: Guard) -> Guard:
    """Conjunction, flattened: ``TRUE`` parts dropped, any ``FALSE`` part makes ``FALSE``."""
    return _join(AllOf, FALSE, gs)


def any_of(*gs: Guard) -> Guard:
    """Disjunction, flattened: ``FALSE`` parts dropped, any ``TRUE`` part makes ``TRUE``."""
    return _join(AnyOf, TRUE, gs)


def negate(g: Guard) -> Guard:
    """The complement, pushed down to the comparisons (De Morgan).

    >>> print(negate(all_of(Cmp("q", ">=", Lin((("q0", 0.1),))), Cmp("q", "<=", Lin()))))
    q < 0.1*q0 | q > 0
    """
    if isinstance(g, Cmp):
        return Cmp(g.var, _NEG[g.op], g.rhs)
    if isinstance(g, AllOf):
        return any_of(*(negate(a) for a in g.args)) if g.args else FALSE
    return all_of(*(negate(a) for a in g.args)) if g.args else TRUE


def interior(g: Guard) -> Guard:
    """The same guard with every comparison strict (the interior of a closed band)."""
    if isinstance(g, Cmp):
        return Cmp(g.var, _STRICT[g.op], g.rhs)
    if isinstance(g, AllOf):
        return AllOf(tuple(interior(a) for a in g.args))
    return AnyOf(tuple(interior(a) for a in g.args))


def evaluate(g: Guard, env: Mapping[str, Any]) -> np.ndarray:
    """Evaluate ``g`` on arrays of a common shape (one entry per run); no ``eval``.

    >>> env = {"q": np.array([-0.5, 0.2]), "q0": np.array([-1.0, -1.0])}
    >>> evaluate(Cmp("q", ">", Lin((("q0", 0.9),))), env)
    array([ True,  True])
    >>> evaluate(Cmp("q", ">", Lin()), env)
    array([False,  True])
    """
    if isinstance(g, Cmp):
        return np.asarray(_OPS[g.op](env[g.var], g.rhs.value(env)))
    shape = np.shape(env["q"])
    if isinstance(g, AllOf):
        out = np.ones(shape, dtype=bool)
        for a in g.args:
            out &= evaluate(a, env)
        return out
    out = np.zeros(shape, dtype=bool)
    for a in g.args:
        out |= evaluate(a, env)
    return out


def variables(g: Guard) -> set[str]:
    """The variables a guard reads."""
    if isinstance(g, Cmp):
        return {g.var} | {v for v, _ in g.rhs.terms}
    out: set[str] = set()
    for a in g.args:
        out |= variables(a)
    return out


def guard_to_dict(g: Guard) -> dict[str, Any]:
    """The guard as nested JSON-able dicts (``cmp``, ``all``, ``any``)."""
    if isinstance(g, Cmp):
        return {"cmp": {"var": g.var, "op": g.op, "rhs": g.rhs.to_dict()}}
    key = "all" if isinstance(g, AllOf) else "any"
    return {key: [guard_to_dict(a) for a in g.args]}


def guard_from_dict(d: Mapping[str, Any]) -> Guard:
    """Inverse of :func:`guard_to_dict`."""
    if "cmp" in d:
        c = d["cmp"]
        return Cmp(str(c["var"]), str(c["op"]), Lin.from_dict(c.get("rhs", {})))
    if "all" in d:
        return AllOf(tuple(guard_from_dict(a) for a in d["all"]))
    if "any" in d:
        return AnyOf(tuple(guard_from_dict(a) for a in d["any"]))
    raise InputError(f"not a guard: {sorted(d)}")
