"""The runtime against hand-computed markings and rewards; the plants against their equations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.plants.base import PLANTS, wrap_angle
from mitlc.runtime import NetRuntime
from mitlc.runtime.tables import Tables
from mitlc.spec.parse import parse_spec

P1 = """
plant pendulum(u_max = 3)
init q = pi, qdot = 0
prop kappa = abs(q) < 0.3
formula F G kappa
"""

P2 = """
plant pendulum(u_max = 10)
init q in [2.4, pi], qdot = 0
prop kappa = abs(q) < 0.3
prop psi   = 0.3 < q < pi/2 + 0.5
formula F G kappa & 10 * G !psi
"""

P3 = """
plant pendulum(u_max = 10)
init q in [2.4, pi], qdot = 0
prop kappa   = abs(q) < 0.3
prop psi     = 0.3 < q < pi/2 + 0.5
prop upsilon = abs(qdot) < 10
formula F G kappa & 10 * G !psi & 10 * G upsilon
"""

P4 = """
plant pendulum(u_max = 10)
init q in [-0.3, 0.3], qdot = 0
prop kappa   = -pi/2 - 0.5 < q < -pi/2 + 0.3
prop upsilon = pi/2 - 0.3 < q < pi/2 + 0.5
prop psi     = -pi < q < -pi/2 - 0.5 or pi/2 + 0.5 < q < pi
formula 5 * G F kappa & 5 * G F upsilon & 25 * G !psi
"""

P5 = """
plant pendulum(u_max = 10)
init q in [-pi/2, pi/2], qdot = 0
prop kappa = -pi < q < -pi + 0.5 or pi - 0.5 < q < pi
option clock = trial
formula 2 * !kappa U(1,2] (3 * kappa U(2,inf) G !kappa)
"""

SPECS = {"p1": P1, "p2": P2, "p3": P3, "p4": P4, "p5": P5}


def runtime(text: str, conjunction: str = "literal") -> NetRuntime:
    spec = parse_spec(text)
    return NetRuntime(compile_spec(spec, CompileOptions.from_spec(spec, conjunction=conjunction)))


def states(qs, qdots=None) -> np.ndarray:
    qdots = [0.0] * len(qs) if qdots is None else qdots
    return np.array([[q, qd] for q, qd in zip(qs, qdots, strict=True)], dtype=float)


def trace(rt: NetRuntime, x0: float, steps: list[tuple[float, float]], qdot0: float = 0.0):
    """Run one trajectory given as (tau_k+1, q_k+1) pairs; return markings and rewards."""
    M = rt.reset(states([x0], [qdot0]))
    marks, rewards = [M[0].tolist()], []
    for tau, q in steps:
        M1 = rt.step(M, states([q]), tau)
        rewards.append(float(rt.reward(M, M1)[0]))
        marks.append(M1[0].tolist())
        M = M1
    return marks, rewards


# ------------------------------------------------------------------ hand-computed traces


def test_p1_trace():
    rt = runtime(P1)
    assert rt.net.place_names == ("p_kappa", "p_not_kappa")
    # r = (1 + ~p_kappa)(p_kappa - p_not_kappa)    (4-12)
    marks, rewards = trace(rt, math.pi, [(0.03, 2.0), (0.06, 0.2), (0.09, -0.1), (0.12, 0.5), (0.15, 0.5)])
    assert marks == [[0, 1], [0, 1], [1, 0], [1, 0], [0, 1], [0, 1]]
    assert rewards == [-1.0, 1.0, 2.0, -2.0, -1.0]


def test_p2_trace():
    rt = runtime(P2)
    assert rt.net.place_names == ("p_kappa", "p_psi", "p_none_kappa_psi")
    # (4-13): min((1 + ~pk)(pk - pnk), 10 (1 + ~pnpsi)(pnpsi - ppsi)), pnk = ppsi + pnone, pnpsi = pk + pnone
    marks, rewards = trace(rt, 2.77, [(0.03, 1.0), (0.06, 1.0), (0.09, 0.1), (0.12, 0.0), (0.15, -1.0)])
    assert marks == [[0, 0, 1], [0, 1, 0], [0, 1, 0], [1, 0, 0], [1, 0, 0], [0, 0, 1]]
    assert rewards == [-20.0, -10.0, 1.0, 2.0, -2.0]


def test_p3_two_region_nets_move_together():
    rt = runtime(P3)
    assert rt.net.place_names == ("p_kappa", "p_psi", "p_none_kappa_psi", "p_upsilon", "p_not_upsilon")
    M = rt.reset(states([2.77], [0.0]))
    assert M.tolist() == [[0, 0, 1, 1, 0]]
    M1 = rt.step(M, states([0.1], [12.0]), 0.03)  # kappa, too fast
    assert M1.tolist() == [[1, 0, 0, 0, 1]]
    # min(1 * (1 - 0), 10 * (1 + 1) * (1 - 0), 10 * (1 + 1) * (0 - 1))
    assert rt.reward(M, M1).tolist() == [-20.0]


@pytest.mark.parametrize(
    "conjunction, expected",
    [("literal", [0.0, -5.0, 0.0, -50.0]), ("active", [5.0, -5.0, 5.0, -50.0])],
)
def test_p4_recurrence_and_gated_min(conjunction, expected):
    rt = runtime(P4, conjunction)
    assert rt.net.place_names == (
        "p_tau_kappa",
        "p_tau_upsilon",
        "p_kappa",
        "p_upsilon",
        "p_psi",
        "p_none_kappa_upsilon_psi",
    )
    marks, rewards = trace(rt, 0.0, [(0.03, -1.5), (0.06, -1.5), (0.09, 1.5), (0.12, 3.0)])
    assert marks == [
        [1, 0, 0, 0, 0, 1],
        [0, 1, 1, 0, 0, 0],  # kappa reached: the timing token moves on to upsilon
        [0, 1, 1, 0, 0, 0],
        [1, 0, 0, 1, 0, 0],  # upsilon reached: back to kappa
        [1, 0, 0, 0, 1, 0],
    ]
    assert rewards == expected


def test_p5_timeline_moves_one_place_per_step():
    rt = runtime(P5)
    assert rt.net.place_names == ("p_tau<=1", "p_1<tau<=2", "p_tau>2", "p_kappa", "p_not_kappa")
    # (4-18): 2 p_tau<1 (pnk - pk) + 3 p_1<tau<2 (pk - pnk) + p_tau>2 (1 + ~pnk)(pnk - pk)
    steps = [(0.5, 0.0), (1.0, 3.0), (1.2, 3.0), (2.5, 3.0), (2.6, 3.0), (2.7, 0.0), (2.8, 0.0)]
    marks, rewards = trace(rt, 0.0, steps)
    assert marks == [
        [1, 0, 0, 0, 1],
        [1, 0, 0, 0, 1],
        [1, 0, 0, 1, 0],  # tau = 1 is not > 1: still in the first phase
        [0, 1, 0, 1, 0],
        [0, 0, 1, 1, 0],
        [0, 0, 1, 1, 0],
        [0, 0, 1, 0, 1],
        [0, 0, 1, 0, 1],
    ]
    assert rewards == [2.0, -2.0, 3.0, -1.0, -1.0, 1.0, 2.0]


def test_p5_jump_over_two_thresholds_takes_two_steps():
    rt = runtime(P5)
    M = rt.reset(states([0.0]))
    M1 = rt.step(M, states([0.0]), 2.5)
    assert M1.tolist() == [[0, 1, 0, 0, 1]]
    M2 = rt.step(M1, states([0.0]), 2.5)
    assert M2.tolist() == [[0, 0, 1, 0, 1]]


def test_reset_puts_state_tokens_on_the_region():
    rt = runtime(P2)
    M = rt.reset(states([0.0, 1.0, 2.77, -3.0]))
    assert M.tolist() == [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1]]
    rt5 = runtime(P5)
    assert rt5.reset(states([3.0]))[0].tolist() == [1, 0, 0, 1, 0]


def test_truth_is_per_run():
    rt = runtime(P3)
    t = rt.truth(states([0.0, 1.0, 3.0], [0.0, 11.0, -9.0]))
    assert t["kappa"].tolist() == [True, False, False]
    assert t["psi"].tolist() == [False, True, False]
    assert t["upsilon"].tolist() == [True, False, True]


def test_bad_marking_is_rejected():
    rt = runtime(P2)
    with pytest.raises(ValueError):
        rt.step(np.array([[1, 1, 0]]), states([0.0]), 0.03)


@pytest.mark.parametrize("name", sorted(SPECS))
@pytest.mark.parametrize("conjunction", ["literal", "active"])
def test_tables_agree_with_the_direct_rule(name, conjunction):
    rt = runtime(SPECS[name], conjunction)
    assert rt.tables is not None
    rng = np.random.default_rng(7)
    R = 64
    x = np.column_stack([rng.uniform(-math.pi, math.pi, R), rng.uniform(-15, 15, R)])
    M = rt.reset(x)
    for k in range(60):
        x = np.column_stack([rng.uniform(-math.pi, math.pi, R), rng.uniform(-15, 15, R)])
        tau = rng.uniform(0, 3.2, R) if k % 2 else 0.05 * (k + 1)
        fast = rt.step(M, x, tau)
        slow = rt.step_direct(M, x, tau)
        np.testing.assert_array_equal(fast, slow)
        code, code1 = rt.encode(M), rt.encode(fast)
        np.testing.assert_array_equal(rt.reward_code(code, code1), rt.reward(M, fast))
        np.testing.assert_array_equal(rt.decode(code1), fast)
        assert (fast.sum(axis=1) == rt.n_subnets).all()
        M = fast


def test_marked_places():
    rt = runtime(P5)
    M = rt.reset(states([0.0, 3.0]))
    np.testing.assert_array_equal(rt.marked_places(rt.encode(M)), [[0, 4], [0, 3]])


# ------------------------------------------------------------------ plants


PEND = PLANTS["pendulum"]
MD = PLANTS["mass-damper"]


def test_pendulum_equation_a2():
    p = PEND.params()
    x = np.array([[0.4, -2.0], [-2.5, 7.0]])
    u = np.array([1.5, -3.0])
    xdot = PEND.dynamics(x, u, p)
    J, M, g, l, b, K, R = (p[k] for k in ("J", "M", "g", "l", "b", "K", "R"))
    for i in range(2):
        q, qd = x[i]
        qdd = (M * g * l * math.sin(q) - (b + K * K / R) * qd + K / R * u[i]) / J
        assert xdot[i, 0] == pytest.approx(qd)
        assert xdot[i, 1] == pytest.approx(qdd, rel=1e-12)


def test_mass_damper_equation_a1_against_exact_solution():
    p = MD.params({"u_max": 10.0})
    x = np.array([[0.3, 1.0]])
    u = np.array([0.7])
    Mm, B, dt = p["M"], p["B"], p["dt"]
    out = MD.step(x.copy(), u, p)
    a = B / Mm
    v_inf = u[0] / B
    v = v_inf + (1.0 - v_inf) * math.exp(-a * dt)
    q = 0.3 + v_inf * dt + (1.0 - v_inf) * (1 - math.exp(-a * dt)) / a
    assert out[0, 1] == pytest.approx(v, abs=1e-10)
    assert out[0, 0] == pytest.approx(q, abs=1e-10)


def _fine_reference(x: np.ndarray, u: np.ndarray, p: dict, substeps: int = 2000) -> np.ndarray:
    fine = dict(p, dt=p["dt"] / substeps)
    y = x.copy()
    for _ in range(substeps):  # unwrapped, unclipped RK4 with a tiny step
        k1 = PEND.dynamics(y, u, fine)
        k2 = PEND.dynamics(y + 0.5 * fine["dt"] * k1, u, fine)
        k3 = PEND.dynamics(y + 0.5 * fine["dt"] * k2, u, fine)
        k4 = PEND.dynamics(y + fine["dt"] * k3, u, fine)
        y = y + fine["dt"] / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y


def test_pendulum_rk4_against_fine_step_reference():
    p = PEND.params({"u_max": 10.0})
    x = np.array([[math.pi - 0.01, 0.0], [0.2, 3.0], [-1.0, -5.0]])
    u = np.array([10.0, -4.0, 0.0])
    ref = _fine_reference(x, u, p)
    out = PEND.step(x.copy(), u, p)
    np.testing.assert_allclose(out[:, 1], ref[:, 1], atol=2e-3)
    np.testing.assert_allclose(wrap_angle(out[:, 0] - ref[:, 0]), 0.0, atol=1e-4)


def test_pendulum_falls_from_upright_and_rests_at_bottom():
    p = PEND.params()
    x = np.array([[1e-3, 0.0]])
    assert PEND.step(x.copy(), np.zeros(1), p)[0, 1] > 0  # gravity pulls away from upright
    bottom = np.array([[-math.pi, 0.0]])
    np.testing.assert_allclose(PEND.step(bottom.copy(), np.zeros(1), p), bottom, atol=1e-12)


def test_pendulum_angle_is_wrapped():
    p = PEND.params({"u_max": 10.0})
    x = np.array([[math.pi - 0.01, 5.0], [-math.pi + 0.01, -5.0]])
    out = PEND.step(x.copy(), np.zeros(2), p)
    assert (out[:, 0] >= -math.pi).all() and (out[:, 0] < math.pi).all()
    assert out[0, 0] < 0 and out[1, 0] > 0  # crossed the bottom
    np.testing.assert_allclose(wrap_angle(np.array([3 * math.pi, -3 * math.pi + 0.1])), [-math.pi, -math.pi + 0.1])


def test_pendulum_input_saturates_and_velocity_is_bounded():
    p = PEND.params({"u_max": 3.0})
    x = np.array([[0.0, 0.0]])
    np.testing.assert_array_equal(PEND.step(x.copy(), np.array([100.0]), p), PEND.step(x.copy(), np.array([3.0]), p))
    fast = np.array([[0.0, 15 * math.pi]])
    out = PEND.step(fast.copy(), np.array([3.0]), PEND.params({"u_max": 3.0}))
    assert abs(out[0, 1]) <= 15 * math.pi


def test_compiled_predicates_agree_with_the_reference():
    from mitlc.runtime.atoms import compile_predicate
    from mitlc.spec import predicates as Pr

    spec = parse_spec(
        "plant pendulum\nprop a = -pi < q < -pi + 0.5 or pi - 0.5 < q < pi\n"
        "prop b = not (abs(qdot) >= 2 * 5) and sin(q) - -q / 2 > min(0.1, cos(qdot))\nformula G a & F b"
    )
    rng = np.random.default_rng(3)
    x = np.column_stack([rng.uniform(-4, 4, 500), rng.uniform(-20, 20, 500)])
    cols = {"q": 0, "qdot": 1}
    for prop in spec.props:
        ref = Pr.evaluate(prop.pred, {"q": x[:, 0], "qdot": x[:, 1]})
        np.testing.assert_array_equal(compile_predicate(prop.pred, cols)(x), ref)


def _many_eventuallys(n: int, props: int = 1) -> str:
    parts = " & ".join(f"F[0,{0.5 + 0.04 * i:.2f}] a{i % props}" for i in range(n))
    defs = "".join(f"prop a{j} = abs(q - {0.2 * j}) < 0.3\n" for j in range(props))
    return f"plant pendulum\ninit q in [2.4, pi], qdot = 0\nhorizon 3\n{defs}formula {parts}\n"


def test_compact_tables_follow_the_direct_rule() -> None:
    """Twelve bounded eventuallys over two propositions: 2^12 x 13 x 4 product markings, too many to
    tabulate; the reachable ones are tabulated instead and step exactly as the rule does."""
    from mitlc.runtime import tables as RT

    rs = compile_spec(parse_spec(_many_eventuallys(12, props=2)))
    rt = NetRuntime(rs)
    assert rt.compact and rt.tables is not None
    assert rt.n_codes < math.prod(len(p) for p in rt.subnet_places)
    rng = np.random.default_rng(3)
    R, N = 64, 100
    q = np.cumsum(rng.normal(0, 0.3, (R, N + 1)), axis=1) + rng.uniform(-1, 1, (R, 1))
    x = np.stack([q, np.zeros_like(q)], axis=2)
    code = rt.reset_code(x[:, 0])
    M = rt.reset(x[:, 0])
    np.testing.assert_array_equal(rt.decode(code), M)
    for k in range(N):
        tau = (k + 1) * 0.03
        code1 = rt.step_code(code, x[:, k + 1], tau)
        M1 = rt.step_direct(M, x[:, k + 1], tau)
        np.testing.assert_array_equal(rt.decode(code1), M1)
        np.testing.assert_array_equal(rt.reward_code(code, code1), rs.reward.evaluate(M, M1))
        code, M = code1, M1
    assert RT.MAX_TABLE  # the limit the product exceeded


def test_sixty_bounded_eventuallys_train() -> None:
    from mitlc.learn.sacpn import Sacpn

    rs = compile_spec(parse_spec(_many_eventuallys(60)))
    agent = Sacpn(rs, runs=3, seed=0)
    assert agent.runtime.compact and agent.runtime.n_codes < 10_000
    returns = agent.train(2)
    assert returns.shape == (3, 2) and np.all(np.isfinite(returns))
    ro = agent.rollout(agent.evaluation_states())
    np.testing.assert_array_equal(ro.rewards, agent.runtime.reward_code(ro.codes[:, :-1], ro.codes[:, 1:]))


@pytest.mark.parametrize("n_props", [3, 7, 8, 9, 12])
def test_many_propositions_pack_and_step_as_their_predicates_say(n_props):
    """n region nets, one per threshold q > c_i (none provably disjoint from another): after
    every step each net marks the place of its own predicate's truth, whichever path steps it
    (markings, packed codes, the tables or the direct reading), and the rewards agree."""
    from mitlc.petri.compile import compile_spec
    from mitlc.spec.parse import parse_spec

    cs = np.linspace(-2.0, 2.0, n_props)
    props = "".join(f"prop a{i} = q > {c:.4f}\n" for i, c in enumerate(cs))
    formula = " & ".join(f"F a{i}" for i in range(n_props))
    rs = compile_spec(parse_spec(f"plant pendulum\nhorizon 3\n{props}formula {formula}\n"))
    rt = NetRuntime(rs, ("q", "qdot"), dt=0.03, steps=100)
    rng = np.random.default_rng(n_props)
    x = np.stack([rng.uniform(-3, 3, (5, 12)), np.zeros((5, 12))], axis=2)
    M, code = rt.reset(x[:, 0]), rt.reset_code(x[:, 0])
    names = rs.net.place_names
    for k in range(1, 12):
        tau = k * 0.03
        M1, code1 = rt.step(M, x[:, k], tau), rt.step_code(code, x[:, k], tau)
        np.testing.assert_array_equal(rt.decode(code1), M1)
        np.testing.assert_array_equal(rt.step_direct(M, x[:, k], tau), M1)
        for i, c in enumerate(cs):
            holds = x[:, k, 0] > round(c, 4)
            np.testing.assert_array_equal(M1[:, names.index(f"p_a{i}")], holds.astype(int))
            np.testing.assert_array_equal(M1[:, names.index(f"p_not_a{i}")], (~holds).astype(int))
        np.testing.assert_allclose(rt.reward_code(code, code1), rt.reward(M, M1))
        M, code = M1, code1


def test_obligation_clocks_and_verdicts_by_hand():
    """F[0,2] G goal at dt = 0.5 s, horizon 3 s: goal from t = 1 s on. The G obligation started
    at t = 1 s ages over the trial length (3 s), F's over its upper end (2 s); at the end both
    are decided (true) and nothing lives."""
    from mitlc.petri import timed
    from mitlc.petri.compile import compile_spec
    from mitlc.spec.parse import parse_spec

    rs = compile_spec(
        parse_spec("plant pendulum(dt = 0.5)\nhorizon 3\nprop goal = abs(q) < 0.3\nformula F[0,2] G goal\n")
    )
    rt = NetRuntime(rs, ("q", "qdot"), dt=0.5, steps=6)
    qs = [2.0, 1.0, 0.1, 0.0, 0.1, 0.0, 0.1]
    x = np.array([[[q, 0.0] for q in qs]])
    M = rt.reset(x[:, 0])
    assert rt.obligation_clocks().tolist() == [[0.0, 0.0]]
    want = [[0.0, 0.25], [0.0, 0.5], [0.5 / 3, 0.75], [1.0 / 3, 1.0], [0.5, 1.25], [0.0, 0.0]]
    for k in range(1, 7):
        M = rt.step(M, x[:, k], k * 0.5)
        np.testing.assert_allclose(rt.obligation_clocks(), [want[k - 1]], atol=1e-12)
        assert rt.verdicts().tolist() == [[timed.PENDING if k < 6 else timed.TRUE]]


def test_obligation_clocks_of_a_window_within_a_second():
    """F[0,1] G goal: the F obligation's age is over its own upper end, 1 s, not the trial."""
    from mitlc.petri.compile import compile_spec
    from mitlc.spec.parse import parse_spec

    rs = compile_spec(
        parse_spec("plant pendulum(dt = 0.5)\nhorizon 3\nprop goal = abs(q) < 0.3\nformula F[0,1] G goal\n")
    )
    rt = NetRuntime(rs, ("q", "qdot"), dt=0.5, steps=6)
    M = rt.reset(np.array([[2.0, 0.0]]))
    M = rt.step(M, np.array([[2.0, 0.0]]), 0.5)
    np.testing.assert_allclose(rt.obligation_clocks(), [[0.0, 0.5]], atol=1e-12)


