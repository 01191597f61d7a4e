"""The normal-form passes keep a formula's meaning: checked against the monitor, which reads
``->``, ``<->``, ``W``, ``R``, ``true`` and ``false`` directly (an independent reading)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import formulas, grid_intervals

from mitlc.monitor.offline import monitor
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_formula, parse_spec
from mitlc.spec.passes import desugar, is_state_formula, normal_form, push_negations

SPEC = parse_spec("prop a = x > 0\nprop b = y > 0\nprop c = x > y\nformula F a\n")


def _traces(seed: int, runs: int = 6, n: int = 9) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {"x": rng.normal(size=(runs, n)), "y": rng.normal(size=(runs, n))}


def _in_normal_form(f: A.Formula) -> bool:
    for node in A.walk(f):
        if isinstance(node, (A.Implies, A.Iff, A.WeakUntil)):
            return False
        if isinstance(node, A.Not) and not isinstance(node.child, A.Atom):
            return False
    return True


@settings(max_examples=300, deadline=None)
@given(formulas(atoms=("a", "b", "c"), interval=grid_intervals(step=0.5, max_end=3), max_leaves=6), st.integers(0, 999))
def test_normal_form_means_the_same_on_random_traces(f, seed):
    nf = normal_form(f)
    assert _in_normal_form(nf)
    tr = _traces(seed)
    want, got = monitor(SPEC, tr, 0.5, f), monitor(SPEC, tr, 0.5, nf)
    np.testing.assert_array_equal(got.satisfied, want.satisfied)
    np.testing.assert_allclose(got.robustness, want.robustness, rtol=1e-12, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(formulas(atoms=("a", "b"), interval=grid_intervals(step=0.5, max_end=3), max_leaves=5), st.integers(0, 999))
def test_each_pass_alone_keeps_the_meaning(f, seed):
    tr = _traces(seed)
    want = monitor(SPEC, tr, 0.5, f).satisfied
    d = desugar(f)
    assert not any(isinstance(n, (A.Implies, A.Iff, A.WeakUntil)) for n in A.walk(d))
    np.testing.assert_array_equal(monitor(SPEC, tr, 0.5, d).satisfied, want)
    neg = push_negations(d, negate=True)  # the negation, pushed to the atoms: the opposite verdict
    np.testing.assert_array_equal(monitor(SPEC, tr, 0.5, neg).satisfied, ~want)


def test_the_rewrites_by_hand():
    cases = {
        "a -> b": "!a | b",
        "a <-> b": "(!a | b) & (a | !b)",
        "a W[0,2] b": "a U[0,2] b | G[0,2] a",
        "!(a & true)": "!a | false",
        "!(2 * F[1,2] a)": "2 * G[1,2] !a",
        "!(a U b)": "!a R !b",
        "!(a R[0,1] b)": "!a U[0,1] !b",
        "!!a": "a",
        "!G F a": "F G !a",
    }
    for text, want in cases.items():
        assert str(normal_form(parse_formula(text))) == want, text


def test_state_formulas():
    assert is_state_formula(parse_formula("a & !(b | true) & 2 * c"))
    assert not is_state_formula(parse_formula("a & F b"))
    assert not is_state_formula(parse_formula("a U b"))
