"""The compiler against the thesis's appendix C nets and rewards (4-12)..(4-18)."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from mitlc.errors import MitlError
from mitlc.petri.compile import CompileOptions, compile_spec, trigger
from mitlc.spec.parse import load_spec, parse_formula, parse_spec

ROOT = Path(__file__).resolve().parent.parent
FIXTURES = json.loads((Path(__file__).parent / "fixtures" / "thesis_nets.json").read_text())
PROBLEMS = [k for k in FIXTURES if not k.startswith("_")]


def compiled(name: str, conjunction: str = "literal"):
    spec = load_spec(ROOT / "specs" / "pendulum" / f"{name}.mitl")
    return compile_spec(spec, CompileOptions.from_spec(spec, conjunction=conjunction))


@pytest.mark.parametrize("name", PROBLEMS)
def test_net_matches_appendix_c(name: str) -> None:
    want = FIXTURES[name]
    net = compiled(name).net
    assert sorted(net.place_names) == sorted(want["places"])
    order = [net.place_index(p) for p in want["places"]]
    got_rows = Counter((tuple(int(v) for v in net.D[t, order]), str(tr.guard)) for t, tr in enumerate(net.transitions))
    want_rows = Counter((tuple(row), guard) for row, guard in zip(want["D"], want["guards"], strict=True))
    assert got_rows == want_rows
    assert net.M0[order].tolist() == want["M0"]
    # D = D+ - D-, with one input and one output place per transition
    assert np.array_equal(net.D, net.D_plus - net.D_minus)
    assert (net.D_minus.sum(axis=1) == 1).all() and (net.D_plus.sum(axis=1) == 1).all()


@pytest.mark.parametrize("name", PROBLEMS)
def test_place_kinds(name: str) -> None:
    net = compiled(name).net
    for p in net.places:
        assert p.kind == ("timing" if p.name.startswith(("p_tau", "p_1<")) else "state")


def _thesis_reward(name: str, p, pt) -> np.ndarray:
    """The thesis's printed reward, in terms of token counts now (p) and one step ago (pt)."""
    if name == "p1_swing_up":  # (4-12)
        return (1 + pt("p_kappa")) * (p("p_kappa") - p("p_not_kappa"))
    if name in ("p2_avoid", "p3_avoid_speed_limit"):  # (4-13), (4-16) with (4-14)
        not_kappa = lambda f: f("p_psi") + f("p_none_kappa_psi")  # noqa: E731
        not_psi = lambda f: f("p_kappa") + f("p_none_kappa_psi")  # noqa: E731
        terms = [
            (1 + pt("p_kappa")) * (p("p_kappa") - not_kappa(p)),
            10 * (1 + not_psi(pt)) * (not_psi(p) - p("p_psi")),
        ]
        if name == "p3_avoid_speed_limit":
            terms.append(10 * (1 + pt("p_upsilon")) * (p("p_upsilon") - p("p_not_upsilon")))
        return np.minimum.reduce(terms)
    if name == "p4_alternate":  # (4-17)
        region = ["p_kappa", "p_upsilon", "p_psi", "p_none_kappa_upsilon_psi"]
        others = lambda f, x: sum(f(r) for r in region if r != x)  # noqa: E731
        return np.minimum.reduce(
            [
                5 * (1 + pt("p_kappa")) * pt("p_tau_kappa") * (p("p_kappa") - others(p, "p_kappa")),
                5 * (1 + pt("p_upsilon")) * pt("p_tau_upsilon") * (p("p_upsilon") - others(p, "p_upsilon")),
                25 * (1 + others(pt, "p_psi")) * (others(p, "p_psi") - p("p_psi")),
            ]
        )
    if name == "p5_timed_visit":  # (4-18)
        return (
            2 * p("p_tau<=1") * (p("p_not_kappa") - p("p_kappa"))
            + 3 * p("p_1<tau<=2") * (p("p_kappa") - p("p_not_kappa"))
            + p("p_tau>2") * (1 + pt("p_not_kappa")) * (p("p_not_kappa") - p("p_kappa"))
        )
    raise KeyError(name)