def _table_mode(rt: NetRuntime) -> str:
    if rt.tables is None:
        return "none"
    return ("compact" if rt.compact else "full") + ("" if rt.tables.reward is not None else "-untabulated reward")


@pytest.mark.parametrize(
    ("spec", "violations"),
    [
        ("pendulum/p2_avoid", "counted"),
        ("pendulum/p4_alternate", "permanent"),
        ("pendulum/p5_timed_visit", "permanent"),
        ("pendulum/n3_bounded_response", "permanent"),
        ("eventuallys", "permanent"),
        ("late eventuallys", "permanent"),
    ],
)
def test_every_table_mode_steps_rewards_and_charges_alike(spec: str, violations: str, monkeypatch) -> None:
    """Whatever the table limit leaves (full tables, compact ones, compact with the reward
    evaluated on markings, none at all), step, step_code, reward_code and charge_code give
    what the full tables give, which are what the reward and charge expressions say on the
    stepped markings."""
    from mitlc.runtime import tables as RT
    from mitlc.spec.parse import load_spec

    if spec.endswith("eventuallys"):
        text = _many_eventuallys(4, props=2)
        if spec.startswith("late"):
            # windows that open late, with ends on the samples: the clock segments before the
            # first end and every end itself are stepped too
            late = "F[0.25,0.5] a0 & F[0.125,0.75] a1 & F[0.375,1] a0 & F[0.25,1.25) a1"
            text = text[: text.index("formula ")] + f"formula {late}\n"
        parsed = parse_spec(text)
    else:
        parsed = load_spec(spec)
    rs = compile_spec(parsed, CompileOptions(violations=violations))
    assert rs.charge is not None
    rng = np.random.default_rng(5)
    R, N, dt = 16, 48, 0.0625  # binary: the taus land exactly on the guards' ends
    q = np.cumsum(rng.normal(0, 0.4, (R, N + 1)), axis=1) + rng.uniform(-3, 3, (R, 1))
    x = np.stack([wrap_angle(q), rng.normal(0, 3, (R, N + 1))], axis=2)
    reference = None
    modes = set()
    for limit in (RT.MAX_TABLE, 1 << 20, 1 << 16, 1 << 12, 1):
        monkeypatch.setattr(RT, "MAX_TABLE", limit)
        rt = NetRuntime(rs, dt=dt, steps=N)  # stepped on markings
        by_code = NetRuntime(rs, dt=dt, steps=N)  # stepped on codes (its own obligation state)
        modes.add(_table_mode(rt))
        M = rt.reset(x[:, 0])
        code = by_code.reset_code(x[:, 0]) if by_code.tables is not None else None
        got = []
        for k in range(N):
            tau = (k + 1) * dt
            M1 = rt.step(M, x[:, k + 1], tau)
            reward = rt.reward(M, M1)
            charge = np.asarray(rs.charge.evaluate(M, M1), dtype=float)
            if code is not None:
                code1 = by_code.step_code(code, x[:, k + 1], tau)
                if not rt.counters.size:  # codes leave the counting places out
                    np.testing.assert_array_equal(by_code.decode(code1), M1)
                    np.testing.assert_array_equal(by_code.reward_code(code, code1), reward)
                np.testing.assert_array_equal(by_code.charge_code(code, code1), charge)
                code = code1
            elif not rt.counters.size:
                np.testing.assert_array_equal(rt.charge_code(rt.encode(M), rt.encode(M1)), charge)
            got.append((M1.copy(), reward, charge))
            M = M1
        if reference is None:
            reference = got
        else:
            for (m, r, c), (m0, r0, c0) in zip(got, reference, strict=True):
                np.testing.assert_array_equal(m, m0)
                np.testing.assert_array_equal(r, r0)
                np.testing.assert_array_equal(c, c0)
    assert "none" in modes and len(modes) >= 2, modes
    if spec.endswith("eventuallys"):
        assert any(m.startswith("compact") for m in modes), modes
    if spec == "eventuallys":
        assert {"compact", "compact-untabulated reward"} <= modes, modes


