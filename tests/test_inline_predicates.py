"""Inline predicates in formulas: ``F[0,1.5] G (abs(q) < 0.3)`` means what the prop lines mean."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from strategies import formulas, grid_intervals

from mitlc.errors import SpecError, SpecSyntaxError
from mitlc.monitor.offline import monitor
from mitlc.petri.compile import compile_spec
from mitlc.petri.export import to_text
from mitlc.petri.render import to_digraph
from mitlc.runtime import NetRuntime
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_formula, parse_spec

PREDS = {"a": "abs(q) < 0.3", "b": "qdot * 2 > 3", "c": "0.3 < q < 2"}
NAMES = {"a": "abs_q_lt_0p3", "b": "qdot_times_2_gt_3", "c": "c_0p3_lt_q_lt_2"}
HEAD = "plant pendulum\nhorizon 3\n"


def test_the_issue_example_names_and_prints():
    spec = parse_spec(HEAD + "formula F[0,1.5] G (abs(q) < 0.3)\n")
    (p,) = spec.props
    assert (p.name, str(p.pred), p.inline) == ("abs_q_lt_0p3", "abs(q) < 0.3", True)
    assert str(spec.formula) == "F[0,1.5] G (abs(q) < 0.3)"
    rs = compile_spec(spec)
    assert "p_abs_q_lt_0p3" in rs.net.place_names
    text = to_text(rs)
    assert "abs_q_lt_0p3  abs(q) < 0.3  (inline)" in text
    assert "abs_q_lt_0p3: abs(q) < 0.3" in to_digraph(rs).source


def test_binding_and_sharing():
    f = parse_formula("G q < 1 & F x >= 0.45 U y")  # a comparison binds tighter than every operator
    assert str(f) == "G (q < 1) & F (x >= 0.45) U y"
    spec = parse_spec(HEAD + "prop kappa = abs(q) < 0.3\nformula F G (q < 1) & G (q < 1 | kappa)\n")
    assert [p.name for p in spec.props] == ["kappa", "q_lt_1"]  # one proposition for one predicate
    assert str(parse_formula("10 * (q < 1)")) == "10 * (q < 1)"
    assert parse_formula(str(f)) == f  # prints back to the same tree


@pytest.mark.parametrize(
    "formula, error, message, hint",
    [
        ("10 * q < 1", SpecError, "is ambiguous: write 10 * (q < 1)", None),
        ("(q + 1) < 2", SpecSyntaxError, "unexpected ')'", "2 > (q + 1)"),
        ("F G (kappa) < 1", SpecSyntaxError, "unexpected '<'", "prop kappa = ..."),
        ("F G kappa < 1", SpecError, "'kappa' is a proposition, not a number", "G kappa"),
        ("G (w < 1)", SpecError, "unknown state variable 'w'", None),
        ("G (obs[0] < 1)", SpecError, "only in a 'state' line", None),
    ],
)
def test_what_is_still_not_allowed_says_what_to_write(formula, error, message, hint):
    with pytest.raises(error) as err:
        parse_spec(HEAD + "prop kappa = abs(q) < 0.3\nformula " + formula + "\n", "s.mitl")
    e = err.value
    assert message in e.message and e.headline().startswith("s.mitl:4:")
    if hint is not None:
        assert e.hint is not None and hint in e.hint


def test_a_bare_comparison_after_a_weight_is_refused_in_a_formula_alone_too():
    with pytest.raises(SpecError, match="is ambiguous"):
        parse_formula("10 * q < 1")
    assert str(parse_formula("10 * (q < 1)")) == "10 * (q < 1)"


def test_a_name_taken_by_a_different_prop_is_an_error():
    with pytest.raises(SpecError, match="rename that proposition"):
        parse_spec(HEAD + "prop q_lt_1 = q > 5\nformula G (q < 1) & F q_lt_1\n")


def _inline(f: A.Formula) -> str:
    return re.sub(r"\b([abc])\b", lambda m: f"({PREDS[m.group(1)]})", str(f))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    formulas(atoms=("a", "b", "c"), interval=grid_intervals(step=0.5, max_end=3), max_leaves=5),
    st.integers(0, 2**31 - 1),
)
def test_inline_means_what_prop_lines_mean(f, seed):
    """The same net and reward, step by step, and the same verdicts, as with prop lines."""
    named = HEAD + "".join(f"prop {k} = {v}\n" for k, v in PREDS.items()) + f"formula {f}\n"
    inline = HEAD + f"formula {_inline(f)}\n"
    try:
        sa = parse_spec(named)
    except SpecError:
        return  # a formula the compiler refuses either way (checked below)
    sb = parse_spec(inline)
    assert {p.name: str(p.pred) for p in sb.props} == {NAMES[k]: PREDS[k] for k in PREDS if k in A.atoms(f)}
    ra, rb = compile_spec(sa), compile_spec(sb)
    assert ra.net.D.shape == rb.net.D.shape
    rng = np.random.default_rng(seed)
    dt, n = 0.5, 7
    x = np.stack([rng.uniform(-1, 2.5, (4, n)), rng.uniform(0, 3, (4, n))], axis=2)  # (runs, samples, [q, qdot])
    for rs_, spec in ((ra, sa), (rb, sb)):
        rt = NetRuntime(rs_, ("q", "qdot"), dt=dt, steps=n - 1)
        M = rt.reset(x[:, 0])
        rewards = []
        for k in range(1, n):
            M1 = rt.step(M, x[:, k], k * dt)
            rewards.append(rt.reward(M, M1))
            M = M1
        spec_rewards = np.array(rewards)
        if spec is sa:
            ref = spec_rewards
        else:
            np.testing.assert_allclose(spec_rewards, ref, rtol=0, atol=1e-12)
    va, vb = monitor(sa, x, dt), monitor(sb, x, dt)
    np.testing.assert_array_equal(va.satisfied, vb.satisfied)
    np.testing.assert_allclose(va.robustness, vb.robustness)