@pytest.mark.parametrize("name", PROBLEMS)
def test_reward_equals_thesis_on_every_reachable_pair(name: str) -> None:
    rs = compiled(name)
    net = rs.net
    pairs = list(net.step_pairs())
    prev = np.array([a for a, _ in pairs])
    now = np.array([b for _, b in pairs])
    p = lambda n: now[:, net.place_index(n)].astype(float)  # noqa: E731
    pt = lambda n: prev[:, net.place_index(n)].astype(float)  # noqa: E731
    want = _thesis_reward(name, p, pt)
    got = rs.reward.evaluate(prev, now)
    assert len(pairs) >= 4
    np.testing.assert_array_equal(got, want)


def test_reward_by_hand_problem_2() -> None:
    rs = compiled("p2_avoid")
    net = rs.net
    m = lambda *names: np.array([[1 if p in names else 0 for p in net.place_names]])  # noqa: E731
    # staying in kappa: min((1+1)(1-0), 10 (1+1)(1-0)) = 2
    assert rs.reward.evaluate(m("p_kappa"), m("p_kappa")).tolist() == [2.0]
    # entering psi from "none": min((1+0)(0-1), 10 (1+1)(0-1)) = -20
    assert rs.reward.evaluate(m("p_none_kappa_psi"), m("p_psi")).tolist() == [-20.0]
    # psi to kappa: min((1+0)(1-0), 10 (1+0)(1-0)) = 1
    assert rs.reward.evaluate(m("p_psi"), m("p_kappa")).tolist() == [1.0]


def test_active_conjunction_problem_4() -> None:
    """With the active reading the inactive target's zero term leaves the min."""
    rs = compiled("p4_alternate", conjunction="active")
    net = rs.net
    m = lambda *names: np.array([[1 if p in names else 0 for p in net.place_names]])  # noqa: E731
    # token on tau_kappa, pendulum arrives in kappa: kappa term (1+0)*1*(1-0)*5 = 5,
    # psi term 25*(1+1)*(1-0) = 50; upsilon term is gated off -> min(5, 50) = 5
    prev, now = m("p_tau_kappa", "p_none_kappa_upsilon_psi"), m("p_tau_upsilon", "p_kappa")
    assert rs.reward.evaluate(prev, now).tolist() == [5.0]
    literal = compiled("p4_alternate").reward.evaluate(prev, now)
    assert literal.tolist() == [0.0]  # the upsilon term ~p_tau_upsilon * ... = 0 caps the literal min


def test_state_groups_follow_disjointness() -> None:
    assert compiled("p3_avoid_speed_limit").groups == (("kappa", "psi"), ("upsilon",))
    assert compiled("p4_alternate").groups == (("kappa", "upsilon", "psi"),)


def spec_with(formula: str, props: str | None = None) -> str:
    props = props or ("prop a = x < 0\nprop b = x > 1\nprop c = y < 0\nprop d = 0 < x < 1 and y > 2\n")
    return f"{props}formula {formula}\n"


def test_untimed_until_switches_on_right_side() -> None:
    rs = compile_spec(parse_spec(spec_with("a U c")))
    net = rs.net
    (t,) = [t for t in net.transitions if net.subnets[t.subnet].role == "until"]
    assert str(t.guard) == "c"
    assert str(rs.reward) == "p_until_U1 * (p_a - p_not_a) + p_after_U1 * (p_c - p_not_c)"


def test_bounded_until_has_deadline() -> None:
    rs = compile_spec(parse_spec(spec_with("a U[0,2] c")))
    (t,) = [t for t in rs.net.transitions if rs.net.subnets[t.subnet].role == "until"]
    assert str(t.guard) == "c | tau > 2"


def test_eventually_state_formula_has_done_place() -> None:
    rs = compile_spec(parse_spec(spec_with("F a & G !c")))
    roles = [s.role for s in rs.net.subnets]
    assert roles.count("eventually") == 1
    assert "~p_tau_a * (p_a - " in str(rs.reward)


