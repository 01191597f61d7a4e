"""Violation-aware reward nets (option violations)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mitlc.errors import CompileError
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.spec.parse import load_spec, parse_spec

ROOT = Path(__file__).resolve().parent.parent

# problem 2 with unit weights: the reward (4-15)
P2_UNIT = """\
plant pendulum(u_max = 10)
init q in [2.4, pi], qdot = 0
horizon 3
prop kappa = abs(q) < 0.3
prop psi   = 0.3 < q < pi/2 + 0.5
formula F G kappa & G !psi
"""


def marking(net, *names: str) -> np.ndarray:
    return np.array([[1 if p in names else 0 for p in net.place_names]])


def test_off_is_the_thesis_net() -> None:
    spec = load_spec(ROOT / "specs" / "pendulum" / "p2_avoid.mitl")
    assert compile_spec(spec).net.place_names == compile_spec(spec, CompileOptions(violations="off")).net.place_names
    assert compile_spec(spec).penalty == 0.0


def test_permanent_places_guards_and_penalty() -> None:
    rs = compile_spec(parse_spec(P2_UNIT), CompileOptions(violations="permanent"))
    net = rs.net
    watch = {t.outputs: str(t.guard) for t in net.transitions if net.subnets[t.subnet].role == "violation"}
    assert watch == {
        ("p_violated_FG_kappa",): "!kappa & tau >= 2.985",
        ("p_violated_G_not_psi",): "psi",
    }
    assert {p.kind for p in net.places if "violated" in p.name or "p_ok" in p.name} == {"violation"}
    # r in [-2, 2] on any step: after a violation every step costs c = 2 - (-2) + 1
    assert rs.penalty == 5.0


def test_permanent_reward_by_hand() -> None:
    rs = compile_spec(parse_spec(P2_UNIT), CompileOptions(violations="permanent"))
    net = rs.net
    ok = ("p_ok_FG_kappa", "p_ok_G_not_psi")
    # before any violation: the thesis's reward, min((1+1)(1-0), (1+1)(1-0)) = 2 for staying in kappa
    assert rs.reward.evaluate(marking(net, "p_kappa", *ok), marking(net, "p_kappa", *ok)).tolist() == [2.0]
    # entering psi from "none" violates G !psi: min((1+0)(0-1), (1+1)(0-1)) - 5 = -7
    prev = marking(net, "p_none_kappa_psi", *ok)
    now = marking(net, "p_psi", "p_ok_FG_kappa", "p_violated_G_not_psi")
    assert rs.reward.evaluate(prev, now).tolist() == [-7.0]
    # and every later step costs 5 too: reaching kappa pays 1 - 5, less than any violation-free step
    now2 = marking(net, "p_kappa", "p_ok_FG_kappa", "p_violated_G_not_psi")
    assert rs.reward.evaluate(now, now2).tolist() == [-4.0]


def test_counted_counts_separate_violations() -> None:
    rs = compile_spec(parse_spec(P2_UNIT), CompileOptions(violations="counted"))
    net = rs.net
    (enter,) = [t for t in net.transitions if t.outputs == ("p_bad_G_not_psi", "p_count_G_not_psi")]
    (leave,) = [t for t in net.transitions if t.inputs == ("p_bad_G_not_psi",)]
    assert str(enter.guard) == "psi" and str(leave.guard) == "!psi"
    T = np.eye(len(net.transitions), dtype=np.int64)
    i_enter, i_leave = net.transition_names.index(enter.name), net.transition_names.index(leave.name)
    m = net.M0.copy()
    for _ in range(3):
        m = net.fire(m, T[i_enter])
        m = net.fire(m, T[i_leave])
    assert m[net.place_index("p_count_G_not_psi")] == 3
    assert m[net.place_index("p_ok_G_not_psi")] == 1


def test_deadlines_of_eventually_and_until() -> None:
    spec = parse_spec(
        "plant pendulum\nhorizon 3\nprop a = q < 0\nprop b = q > 1\nformula F[0,2] a & F b & (a U[0,1] b)\n"
    )
    rs = compile_spec(spec, CompileOptions(violations="permanent"))
    guards = {(t.inputs, t.outputs): str(t.guard) for t in rs.net.transitions}
    assert guards[(("p_tau_a",), ("p_late_a",))] == "tau > 2"
    assert guards[(("p_tau_b",), ("p_late_b",))] == "tau >= 2.985"
    assert guards[(("p_until_U1",), ("p_after_U1",))] == "b & tau <= 1"  # a late b fails
    assert guards[(("p_until_U1",), ("p_failed_U1",))] == "(!a & !b) | tau > 1"


def test_timed_until_watches_its_phases() -> None:
    spec = load_spec(ROOT / "specs" / "pendulum" / "p5_timed_visit.mitl")
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations="permanent"))
    watch = sorted(str(t.guard) for t in rs.net.transitions if rs.net.subnets[t.subnet].role == "violation")
    assert watch == ["!kappa & 1 < tau <= 2", "kappa & tau <= 1", "kappa & tau > 2"]


def test_disjunctions_are_not_watched() -> None:
    spec = parse_spec("plant pendulum\nhorizon 3\nprop a = q < 0\nprop b = q > 1\nformula G a | G b\n")
    rs = compile_spec(spec, CompileOptions(violations="permanent"))
    assert not [s for s in rs.net.subnets if s.role == "violation"] and rs.penalty == 0.0


def test_violations_need_a_horizon() -> None:
    with pytest.raises(CompileError, match="needs the trial length"):
        compile_spec(parse_spec("prop a = x < 0\nformula G a\n"), CompileOptions(violations="permanent"))


def test_spec_option() -> None:
    rs = compile_spec(parse_spec("option violations = counted\n" + P2_UNIT))
    assert rs.options.violations == "counted"


# ----------------------------------------------------------------- the ordering guarantee
from mitlc.monitor.offline import monitor  # noqa: E402
from mitlc.runtime import NetRuntime  # noqa: E402
from mitlc.spec.parse import parse_formula  # noqa: E402

DT, STEPS = 0.03, 100


def _rewards_and_first_violation(rs, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-step rewards (R, N) and the first step whose marking records a violation (N if none)."""
    rt = NetRuntime(rs)
    watched = [i for i, p in enumerate(rs.net.places) if p.kind == "violation" and not p.name.startswith("p_ok_")]
    m = rt.reset(x[:, 0])
    rewards = np.zeros((len(x), STEPS))
    first = np.full(len(x), STEPS)
    for k in range(STEPS):
        m_next = rt.step(m, x[:, k + 1], (k + 1) * DT)
        rewards[:, k] = rt.reward(m, m_next, x[:, k + 1])  # the new states: read by a graded reward
        hit = (m_next[:, watched].sum(axis=1) > 0) & (first == STEPS)
        first[hit] = k
        m = m_next
    return rewards, first


