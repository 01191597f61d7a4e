"""Hybrid automata of appendix B: structure, transitions on hand-made trajectories,
mode-wise rewards by hand (Tables 3-1 / B-2, 3-3 / B-4), exports."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mitlc.errors import SpecError
from mitlc.hybrid import (
    FALSE,
    TRUE,
    AllOf,
    AnyOf,
    Cmp,
    Lin,
    all_of,
    any_of,
    compile_requirements,
    evaluate,
    guard_from_dict,
    guard_to_dict,
    negate,
)
from mitlc.spec.parse import load_spec, parse_spec

HEAD = "plant mass-damper\nsetpoint 0\n"


def automaton(body: str, init: str = "init q in [-1, -0.5], qdot = 0\n"):
    return compile_requirements(parse_spec(HEAD + init + body))


def states(*rows):
    """A trajectory from (q, qdot) pairs: shape (1, N+1, 2)."""
    return np.array(rows, dtype=float)[None]


# ------------------------------------------------------------------ structure


def test_overshoot_automaton_is_table_b1(spec_dir):
    h = compile_requirements(load_spec(spec_dir / "mass_damper" / "overshoot.mitl"))
    assert h.names == ("I", "E_Mp", "S", "P")
    assert h.cases == ("rising", "falling")
    g = {(e.src, e.dst): str(e.guard) for e in h.edges}
    assert g == {
        ("I", "E_Mp"): "(q0 < 0 & q > 0.05*q0) | (q0 >= 0 & q < 0.05*q0)",
        ("E_Mp", "P"): "(q0 < 0 & q > 0) | (q0 >= 0 & q < 0)",
        ("E_Mp", "S"): "(q0 < 0 & qdot < 0) | (q0 >= 0 & qdot > 0)",
        ("S", "P"): "(q0 < 0 & (q < 0.1*q0 | q > 0)) | (q0 >= 0 & (q > 0.1*q0 | q < 0))",
        ("P", "S"): "(q0 < 0 & q > 0.1*q0 & q < 0) | (q0 >= 0 & q < 0.1*q0 & q > 0)",
    }
    assert str(h.mode("S").invariant) == "(q0 < 0 & q >= 0.1*q0 & q <= 0) | (q0 >= 0 & q <= 0.1*q0 & q >= 0)"
    assert str(h.mode("I").invariant) == "(q0 < 0 & q <= 0.05*q0) | (q0 >= 0 & q >= 0.05*q0)"
    assert not h.mode("P").permanent and not h.mode("S").permanent
    assert [m.name for m in h.modes if m.clock] == []
    assert h.time_vars() == ()


def test_rise_time_automaton_is_table_b3(spec_dir):
    h = compile_requirements(load_spec(spec_dir / "mass_damper" / "rise_time.mitl"))
    assert h.names == ("I", "E_tr", "S", "P")
    assert h.cases == ("rising",)
    g = {(e.src, e.dst): str(e.guard) for e in h.edges}
    assert g == {
        ("I", "E_tr"): "q > 0.9*q0",
        ("E_tr", "P"): "qdot < 0 | (q > 0.1*q0 & t < 0.6) | t > 0.8",
        ("E_tr", "S"): "q > 0.1*q0 & t >= 0.6 & t <= 0.8",
    }
    # (B-2): S and P are X-bar: the automaton lives there for the rest of the trial
    assert h.mode("S").invariant == TRUE and h.mode("P").invariant == TRUE
    assert h.mode("S").permanent and h.mode("P").permanent
    assert [m.name for m in h.modes if m.clock] == ["E_tr"]
    assert h.time_vars() == ("t",) and h.time_range("t") == (0.0, 0.8)


def test_combined_automaton_is_table_b5(spec_dir):
    h = compile_requirements(load_spec(spec_dir / "mass_damper" / "overshoot_rise_time.mitl"))
    assert h.names == ("I", "E_tr", "E_Mp", "S", "P")
    g = {(e.src, e.dst): str(e.guard) for e in h.edges}
    assert g == {
        ("I", "E_tr"): "q > 0.9*q0",
        ("E_tr", "P"): "qdot < 0 | (q > 0.1*q0 & t < 0.6) | t > 0.8",
        ("E_tr", "E_Mp"): "q > 0.1*q0 & t >= 0.6 & t <= 0.8",
        ("E_Mp", "P"): "q > 0",
        ("E_Mp", "S"): "qdot < 0",
        ("S", "P"): "q < 0.1*q0 | q > 0",
        ("P", "S"): "q > 0.1*q0 & q < 0",
    }
    assert str(h.mode("E_Mp").invariant) == "q > 0.1*q0 & q <= 0"
    assert not h.mode("P").permanent


def test_thresholds_follow_the_setpoint_and_allowed_overshoot():
    h = compile_requirements(
        parse_spec("plant mass-damper\nsetpoint 0.5\ninit q in [-1, -0.5], qdot = 0\nrequire overshoot <= 0.2\n")
    )
    # 95% of the step: s + 0.05 (q0 - s); the peak (3-1): s + M_p (s - q0)
    assert str(h.edge("I", "E_Mp").guard) == "q > 0.05*q0 + 0.475"
    assert str(h.edge("E_Mp", "P").guard) == "q > -0.2*q0 + 0.6"
    env = {"q": np.array([0.79, 0.81]), "q0": np.array([-1.0, -1.0])}
    np.testing.assert_array_equal(evaluate(h.edge("E_Mp", "P").guard, env), [False, True])


def test_falling_only_start_writes_only_the_undershoot_case():
    h = automaton("require overshoot <= 0\n", init="init q in [0.5, 1], qdot = 0\n")
    assert h.cases == ("falling",)
    assert str(h.edge("I", "E_Mp").guard) == "q < 0.05*q0"
    assert str(h.edge("E_Mp", "P").guard) == "q < 0"


def test_settling_and_steady_state_modes():
    h = automaton("require settling_time <= 2 band 0.05\nrequire steady_state_error <= 0.02\n")
    assert h.names == ("I", "E_ts", "E_ess", "S", "P")
    assert str(h.edge("I", "E_ts").guard) == "q >= 0.05*q0 | tau >= 2"
    assert str(h.edge("E_ts", "P").guard) == "tau >= 2 & (q < 0.05*q0 | q > -0.05*q0)"
    assert str(h.edge("E_ts", "E_ess").guard) == "tau >= 2 & q >= 0.05*q0 & q <= -0.05*q0"
    # once settled, leaving the band is a violation in every later mode
    assert str(h.edge("E_ess", "P").guard) == "q < 0.05*q0 | q > -0.05*q0"
    assert str(h.edge("E_ess", "S").guard) == "q >= -0.02 & q <= 0.02"
    assert h.time_vars() == ("tau",)


@pytest.mark.parametrize(
    "body, message",
    [
        ("require overshoot in [0.1, 0.2]\n", "upper bound only"),
        ("require rise_time in [0.6, 6]\n", "cannot be judged within the 5 s trial"),
    ],
)
def test_bad_requirements_are_located_spec_errors(body, message):
    with pytest.raises(SpecError, match=message) as exc:
        automaton(body)
    assert exc.value.line == 4


def test_spec_without_requirements_or_initial_positions():
    with pytest.raises(SpecError, match="no 'require'"):
        compile_requirements(parse_spec("prop k = abs(q) < 1\nformula F k"))
    with pytest.raises(SpecError, match="init q in"):
        compile_requirements(parse_spec("plant mass-damper\nrequire overshoot <= 0\n"))


# ------------------------------------------------------------------ guards as data


def test_guard_algebra_and_round_trip():
    a = Cmp("q", ">", Lin((("q0", 0.05),)))
    b = Cmp("qdot", "<", Lin())
    assert all_of(a, TRUE) == a and all_of(a, FALSE) == FALSE
    assert any_of(a, FALSE) == a and any_of(a, TRUE) == TRUE
    assert negate(all_of(a, b)) == AnyOf((Cmp("q", "<=", a.rhs), Cmp("qdot", ">=", b.rhs)))
    g = any_of(all_of(Cmp("q0", "<", Lin()), a), all_of(Cmp("q0", ">=", Lin()), b))
    assert guard_from_dict(json.loads(json.dumps(guard_to_dict(g)))) == g
    assert isinstance(g, AnyOf) and isinstance(g.args[0], AllOf)
    with pytest.raises(SpecError, match="unknown guard variable"):
        Cmp("x", "<", Lin())


# ------------------------------------------------------------------ runs on hand-made trajectories

OVERSHOOT = "require overshoot <= 0\n"
WIDE = "init q in [-1, 1], qdot = 0\n"


def test_overshoot_rising_sequence_and_rewards_by_hand():
    h = automaton(OVERSHOOT, WIDE)
    traj = states(
        (-1.0, 0.0),  # start: I
        (-0.5, 1.0),  # q <= 0.05 q0: still I, moving towards 0: reward 0
        (-0.04, 1.0),  # q > -0.05: E_Mp, reward -3 |0 - q| = -0.12
        (-0.02, -0.1),  # velocity turned: S, just entered: -0.06, no bonus
        (-0.03, 0.0),  # in [0.1 q0, 0] = [-0.1, 0]: stays S: -0.09 + 3
        (0.01, 0.5),  # past the set-point: P, -9
        (-0.05, -0.5),  # back inside (-0.1, 0): S, -0.15 (no bonus: came from P)
    )
    tr = h.trace(traj, dt=0.03)
    assert tr.mode_names() == ["I", "I", "E_Mp", "S", "S", "P", "S"]
    np.testing.assert_allclose(tr.rewards[0], [0.0, -0.12, -0.06, 2.91, -9.0, -0.15], atol=1e-12)
    # every sample satisfies the invariant of its mode
    for k, name in enumerate(tr.mode_names()):
        env = {"q": traj[0, k : k + 1, 0], "qdot": traj[0, k : k + 1, 1], "q0": np.array([-1.0])}
        assert evaluate(h.mode(name).invariant, env).all(), (k, name)


def test_overshoot_falling_case_is_the_mirror():
    h = automaton(OVERSHOOT, WIDE)
    tr = h.trace(states((0.8, 0.0), (0.5, -1.0), (0.03, -1.0), (0.01, 0.2), (-0.01, 0.1), (0.05, 0.0)), dt=0.03)
    assert tr.mode_names() == ["I", "I", "E_Mp", "S", "P", "S"]
    np.testing.assert_allclose(tr.rewards[0], [0.0, -0.09, -0.03, -9.0, -0.15], atol=1e-12)


def test_idle_penalises_moving_away_and_standing_still():
    h = automaton(OVERSHOOT, WIDE)
    tr = h.trace(states((-1.0, 0.0), (-1.1, -1.0), (-1.1, 0.0), (-0.9, 1.0)), dt=0.03)
    assert tr.mode_names() == ["I"] * 4
    np.testing.assert_array_equal(tr.rewards[0], [-3.0, -3.0, 0.0])


def test_overshoot_inside_e_goes_to_p_and_jumps_chain_in_one_sample():
    h = automaton(OVERSHOOT, WIDE)
    tr = h.trace(
        np.stack(
            [
                states((-1.0, 0.0), (-0.04, 2.0), (0.02, 1.0), (0.01, -0.5))[0],
                states((-1.0, 0.0), (0.01, 2.0), (0.0, 0.0), (0.0, 0.0))[0],  # I -> E_Mp -> P at once
            ]
        ),
        dt=0.03,
    )
    assert tr.mode_names(0) == ["I", "E_Mp", "P", "P"]
    assert tr.mode_names(1) == ["I", "P", "P", "P"]  # q = 0 is on neither side of S's open interior
    np.testing.assert_array_equal(tr.rewards[1], [-9.0, -9.0, -9.0])


def rise_trajectory(qs):
    """q0 = -1, then the given positions with a positive velocity (dt = 0.1)."""
    return states((-1.0, 0.0), *[(q, 1.0) for q in qs])


def test_rise_time_in_window_reaches_s_and_clock_runs_only_in_e():
    h = automaton("require rise_time in [0.6, 0.8]\n")
    qs = [-0.95, -0.85, -0.75, -0.6, -0.5, -0.4, -0.3, -0.2, -0.05, 0.5]
    tr = h.trace(rise_trajectory(qs), dt=0.1)
    assert tr.sequence() == ["I", "E_tr", "S"]
    assert tr.mode_names()[:4] == ["I", "I", "E_tr", "E_tr"]
    # t is held in I, counts in E (appendix B-2), and is held again in S
    np.testing.assert_allclose(tr.t[0], [0, 0, 0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.7], atol=1e-12)
    assert tr.mode_names()[9] == "S"  # 90% reached at t = 0.7 s
    # rewards: I 0 (rising), E: -3 |0.1 q0 - q| = -3 |q + 0.1|, S: -3 |q| (+3 once it stays)
    expected = [0.0, -2.25, -1.95, -1.5, -1.2, -0.9, -0.6, -0.3, -0.15, -1.5 + 3.0]
    np.testing.assert_allclose(tr.rewards[0], expected, atol=1e-12)
    assert tr.mode_names()[-1] == "S"  # S is permanent: even q = 0.5 stays in S


@pytest.mark.parametrize(
    "qs, why",
    [
        ([-0.85, -0.6, -0.3, -0.05], "too fast: 90% at t = 0.3 s"),
        ([-0.85, -0.8, -0.75, -0.7, -0.65, -0.6, -0.55, -0.5, -0.45, -0.4], "too slow: t > 0.8 s below 90%"),
        ([-0.85, -0.7, -0.75], "waiting: qdot < 0 in E"),
    ],
)
def test_rise_time_violations_go_to_a_permanent_p(qs, why):
    h = automaton("require rise_time in [0.6, 0.8]\n")
    traj = rise_trajectory(qs + [-0.05, -0.01])
    if "waiting" in why:
        traj[0, 3, 1] = -0.5
    tr = h.trace(traj, dt=0.1)
    assert tr.sequence() == ["I", "E_tr", "P"], why
    first_p = tr.mode_names().index("P")
    np.testing.assert_array_equal(tr.rewards[0, first_p - 1 :], -9.0)


def test_combined_chain_rise_then_overshoot():
    h = automaton("require rise_time in [0.6, 0.8]\nrequire overshoot <= 0\n")
    qs = [-0.95, -0.85, -0.75, -0.6, -0.5, -0.4, -0.3, -0.2, -0.05]
    traj = states((-1.0, 0.0), *[(q, 1.0) for q in qs], (-0.02, 0.2), (-0.03, -0.1), (-0.04, 0.0))
    tr = h.trace(traj, dt=0.1)
    assert tr.sequence() == ["I", "E_tr", "E_Mp", "S"]
    # overshoot after a good rise: E_Mp -> P, then back into (0.1 q0, 0): S
    traj2 = states((-1.0, 0.0), *[(q, 1.0) for q in qs], (0.01, 0.5), (-0.05, -0.2))
    assert h.trace(traj2, dt=0.1).sequence() == ["I", "E_tr", "E_Mp", "P", "S"]


def test_settling_time_judged_at_t_s():
    h = automaton("require settling_time <= 1 band 0.1\n")
    ok = states((-1.0, 0.0), (-0.5, 1.0), (-0.05, 1.0), (0.05, 0.1), (0.02, 0.0), (0.2, 1.0))
    tr = h.trace(ok, dt=0.25)
    # in the band at tau = 1 s: S (jumps chain E_ts -> S); leaving the band later: P
    assert tr.mode_names() == ["I", "I", "E_ts", "E_ts", "S", "P"]
    late = states((-1.0, 0.0), (-0.8, 1.0), (-0.6, 1.0), (-0.4, 1.0), (-0.2, 1.0))
    assert h.trace(late, dt=0.25).mode_names() == ["I", "I", "I", "I", "P"]  # I -> E_ts -> P at tau = 1


def test_steady_state_error_band_joins_s():
    h = automaton("require steady_state_error <= 0.02\n")
    tr = h.trace(states((-1.0, 0.0), (-0.04, 1.0), (-0.01, 0.1), (0.03, 0.1), (0.0, 0.0)), dt=0.03)
    assert tr.mode_names() == ["I", "E_ess", "S", "P", "S"]
    np.testing.assert_allclose(tr.rewards[0], [-0.12, -0.03, -9.0, 0.0], atol=1e-12)


def test_runs_are_vectorised():
    h = automaton(OVERSHOOT, WIDE)
    a = states((-1.0, 0.0), (-0.04, 1.0), (0.01, 1.0))[0]
    b = states((0.8, 0.0), (0.5, -1.0), (0.03, -1.0))[0]
    both = h.trace(np.stack([a, b]), dt=0.03)
    for i, one in enumerate((a, b)):
        single = h.trace(one, dt=0.03)
        np.testing.assert_array_equal(both.modes[i], single.modes[0])
        np.testing.assert_array_equal(both.rewards[i], single.rewards[0])


# ------------------------------------------------------------------ exports


def test_text_json_and_digraph(spec_dir):
    h = compile_requirements(load_spec(spec_dir / "mass_damper" / "rise_time.mitl"))
    text = str(h)
    assert "memory z = (q0, t); t runs in: E_tr" in text
    assert "E_tr -> P  [violation]  qdot < 0 | (q > 0.1*q0 & t < 0.6) | t > 0.8" in text
    d = json.loads(h.to_json())
    assert [m["name"] for m in d["modes"]] == ["I", "E_tr", "S", "P"]
    assert d["memory"] == {"vars": ["q0", "t"], "clock_runs_in": ["E_tr"]}
    for e in d["edges"]:
        assert str(guard_from_dict(e["guard_tree"])) == e["guard"]
    assert d["modes"][1]["reward"] == "-3*|q - 0.1*q0|"
    src = h.to_digraph().source
    assert "rounded,filled" in src and "peripheries=2" in src  # permanent P highlighted
    assert "q > 0.9*q0" in src
    src_b1 = compile_requirements(load_spec(spec_dir / "mass_damper" / "overshoot.mitl")).to_digraph().source
    assert "peripheries=2" not in src_b1 and "dashed" in src_b1  # P -> S recovery edge