def test_timed_eventually_window() -> None:
    rs = compile_spec(parse_spec(spec_with("F[1,2] a")))
    net = rs.net
    assert [p.name for p in net.places if net.subnets[p.subnet].role == "timeline"] == [
        "p_tau<1",
        "p_1<=tau<=2",
        "p_tau>2",
    ]
    (t,) = [t for t in net.transitions if net.subnets[t.subnet].role == "eventually"]
    assert str(t.guard) == "a & 1 <= tau <= 2"


def test_single_recurrence_is_trivial() -> None:
    rs = compile_spec(parse_spec(spec_with("G F a")))
    assert [s.role for s in rs.net.subnets] == ["region"]
    assert str(rs.reward) == "(1 + ~p_a) * (p_a - p_not_a)"


def test_three_recurrences_share_one_token() -> None:
    rs = compile_spec(parse_spec(spec_with("G F a & G F b & G F c")))
    (cycle,) = [s for s in rs.net.subnets if s.role == "recurrence"]
    assert len(cycle.places) == 3 and int(rs.net.M0[list(cycle.places)].sum()) == 1


def test_negation_pushed_through_duals() -> None:
    rs = compile_spec(parse_spec(spec_with("!(F a | G !b)")))
    assert str(rs.normal_form) == "G !a & F b"


def test_trigger_of_temporal_right_sides() -> None:
    assert str(trigger(parse_formula("G a & F b"))) == "a"
    assert str(trigger(parse_formula("G[1,2] a"))) == "true"


def test_unknown_conjunction_reading() -> None:
    with pytest.raises(MitlError, match="conjunction"):
        compile_spec(parse_spec(spec_with("a & b")), CompileOptions(conjunction="mean"))


def _stepped(rs, qs, dt=0.5):
    from mitlc.runtime import NetRuntime

    x = np.array([[[q, 0.0] for q in qs]])
    rt = NetRuntime(rs, ("q", "qdot"), dt=dt, steps=len(qs) - 1)
    M = rt.reset(x[:, 0])
    out = []
    for k in range(1, len(qs)):
        M1 = rt.step(M, x[:, k], k * dt)
        out.append(float(rt.reward(M, M1, x[:, k] if rs.grader is not None else None)[0]))
        M = M1
    return out