def _returns(rs, x: np.ndarray) -> np.ndarray:
    return _rewards_and_first_violation(rs, x)[0].sum(axis=1)


def _traces(rng: np.random.Generator, q0: tuple[float, float], designed: list[np.ndarray], n: int = 150) -> np.ndarray:
    """Random smooth angle paths from the initial set, the designed ones, and noisy copies of them."""
    t = np.arange(STEPS + 1) * DT
    paths = []
    for _ in range(n):
        k = int(rng.integers(2, 7))
        knots = np.linspace(0, t[-1], k)
        values = rng.uniform(q0[0], q0[1]) + np.concatenate([[0.0], np.cumsum(rng.normal(0, 2.0, k - 1))])
        paths.append(np.interp(t, knots, values))
    for d in designed:
        paths.append(d)
        for _ in range(10):
            paths.append(d + rng.normal(0, 0.15, d.shape) * (t > 0))
    q = np.array(paths)
    qdot = np.gradient(q, DT, axis=1)
    q = (q + np.pi) % (2 * np.pi) - np.pi
    return np.stack([q, qdot], axis=2)


def _swing_clockwise() -> np.ndarray:
    t = np.arange(STEPS + 1) * DT
    return np.interp(t, [0, 2.0, 3.0], [2.77, 2 * np.pi, 2 * np.pi])


def _timed_visit() -> np.ndarray:
    t = np.arange(STEPS + 1) * DT
    return np.where((t > 1) & (t <= 2), 3.0, 0.0)


ORDERING = [
    # spec, monitor formula (None: the spec's), initial angles, designed satisfying paths
    ("p1_swing_up", None, (np.pi - 0.1, np.pi), [_swing_clockwise()]),
    ("p2_avoid", None, (2.4, np.pi), [_swing_clockwise()]),
    ("p3_avoid_speed_limit", None, (2.4, np.pi), [_swing_clockwise()]),
    # problem 4: only its safety part is watched (G F is never violated on a finite trial)
    ("p4_alternate", "G !psi", (-0.3, 0.3), [np.zeros(STEPS + 1)]),
    # problem 5 under the net's (absolute-clock) reading
    ("p5_timed_visit", "G[0,1] !kappa & G(1,2] kappa & G(2,3] !kappa", (-1.5, 1.5), [_timed_visit()]),
]


