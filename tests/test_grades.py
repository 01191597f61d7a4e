"""Graded propositions (reward = shaped) against the monitor's robustness, and the graded reward by hand."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mitlc.monitor.offline import compile_pred
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.runtime import NetRuntime
from mitlc.spec import predicates as P
from mitlc.spec.grades import Grader
from mitlc.spec.parse import load_spec, parse_spec

# predicates over the mass-damper's q in [-1, 1] and qdot in [-5, 5]
_TERMS = st.one_of(
    st.sampled_from(["q", "qdot"]).map(P.Var),
    st.sampled_from([0.0, 0.2, -1.0, 1.5]).map(P.Num),
)
_ARITH = st.recursive(
    _TERMS,
    lambda c: st.one_of(
        st.builds(P.BinOp, st.sampled_from(["+", "-", "*"]), c, c),
        st.builds(lambda a: P.Call("abs", (a,)), c),
    ),
    max_leaves=3,
)
_CMP = st.builds(
    lambda ops, terms: P.Compare(tuple(terms[: len(ops) + 1]), tuple(ops)),
    st.lists(st.sampled_from(["<", "<=", ">", ">=", "==", "!="]), min_size=1, max_size=2),
    st.lists(_ARITH, min_size=3, max_size=3),
)
_BOOL = st.recursive(
    _CMP, lambda c: st.one_of(c.map(P.PNot), st.builds(P.PAnd, c, c), st.builds(P.POr, c, c)), max_leaves=3
)
PLANT = "plant mass-damper\ninit q in [-1, -0.5], qdot = 0\nhorizon 5\n"


def _spec(pred: P.Pred):
    return parse_spec(f"{PLANT}prop a = {pred}\nformula F G a")


@settings(max_examples=200, deadline=None)
@given(_BOOL, st.lists(st.tuples(st.floats(-1.5, 1.5), st.floats(-6.0, 6.0)), min_size=1, max_size=6))
def test_grades_are_the_monitors_robustness_scaled_and_clipped(pred, states):
    """With every comparison's scale set to 1 a grade is the monitor's robustness clipped to [-1, 1];
    with the box's scales its sign is still the proposition's truth (0 allowed on the boundary)."""
    spec = _spec(pred)
    grader = Grader.of(spec, ("a",))
    env = {"q": np.array([s[0] for s in states]), "qdot": np.array([s[1] for s in states])}
    truth, rob = compile_pred(spec.prop("a").pred)(env, (1, len(states)))
    unit = dataclasses.replace(grader, scales=tuple(tuple(1.0 for _ in row) for row in grader.scales))
    np.testing.assert_array_equal(unit.grades(env)[:, 0], np.clip(rob[0], -1.0, 1.0))
    g = grader.grades(env)[:, 0]
    assert np.all(np.abs(g) <= 1.0)
    assert np.all(g[truth[0]] >= 0.0) and np.all(g[~truth[0]] <= 0.0)
    assert all(s > 0 and math.isfinite(s) for row in grader.scales for s in row)


def test_small_goal_grades_by_hand():
    pred = parse_spec(f"{PLANT}prop t = abs(q - 0.5) < 0.2 and abs(qdot) < 0.3\nformula F t").prop("t").pred
    g = Grader.of(_spec(pred), ("a",))
    # 0.2 - |q - 0.5| over q in [-1, 1] is largest in size at q = -1 (-1.3); 0.3 - |qdot|, at qdot = +-5 (-4.7)
    assert g.scales == ((1.3, 4.7),)
    got = g.grades({"q": np.array([0.5, 0.0, 0.6, -1.0]), "qdot": np.array([0.0, 0.0, 0.3, 5.0])})[:, 0]
    want = [min(0.2 / 1.3, 0.3 / 4.7), min(-0.3 / 1.3, 0.3 / 4.7), min(0.1 / 1.3, 0.0), -1.0]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


@pytest.mark.parametrize("reward,mix", [("graded", 0.0), ("shaped", 0.5)])
def test_p1_graded_and_shaped_rewards_by_hand(reward, mix):
    """(1 + ~p_kappa) * (mix * (p_kappa - p_not_kappa) + (1 - mix) * g_kappa),
    g_kappa = clip((0.3 - |q|) / (pi - 0.3), -1, 1)."""
    spec = load_spec("pendulum/p1_swing_up")
    rs = compile_spec(spec, CompileOptions.from_spec(spec, reward=reward))
    assert str(rs.reward) == f"(1 + ~p_kappa) * {reward[0]}_kappa"
    rt = NetRuntime(rs)
    assert rt.tables is not None and rt.tables.reward is None  # the state is read: no reward table
    q = np.array([3.0, 0.5, 0.2, 0.1, -2.0])
    x = np.stack([q, np.zeros_like(q)], axis=1)
    M = rt.reset(x[:1])
    got = []
    for k in range(1, len(q)):
        M1 = rt.step(M, x[k : k + 1], k * 0.05)
        got.append(float(rt.reward(M, M1, x[k : k + 1])[0]))
        M = M1
    g = (0.3 - np.abs(q)) / (math.pi - 0.3)
    inside = np.abs(q) < 0.3
    want = (1.0 + inside[:-1]) * (mix * np.where(inside[1:], 1.0, -1.0) + (1.0 - mix) * g[1:])
    np.testing.assert_allclose(got, want, rtol=1e-15, atol=0)
    codes = rt.encode(rt.reset(x[:2]))
    np.testing.assert_array_equal(
        rt.reward_code(codes, codes, x[:2]), rt.reward(rt.decode(codes), rt.decode(codes), x[:2])
    )


def _scales(prop: str) -> tuple[float, ...]:
    return Grader.of(parse_spec(f"{PLANT}prop a = {prop}\nformula F a"), ("a",)).scales[0]


def test_scales_below_one_and_on_the_grid_by_hand():
    # 0.5 - |q| over q in [-1, 1]: +-0.5 at most, a scale under 1 is kept
    assert _scales("abs(q) < 0.5") == (0.5,)
    # |q| - 5 is largest in size at q = 0, which the grid of 4096 points (an even count over a
    # symmetric box) misses by one step: 2 / 4095 apart, the nearest points are +-1 / 4095
    assert _scales("abs(q) > 5") == (5.0 - 1.0 / 4095,)
    # a comparison of two constants has its own margin as scale: a grade of +-1
    g = Grader.of(parse_spec(f"{PLANT}prop a = 0.5 > 0 and q > 2\nprop b = 0.5 > 0\nformula F a"), ("a", "b"))
    assert g.scales == ((0.5, 3.0), (0.5,))
    got = g.grades({"q": np.array([0.0, 1.0]), "qdot": np.zeros(2)})
    np.testing.assert_allclose(got, [[-2.0 / 3.0, 1.0], [-1.0 / 3.0, 1.0]], rtol=0, atol=1e-15)


def test_a_grader_of_no_variables_grades_one_state():
    g = Grader.of(parse_spec(f"{PLANT}prop b = 0.5 > 0\nformula F b"), ("b",))
    np.testing.assert_array_equal(g.grades({}), [[1.0]])


def test_a_margin_the_monitor_reads_as_nan_grades_zero():
    """q / qdot at 0 / 0 is nan: neither near nor far, 0 (the monitor's robustness reads it so)."""
    g = Grader.of(parse_spec(f"{PLANT}prop a = q / qdot > 1\nformula F a"), ("a",))
    got = g.grades({"q": np.array([0.0, 2.0]), "qdot": np.array([0.0, 1.0])})[:, 0]
    assert got[0] == 0.0 and got[1] > 0.0


def test_the_box_grid_holds_at_most_grid_points_and_two_per_axis():
    from mitlc.spec.grades import GRID_POINTS, _box_grid

    one = _box_grid(["q"], {"q": (-1.0, 1.0)})
    assert one is not None and len(one["q"]) == GRID_POINTS == 4096
    assert one["q"][0] == -1.0 and one["q"][-1] == 1.0
    names = [f"v{i}" for i in range(12)]  # 4096 ** (1 / 12) = 2: the box's corners
    twelve = _box_grid(names, {n: (0.0, 1.0) for n in names})
    assert twelve is not None and all(len(twelve[n]) == 2**12 for n in names)
    assert sorted(set(twelve["v0"].tolist())) == [0.0, 1.0]
    assert _box_grid([], {}) == {}
    assert _box_grid(["q"], {}) is None


def test_without_plant_bounds_the_scale_is_one():
    """No plant, no box: the raw margin, clipped (the module text)."""
    g = Grader.of(parse_spec("prop a = x > 0.5\nformula F a"), ("a",))
    assert g.scales == ((1.0,),)
    np.testing.assert_allclose(g.grades({"x": np.array([0.7, 2.0, -3.0])})[:, 0], [0.2, 1.0, -1.0], atol=1e-15)


def test_margins_by_hand():
    from mitlc.spec.grades import margin

    a, b = np.array([1.0, -2.0, 0.5]), np.array([3.0, 1.0, 0.5])
    np.testing.assert_array_equal(margin("<", a, b), [2.0, 3.0, 0.0])
    np.testing.assert_array_equal(margin("<=", a, b), [2.0, 3.0, 0.0])
    np.testing.assert_array_equal(margin(">", a, b), [-2.0, -3.0, 0.0])
    np.testing.assert_array_equal(margin(">=", a, b), [-2.0, -3.0, 0.0])
    np.testing.assert_array_equal(margin("==", a, b), [-2.0, -3.0, -0.0])
    np.testing.assert_array_equal(margin("!=", a, b), [2.0, 3.0, 0.0])