def test_timed_runtime_takes_its_trial_from_the_spec() -> None:
    """A net with timed obligations steps at the plant's dt over the spec's horizon unless told
    otherwise; without a horizon it must be told."""
    from mitlc.errors import CompileError
    from mitlc.spec.parse import load_spec

    spec = load_spec("pendulum/n3_bounded_response")
    rt = NetRuntime(compile_spec(spec))
    assert rt.dt == float(spec.param("dt")) and rt.steps == round(spec.horizon / rt.dt)
    assert NetRuntime(compile_spec(spec), dt=0.1, steps=7).steps == 7
    bare = parse_spec("plant pendulum\nprop a = q > 0\nformula G[0,1] F[0,0.5] a\n")
    with pytest.raises((CompileError, ValueError), match="horizon"):
        NetRuntime(compile_spec(bare))


def test_runtimes_of_one_compiled_net_tabulate_it_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """A training builds a runtime per design it races and per search it judges, all on one compiled
    net: the tables are built for the first and shared; another compile of the spec builds its own."""
    import mitlc.runtime.netruntime as nr

    built = []
    real = nr.build_tables

    def counting(rule, radix, rs):
        built.append(rs)
        return real(rule, radix, rs)

    monkeypatch.setattr(nr, "build_tables", counting)
    text = "plant pendulum\nprop up = abs(q) < 0.3\nprop fast = abs(qdot) > 4\nformula F G up & G !fast\n"
    rs = compile_spec(parse_spec(text))
    a, b = NetRuntime(rs), NetRuntime(rs, dt=0.1, steps=50)
    assert built == [rs] and a.tables is b.tables
    again = compile_spec(parse_spec(text))
    c = NetRuntime(again)
    assert built == [rs, again] and c.tables is not a.tables
    assert np.array_equal(c.tables.next_code, a.tables.next_code) and np.array_equal(c.tables.reward, a.tables.reward)
    x = np.array([[0.1, 0.0], [2.0, 5.0]])
    code = a.reset_code(x.copy())
    assert np.array_equal(code, b.reset_code(x.copy())) and np.array_equal(code, c.reset_code(x.copy()))