@pytest.mark.parametrize("reward", ["net", "shaped", "graded"])
@pytest.mark.parametrize("name,formula,q0,designed", ORDERING, ids=[o[0] for o in ORDERING])
def test_no_violating_continuation_out_earns_a_satisfying_one(name, formula, q0, designed, reward) -> None:
    """The guarantee of violations = permanent, with flat and with graded propositions."""
    spec = load_spec(ROOT / "specs" / "pendulum" / f"{name}.mitl")
    rng = np.random.default_rng(7)
    x = _traces(rng, q0, designed)
    verdict = monitor(spec, x, DT, parse_formula(formula) if formula else None).satisfied
    assert verdict.any() and (~verdict).any(), "the sample must hold both kinds of trial"
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations="permanent", reward=reward))
    assert (rs.grader is not None) == (reward != "net")
    rewards, first = _rewards_and_first_violation(rs, x)
    # the net records a violation exactly when the monitor finds one
    np.testing.assert_array_equal(first < STEPS, ~verdict)
    # every step from the first violation on earns less than any step before a violation
    before = np.concatenate([rewards[i, : first[i]] for i in range(len(x))])
    for i in np.flatnonzero(~verdict):
        assert rewards[i, first[i] :].max() < before.min()
        # so its rest earns less than the same stretch of any satisfying trial
        assert rewards[i, first[i] :].sum() < rewards[verdict][:, first[i] :].sum(axis=1).min()


def test_cutting_through_psi_pays_only_without_the_option() -> None:
    """Figure 4-6b: with equal weights (4-15) the short way through psi earns more."""
    spec = parse_spec(P2_UNIT)
    t = np.arange(STEPS + 1) * DT
    short = np.interp(t, [0, 0.5, 3.0], [2.77, 0.0, 0.0])  # straight through psi
    long = _swing_clockwise()
    q = np.array([short, long])
    x = np.stack([(q + np.pi) % (2 * np.pi) - np.pi, np.gradient(q, DT, axis=1)], axis=2)
    assert monitor(spec, x, DT).satisfied.tolist() == [False, True]
    plain = _returns(compile_spec(spec), x)
    assert plain[0] > plain[1]
    aware = _returns(compile_spec(spec, CompileOptions(violations="permanent")), x)
    assert aware[0] < aware[1]


def test_runtime_counts_violations_on_both_paths() -> None:
    rs = compile_spec(parse_spec(P2_UNIT), CompileOptions(violations="counted"))
    rt = NetRuntime(rs)
    assert rt.tables is not None
    count = rs.net.place_index("p_count_G_not_psi")
    qs = [2.77, 1.0, 2.5, 1.0, 2.5, 0.1]  # none, psi, none, psi, none, kappa
    x = np.array([[[q, 0.0] for q in qs]])
    m = rt.reset(x[:, 0])
    rewards = []
    for k in range(len(qs) - 1):
        m_next = rt.step(m, x[:, k + 1], (k + 1) * DT)
        np.testing.assert_array_equal(m_next, rt.step_direct(m, x[:, k + 1], (k + 1) * DT))
        rewards.append(float(rt.reward(m, m_next)[0]))
        assert rt.reward_code(rt.encode(m), rt.encode(m_next))[0] == rewards[-1]
        m = m_next
    assert m[0, count] == 2
    # each entry into psi: base min(1*(0-1), 2*(0-1)) = -2 and the penalty c = 4 + 1
    assert rs.penalty == 5.0
    assert rewards == [-7.0, -1.0, -7.0, -1.0, 1.0]


def test_stepped_rewards_are_the_off_reward_less_c_per_charge() -> None:
    """Stepped by the runtime over a trace that enters psi twice: counted charges each entry
    once, permanent charges every step from the first; both pay exactly off - c * charge."""
    spec = load_spec(ROOT / "specs" / "pendulum" / "p2_avoid.mitl")
    qs = [3.0, 1.0, 1.1, 2.5, 1.0, 2.6, 0.1, 0.0]  # psi is 0.3 < q < pi/2 + 0.5: entered at samples 1 and 4
    x = np.array([[[q, 0.0] for q in qs]])
    stepped = {}
    for v in ("off", "permanent", "counted"):
        rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=v))
        rt = NetRuntime(rs, ("q", "qdot"), dt=0.03, steps=len(qs) - 1)
        M = rt.reset(x[:, 0])
        rewards, charges = [], []
        for k in range(1, len(qs)):
            M1 = rt.step(M, x[:, k], k * 0.03)
            rewards.append(float(rt.reward(M, M1)[0]))
            charges.append(float(rs.charge.evaluate(M, M1)[0]) if rs.charge is not None else 0.0)
            M = M1
        stepped[v] = (rs.penalty, np.array(rewards), charges)
    off = stepped["off"][1]
    c, perm, v_perm = stepped["permanent"]
    assert c == 5.0 and v_perm == [1.0] * 7  # violated from the first entry on, for good
    np.testing.assert_array_equal(perm, off - c * np.array(v_perm))
    c, counted, n_new = stepped["counted"]
    assert c == 5.0 and n_new == [1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]  # each entry once, the second too
    np.testing.assert_array_equal(counted, off - c * np.array(n_new))
