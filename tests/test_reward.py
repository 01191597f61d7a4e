"""The reward expressions of Table 4-2, one node at a time: values by hand, printing, bounds
against a brute force over every marking pair."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mitlc.petri import reward as R

A, B = R.Tokens((0,), ("p_a",)), R.Tokens((1,), ("p_b",))
AB = R.Tokens((0, 1), ("p_a", "p_b"))


def m(*rows: tuple[int, ...]) -> np.ndarray:
    return np.array(rows, dtype=np.int64)


def test_tokens_now_and_one_step_ago():
    prev, now = m((1, 0, 0)), m((0, 1, 0))
    assert A.evaluate(prev, now).tolist() == [0.0] and A.previous().evaluate(prev, now).tolist() == [1.0]
    assert A.previous().prev and not A.prev and str(A.previous()) == "~p_a"
    assert AB.evaluate(m((1, 1, 0)), m((1, 1, 1))).tolist() == [2.0]
    assert str(AB) == "(p_a + p_b)" and str(AB.previous()) == "(~p_a + ~p_b)"


def test_products_sums_and_printing():
    # (1 + ~p_a) * (p_a - p_b): the reward of F G a over the region net {a, b}
    e = R.Prod((R.Sum((R.ONE, A.previous())), R.Sum((A, R.Neg(B)))))
    prev = m((1, 0), (0, 1), (1, 0))
    now = m((1, 0), (1, 0), (0, 1))
    assert e.evaluate(prev, now).tolist() == [2.0, 1.0, -2.0]
    assert str(e) == "(1 + ~p_a) * (p_a - p_b)"
    assert str(R.Neg(R.Sum((A, B)))) == "-(p_a + p_b)"
    assert str(R.Const(-2.0)) == "(-2)"


def test_a_gated_term_is_its_gate_times_its_expression():
    g = R.Gated(A.previous(), R.Sum((B, R.Neg(A))))
    assert g.evaluate(m((1, 0), (0, 1)), m((0, 1), (0, 1))).tolist() == [1.0, 0.0]
    assert str(g) == "~p_a * (p_b - p_a)"


def test_min_literal_and_active():
    closed, open_ = R.Gated(A, R.Const(-5.0)), R.Gated(B, R.Const(3.0))
    prev = now = m((0, 1), (0, 0), (1, 1))
    assert R.Min((closed, open_)).evaluate(prev, now).tolist() == [0.0, 0.0, -5.0]  # a closed gate pays 0
    # active: the min over the open terms only, 0 when none is open
    assert R.Min((closed, open_), active=True).evaluate(prev, now).tolist() == [3.0, 0.0, -5.0]
    assert R.Min((closed, R.Const(1.0)), active=True).evaluate(prev, now).tolist() == [1.0, 1.0, -5.0]
    assert str(R.Min((A, B), active=True)) == "min_active(p_a, p_b)" and str(R.Min((A, B))) == "min(p_a, p_b)"
    assert R.Max((closed, open_)).evaluate(prev, now).tolist() == [3.0, 0.0, 3.0]


def test_scale_folds_constants():
    assert R.scale(1.0, A) is A
    assert str(R.scale(3.0, A)) == "3 * p_a"
    assert str(R.scale(2.0, R.scale(3.0, A))) == "6 * p_a"
    assert str(R.scale(2.0, R.Prod((A, B)))) == "2 * p_a * p_b"


# every expression over two places, now and one step ago, to a small depth
_LEAVES = st.sampled_from([A, B, A.previous(), B.previous(), R.ONE, R.ZERO, R.Const(-2.0), R.Const(0.5)])


def _extend(children: st.SearchStrategy[R.RExpr]) -> st.SearchStrategy[R.RExpr]:
    pair = st.lists(children, min_size=2, max_size=3).map(tuple)
    return st.one_of(
        children.map(R.Neg),
        pair.map(R.Sum),
        pair.map(R.Prod),
        pair.map(R.Min),
        pair.map(lambda t: R.Min(t, active=True)),
        pair.map(R.Max),
        st.builds(R.Gated, st.sampled_from([A, B, A.previous()]), children),
    )


_EXPRS = st.recursive(_LEAVES, _extend, max_leaves=6)
_ALL = np.array(list(itertools.product((0, 1), repeat=2)), dtype=np.int64)
PREV, NOW = np.repeat(_ALL, len(_ALL), axis=0), np.tile(_ALL, (len(_ALL), 1))


@settings(max_examples=300, deadline=None)
@given(_EXPRS)
def test_bounds_hold_every_marking_pair(e):
    lo, hi = R.bounds(e)
    values = e.evaluate(PREV, NOW)
    assert lo - 1e-12 <= values.min() and values.max() <= hi + 1e-12


def test_bounds_are_tight_where_no_place_repeats():
    cases = {
        R.Prod((R.Sum((R.ONE, A.previous())), R.Sum((A, R.Neg(B))))): (-2.0, 2.0),
        R.Neg(R.Sum((A, B))): (-2.0, 0.0),
        R.Prod((R.Const(-2.0), A)): (-2.0, 0.0),
        R.Gated(A, R.Const(3.0)): (0.0, 3.0),
        R.Min((A, R.Const(-1.0))): (-1.0, -1.0),
        R.Min((R.Gated(A, R.Const(-5.0)), R.Gated(B, R.Const(3.0))), active=True): (-5.0, 3.0),
        R.Max((A, R.Const(-1.0))): (0.0, 1.0),
        R.Const(0.5): (0.5, 0.5),
        # active, every term positive: with no gate open the reward is 0, so 0 bounds it below
        R.Min((R.Gated(A, R.Const(2.0)), R.Gated(B, R.Const(3.0))), active=True): (0.0, 3.0),
    }
    for e, want in cases.items():
        assert R.bounds(e) == want, str(e)
        values = e.evaluate(PREV, NOW)
        assert (values.min(), values.max()) == want, str(e)


def test_printing_parenthesises_by_precedence():
    """What mitlc compile prints: sums inside products and negations get parentheses, a sum's
    terms flatten, a nested product keeps its own (it is one factor), negative constants are wrapped."""
    cases = {
        R.Prod((R.Sum((A, B)), R.Neg(R.Sum((A, B))))): "(p_a + p_b) * -(p_a + p_b)",
        R.Neg(R.Prod((A, B))): "-(p_a * p_b)",
        R.Sum((R.Prod((A, B)), R.Neg(A), R.Const(-1.0))): "p_a * p_b - p_a + (-1)",
        R.Prod((R.Neg(A), R.Gated(B, R.Sum((A, R.ONE))))): "-p_a * (p_b * (p_a + 1))",
        R.Gated(R.Sum((A, B)), R.Prod((A, R.Neg(B)))): "(p_a + p_b) * (p_a * -p_b)",
        R.Neg(R.Neg(A)): "-(-p_a)",
        R.Sum((A, R.Sum((A, B)))): "p_a + p_a + p_b",
        R.Prod((A, R.Prod((A, B)))): "p_a * (p_a * p_b)",
        R.Sum((A, R.Const(0.0))): "p_a + 0",
    }
    for e, text in cases.items():
        assert str(e) == text


# graded propositions: a over places {0: p_a, 1: p_not_a}, b over {2: p_b, 3: p_not_b}
GA = R.Graded("a", 0, R.Sum((R.Tokens((0,), ("p_a",)), R.Neg(R.Tokens((1,), ("p_not_a",))))))
GNB = R.Graded("b", 1, R.Sum((R.Tokens((3,), ("p_not_b",)), R.Neg(R.Tokens((2,), ("p_b",))))), negated=True)
SA = R.Graded("a", 0, GA.flat, mix=0.5)  # reward = shaped: half the flat value, half the grade
_G_LEAVES = st.sampled_from(
    [GA, GNB, SA, R.Tokens((0,), ("p_a",)), R.Tokens((2,), ("p_b",), True), R.ONE, R.Const(-2.0), R.Const(0.5)]
)


def _g_extend(children: st.SearchStrategy[R.RExpr]) -> st.SearchStrategy[R.RExpr]:
    pair = st.lists(children, min_size=2, max_size=3).map(tuple)
    gates = st.sampled_from([R.Tokens((0,), ("p_a",)), R.Tokens((2,), ("p_b",), True)])
    return st.one_of(
        children.map(R.Neg),
        pair.map(R.Sum),
        pair.map(R.Prod),
        pair.map(R.Min),
        pair.map(lambda t: R.Min(t, active=True)),
        pair.map(R.Max),
        st.builds(R.Gated, gates, children),
    )


_G_EXPRS = st.recursive(_G_LEAVES, _g_extend, max_leaves=6)
# every marking pair of two two-place region nets, each with grades whose signs agree with it
_REGION = np.array([[1, 0, 1, 0], [1, 0, 0, 1], [0, 1, 1, 0], [0, 1, 0, 1]], dtype=np.int64)
G_PREV, G_NOW = np.repeat(_REGION, 4, axis=0), np.tile(_REGION, (4, 1))


@settings(max_examples=300, deadline=None)
@given(_G_EXPRS, st.lists(st.floats(0.0, 1.0), min_size=2 * len(G_NOW), max_size=2 * len(G_NOW)))
def test_pair_bounds_hold_for_every_grade_the_marking_allows(e, sizes):
    """reward.pair_bounds (what the violation penalty is sized from) holds every value a graded
    reward takes: grades in [0, 1] where the marking says the proposition holds, [-1, 0] where not;
    without graded leaves the bounds are the value itself."""
    lo, hi = R.pair_bounds(e, G_PREV, G_NOW)
    holds = np.stack([G_NOW[:, 0] == 1, G_NOW[:, 2] == 1], axis=1)
    size = np.array(sizes).reshape(len(G_NOW), 2)
    for grades in (np.where(holds, size, -size), np.where(holds, 1.0, -1.0), np.where(holds, 0.0, -0.0)):
        v = e.evaluate(G_PREV, G_NOW, grades)
        assert np.all(lo - 1e-12 <= v) and np.all(v <= hi + 1e-12), str(e)
    if not R.is_graded(e):
        np.testing.assert_array_equal(lo, e.evaluate(G_PREV, G_NOW))
        np.testing.assert_array_equal(hi, e.evaluate(G_PREV, G_NOW))
    lo_all, hi_all = R.bounds(e)  # the interval bounds over everything hold them too
    assert lo_all - 1e-12 <= lo.min() and hi.max() <= hi_all + 1e-12


def test_graded_leaves_by_hand():
    prev = now = np.array([[1, 0, 1, 0], [0, 1, 1, 0]])
    grades = np.array([[0.25, 0.5], [-0.75, 0.5]])
    assert GA.evaluate(prev, now, grades).tolist() == [0.25, -0.75]
    assert GNB.evaluate(prev, now, grades).tolist() == [-0.5, -0.5]
    assert str(GA) == "g_a" and str(GNB) == "-g_b" and R.is_graded(R.Sum((A, GA))) and not R.is_graded(A)
    assert SA.evaluate(prev, now, grades).tolist() == [0.625, -0.875] and str(SA) == "s_a"
    lo, hi = R.pair_bounds(SA, prev, now)
    assert lo.tolist() == [0.5, -1.0] and hi.tolist() == [1.0, -0.5]
    lo, hi = R.pair_bounds(R.Prod((R.Const(3.0), GA, GNB)), prev, now)  # a true / false, b true
    assert lo.tolist() == [-3.0, 0.0] and hi.tolist() == [0.0, 3.0]
    with pytest.raises(ValueError, match="needs the grades"):
        GA.evaluate(prev, now)