def test_shared_tables_are_only_read() -> None:
    """What every runtime of one compiled net shares is never written: a training on the numpy path
    and the code-stepping calls run with the tables' arrays read-only."""
    from mitlc.learn.sacpn import Sacpn, SacpnSettings

    text = "plant pendulum\nhorizon 2\nprop up = abs(q) < 0.3\nprop fast = abs(qdot) > 4\nformula F G up & G !fast\n"
    rs = compile_spec(parse_spec(text), CompileOptions(violations="counted"))
    rt = NetRuntime(rs)
    arrays = [a for a in (getattr(rt.tables, n) for n in Tables.__slots__) if isinstance(a, np.ndarray)]
    assert len(arrays) >= 4
    for a in arrays:
        a.setflags(write=False)
    try:
        agent = Sacpn(rs, SacpnSettings(kernel="numpy", rbf=(4, 3), trial_s=0.5), runs=2, seed=0)
        assert agent.runtime.tables is rt.tables
        agent.train(3)
        x = np.array([[0.1, 0.0], [2.0, 5.0]])
        code = rt.reset_code(x.copy())
        code1 = rt.step_code(code, x.copy(), 0.05)
        rt.reward_code(code, code1)
        rt.charge_code(code, code1)
    finally:
        for a in arrays:
            a.setflags(write=True)