def test_a_bounded_eventually_pays_only_in_its_window_under_the_trial_clock():
    """F[0,1] a, trial clock: gated by the timeline token of [0,1] one step ago and by its own token."""
    spec = parse_spec("plant pendulum(dt = 0.5)\nhorizon 3\noption clock = trial\nprop a = q > 1\nformula F[0,1] a\n")
    rs = compile_spec(spec)
    assert str(rs.reward) == "(~p_tau_a * ~p_tau<=1) * (p_a - p_not_a)"
    assert _stepped(rs, [2.0] * 7) == [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # met at once: paid once
    # never met in time: -1 while the window was open a step ago (t = 0.5, 1, 1.5), nothing after
    assert _stepped(rs, [0.0, 0.0, 0.0, 0.0, 2.0, 2.0, 2.0]) == [-1.0, -1.0, -1.0, 0.0, 0.0, 0.0]


def test_a_part_no_trial_can_satisfy_is_warned_of_under_the_standard_clock_only():
    spec = parse_spec("plant pendulum(dt = 0.5)\nhorizon 3\nprop a = q > 1\nformula F[4,5] a & F a\n", "s.mitl")
    (warning,) = compile_spec(spec, CompileOptions.from_spec(spec, clock="standard")).warnings
    assert warning.startswith("s.mitl: warning: 'F[4,5] a' cannot be satisfied within the horizon 3 s")
    assert "not before t = 4 s" in warning
    assert compile_spec(spec, CompileOptions.from_spec(spec, clock="trial")).warnings == ()
    ok = parse_spec("plant pendulum(dt = 0.5)\nhorizon 3\nprop a = q > 1\nformula F[0,1] G a\n")
    assert compile_spec(ok).warnings == ()
    # the last sample, t = 3 s (100 steps of 0.03 s, 3.0000000000000004 in floating point), still counts
    at_end = parse_spec("plant pendulum\nhorizon 3\nprop a = q > 1\nformula F[3,4] a\n")
    assert compile_spec(at_end).warnings == ()


def test_options_come_from_the_spec_unless_given():
    spec = parse_spec(
        "plant pendulum\nhorizon 3\noption conjunction = active\noption clock = trial\n"
        "prop a = q > 1\nformula F a & G a\n"
    )
    o = CompileOptions.from_spec(spec)
    assert (o.conjunction, o.violations, o.clock) == ("active", "off", "trial")
    o = CompileOptions.from_spec(spec, conjunction="literal", violations=None, clock="standard")
    assert (o.conjunction, o.violations, o.clock) == ("literal", "off", "standard")  # None keeps the spec's


def test_nested_weights_multiply():
    head = "plant pendulum(dt = 0.5)\nhorizon 3\nprop a = q > 1\nprop b = q < -1\n"
    nested = compile_spec(parse_spec(head + "formula F G a & 2 * (3 * G !b)\n"))
    flat = compile_spec(parse_spec(head + "formula F G a & 6 * G !b\n"))
    one = compile_spec(parse_spec(head + "formula F G a & G !b\n"))
    qs = [0.0, -2.0, 0.5, 2.0, 2.0, -2.0, 2.0]
    assert _stepped(nested, qs) == _stepped(flat, qs)
    assert _stepped(nested, qs) != _stepped(one, qs)


def test_the_switch_guard_of_a_timed_until_under_the_trial_clock():
    """a U (phi U[1,2] c): the token leaves 'until' for 'after' when phi holds; with phi = true
    the switch has no condition at all (one empty guard term), not a state condition 'true'."""
    head = "plant pendulum(dt = 0.5)\nhorizon 3\noption clock = trial\nprop a = q > 1\nprop b = q < -1\n"
    head += "prop c = abs(q) < 0.5\n"

    def switch(formula):
        rs = compile_spec(parse_spec(head + f"formula {formula}\n"))
        (t,) = [t for t in rs.net.transitions if t.inputs == ("p_until_U1",) and t.outputs == ("p_after_U1",)]
        return t.guard

    assert str(switch("a U (b U[1,2] c)")) == "b"
    g = switch("a U (true U[1,2] c)")
    assert str(g) == "true" and len(g.terms) == 1 and g.terms[0].state is None and g.terms[0].clock is None


def test_a_weight_inside_a_timed_part_scales_its_gated_reward():
    head = "plant pendulum(dt = 0.5)\nhorizon 3\nprop a = q > 1\n"
    qs = [0.0, 2.0, 2.0, 0.0, 2.0, 2.0, 2.0]
    plain = _stepped(compile_spec(parse_spec(head + "formula F[0,2] G a\n")), qs)
    inner = compile_spec(parse_spec(head + "formula F[0,2] (2 * G a)\n"))
    assert (  # the gates stay outside
        str(inner.reward)
        == "~p_open_G1 * (2 * (1 + ~p_a) * (p_a - p_not_a)) + (~p_open_F2 * ~p_idle_G1) * (2 * (p_a - p_not_a)) "
        "+ ~p_failed_F2 * (2 * (p_a - p_not_a) + (-1))"
    )
    assert _stepped(inner, qs) == [2 * r for r in plain] == [2.0, 4.0, -4.0, 2.0, 4.0, 4.0]


def test_a_sequence_pays_the_next_step_once_its_first_is_done():
    """``F[0,2] (a & F[0,2] G b)``, a and b disjoint: once an instance of ``F[0,2] G b`` is live (it
    started where a held), the reward is that instance's alone, so leaving a for b pays. The literal
    ``min(r_a, ...)`` paid -1 on every step away from a, b included, and learners stayed at a. By
    hand, dt = 0.5: a at t = 0.5, then b from t = 1.5: -1 (the first step sees the reset's open
    tokens: r_b, -1 at a), -1 (away from both), +1 (b, G's instance not yet open), then
    ``(1 + ~b) * r_b`` = 2."""
    head = "plant pendulum(dt = 0.5)\nhorizon 4\nprop a = q > 1\nprop b = q < -1\n"
    rs = compile_spec(parse_spec(head + "formula F[0,2] (a & F[0,2] G b)\n"))
    assert str(rs.reward).startswith("~p_idle_F2 * min(p_a - (p_b + p_none_a_b), ")
    assert _stepped(rs, [0.0, 2.0, 0.0, -2.0, -2.0, -2.0, -2.0, -2.0, -2.0]) == [-1.0, -1.0, 1.0] + [2.0] * 5
    assert _stepped(rs, [0.0] + [2.0] * 8) == [-1.0] * 8  # staying at a pays nothing
    # never a: -1 while the window is open, then a failed part's min(r_a, r_b) - 1 on top
    assert _stepped(rs, [0.0] * 9) == [-1.0] * 4 + [-3.0] * 4


def test_reach_and_stay_pulls_towards_the_goal_while_no_obligation_is_live():
    """``F[0,2] G a`` away from a: every G instance started is false at once (its sub-net idle), so
    G pays nothing; while the window is open the F part pays what a new instance needs now, a
    (-1 a step outside a, as F a would), and once the window closed without it (the part failed)
    a's reward less one: -2 outside a, 0 in it, never more than trying paid. By hand, dt = 0.5: the
    window is open a step ago at t = 0, 0.5, 1, 1.5; the part fails at t = 2."""
    head = "plant pendulum(dt = 0.5)\nhorizon 3\nprop a = q > 1\n"
    rs = compile_spec(parse_spec(head + "formula F[0,2] G a\n"))
    assert _stepped(rs, [0.0] * 7) == [-1.0, -1.0, -1.0, -1.0, -2.0, -2.0]  # never: -1 in the window, -2 after
    assert _stepped(rs, [0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2.0]) == [-1.0, -1.0, 1.0, 2.0, 2.0, 2.0]  # reached at 1.5
    assert _stepped(rs, [0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 2.0]) == [-1.0, -1.0, -1.0, -1.0, 0.0, 0.0]  # too late: 1 - 1
    # in and out: +1 on entering (F's pull), -2 on leaving (G's (1 + ~a)(a - !a)), a's less one once failed
    assert _stepped(rs, [0.0, 2.0, 0.0, 2.0, 0.0, 2.0, 0.0]) == [1.0, -2.0, 1.0, -2.0, 0.0, -2.0]
    # the graded reward pulls by the distance: nearer is better at every step of the window
    shaped = compile_spec(parse_spec(head + "option reward = shaped\nformula F[0,2] G a\n"))
    far, near = _stepped(shaped, [-1.0] * 7), _stepped(shaped, [0.5] * 7)
    assert all(n > f for n, f in zip(near, far, strict=True))
    assert far[4:] == [far[0] - 1.0] * 2 and near[4:] == [near[0] - 1.0] * 2  # failed: the same pull, less one


def test_recurrences_of_a_conjunction_form_one_cycle_in_order():
    """G F a & G F b & G F c (problem 4 with three regions): one token cycles a -> b -> c -> a,
    moving on when the place's own proposition holds; each term pays while its place was marked."""
    head = "plant pendulum(dt = 0.5)\nhorizon 3\nprop a = q > 1\nprop b = q < -1\nprop c = abs(q) < 0.5\n"
    rs = compile_spec(parse_spec(head + "formula G F a & G F b & G F c\n"))
    cycle = {t.inputs[0]: (t.outputs[0], str(t.guard)) for t in rs.net.transitions if t.inputs[0].startswith("p_tau")}
    assert cycle == {"p_tau_a": ("p_tau_b", "a"), "p_tau_b": ("p_tau_c", "b"), "p_tau_c": ("p_tau_a", "c")}
    # by hand, from c with the token at a: visiting a, b, c, a in order moves it round (each term
    # pays 1 on its visit, the min over the closed others is 0); then c instead of b costs
    # (1 + 0) * (0 - 1) = -1 and the token waits at b for b
    assert _stepped(rs, [0.0, 2.0, -2.0, 0.0, 2.0, 0.0, -2.0]) == [0.0, 0.0, 0.0, 0.0, -1.0, 0.0]
    assert _stepped(rs, [0.0, -2.0, 2.0, 0.0, 2.0, -2.0, 0.0]) == [-1.0, 0.0, -1.0, -1.0, 0.0, 0.0]
