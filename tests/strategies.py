"""Hypothesis strategies for mitlc formulas, for any test module to reuse.

``formulas()`` draws syntax trees built from every node type of
:mod:`mitlc.spec.ast`; its printed text always parses back to an equal tree.

    from strategies import formulas            # tests/ is on sys.path under pytest
    @given(formulas(atoms=("a", "b")))
    def test_something(f): ...
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from hypothesis import strategies as st

from mitlc.spec import ast as A

__all__ = ["ATOMS", "bounds", "intervals", "grid_intervals", "weights", "formulas", "state_formulas"]

ATOMS = ("a", "b", "c", "kappa", "psi_2")
"""Default proposition names (none is a reserved word)."""


def bounds(max_value: float = 1e6) -> st.SearchStrategy[float]:
    """Finite non-negative interval ends: small integers, halves, and arbitrary floats."""
    return st.one_of(
        st.integers(0, 10).map(float),
        st.sampled_from([0.5, 0.25, 1.5, 0.1, 0.03, 2.5, 1e-5]),
        st.floats(min_value=0.0, max_value=max_value, allow_nan=False, allow_infinity=False),
    )


@st.composite
def _interval(draw: st.DrawFn, ends: st.SearchStrategy[float], unbounded: bool) -> A.Interval:
    lo, hi = sorted((draw(ends), draw(ends)))
    if unbounded and draw(st.integers(0, 3)) == 0:
        hi = math.inf
    if lo == hi:
        return A.Interval(lo, hi, True, True)  # a point interval must be closed
    return A.Interval(lo, hi, draw(st.booleans()), draw(st.booleans()))


def intervals(ends: st.SearchStrategy[float] | None = None, unbounded: bool = True) -> st.SearchStrategy[A.Interval]:
    """Valid intervals (``lo <= hi``, non-empty), open or closed at either end.

    About a quarter are ``[0,inf)`` (the untimed operators); with ``unbounded``
    some others reach ``inf`` too.
    """
    ends = bounds() if ends is None else ends
    finite = _interval(ends, unbounded)
    return st.integers(0, 3).flatmap(lambda i: st.just(A.UNBOUNDED) if i == 0 else finite)


def grid_intervals(step: float = 0.5, max_end: int = 6, unbounded: bool = True) -> st.SearchStrategy[A.Interval]:
    """Intervals whose ends are multiples of ``step`` (so they fall exactly on sample times)."""
    return intervals(st.integers(0, max_end).map(lambda i: i * step), unbounded)


def weights() -> st.SearchStrategy[float]:
    """Positive finite weights."""
    return st.one_of(
        st.integers(1, 100).map(float),
        st.floats(min_value=1e-3, max_value=1e6, allow_nan=False, allow_infinity=False, exclude_min=False),
    )


def state_formulas(atoms: Sequence[str] = ATOMS, max_leaves: int = 6) -> st.SearchStrategy[A.Formula]:
    """Formulas without temporal operators."""
    leaves = st.one_of(st.sampled_from(tuple(atoms)).map(A.Atom), st.booleans().map(A.Const))

    def extend(children: st.SearchStrategy[A.Formula]) -> st.SearchStrategy[A.Formula]:
        return st.one_of(
            children.map(A.Not),
            st.builds(A.And, children, children),
            st.builds(A.Or, children, children),
            st.builds(A.Implies, children, children),
            st.builds(A.Iff, children, children),
        )

    return st.recursive(leaves, extend, max_leaves=max_leaves)


def formulas(
    atoms: Sequence[str] = ATOMS,
    interval: st.SearchStrategy[A.Interval] | None = None,
    max_leaves: int = 8,
    weighted: bool = True,
    constants: bool = True,
) -> st.SearchStrategy[A.Formula]:
    """MITL formulas over ``atoms`` using every node type of :mod:`mitlc.spec.ast`."""
    iv = intervals() if interval is None else interval
    leaf_choices = [st.sampled_from(tuple(atoms)).map(A.Atom)]
    if constants:
        leaf_choices.append(st.booleans().map(A.Const))
    leaves = st.one_of(*leaf_choices)

    def extend(children: st.SearchStrategy[A.Formula]) -> st.SearchStrategy[A.Formula]:
        options = [
            children.map(A.Not),
            st.builds(A.And, children, children),
            st.builds(A.Or, children, children),
            st.builds(A.Implies, children, children),
            st.builds(A.Iff, children, children),
            st.builds(A.Eventually, children, iv),
            st.builds(A.Globally, children, iv),
            st.builds(A.Until, children, children, iv),
            st.builds(A.Release, children, children, iv),
            st.builds(A.WeakUntil, children, children, iv),
        ]
        if weighted:
            options.append(st.builds(A.Weighted, weights(), children))
        return st.one_of(*options)

    return st.recursive(leaves, extend, max_leaves=max_leaves)