def _every_pair(rs, rt) -> list[np.ndarray]:
    """The reward (or, graded, the charge) and the charge on every (previous, new) pair of the net's
    markings, evaluated on all n^2 pairs at once: what the tables held before they were built from
    the distinct rows of the places the reward reads."""
    from mitlc.runtime.tables import Radix

    radix = Radix(rt.subnet_places, rt.n_places)
    markings = radix.decode(np.arange(radix.n_codes, dtype=np.int64))
    n = len(markings)
    prev, now = np.repeat(markings, n, axis=0), np.tile(markings, (n, 1))
    from mitlc.petri import reward as R

    charge = [rs.charge] if rs.charge is not None else []
    exprs = (charge or [R.ZERO]) if rs.grader is not None else [rs.reward, *charge]
    return [np.asarray(e.evaluate(prev, now), dtype=float).reshape(n, n) for e in exprs]


PAIR_SPECS = [
    ("bench/suite/specs/cartpole_sway.mitl", {}),
    ("bench/suite/specs/unicycle_patrol_pillar.mitl", {}),
    ("bench/suite/specs/cart_patrol.mitl", {"violations": "permanent"}),
    ("specs/pendulum/p4_alternate.mitl", {"violations": "permanent"}),
    ("specs/pendulum/p3_avoid_speed_limit.mitl", {"reward": "shaped"}),
    ("specs/pendulum/n3_bounded_response.mitl", {}),
]


@pytest.mark.parametrize(("path", "options"), PAIR_SPECS)
def test_reward_tables_hold_every_pairs_value(path: str, options: dict) -> None:
    from pathlib import Path

    from mitlc.spec.parse import load_spec

    spec = load_spec(Path(__file__).resolve().parent.parent / path)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, **options))
    rt = NetRuntime(rs)
    tables = rt.tables
    assert tables is not None and not rs.net.counters
    want = _every_pair(rs, rt)
    got = [tables.charge] if rs.grader is not None else [tables.reward, tables.charge]
    for w, g in zip(want, got, strict=False):
        assert np.array_equal(w, g)
    assert rs.grader is not None or len(np.unique(want[0])) > 2  # a reward that tells moves apart
