"""The field's rewards generated from the spec (reward = sparse | robustness | robustness-window),
against the monitor on the trace or window they speak of, in SACPN and the Gymnasium wrapper."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import formulas, grid_intervals

from mitlc.errors import CompileError, TrainingError
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.monitor.offline import monitor
from mitlc.monitor.rewards import TraceReward, formula_horizon, pay
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.spec import ast as A
from mitlc.spec.parse import load_spec, parse_formula, parse_spec

DT = 0.5
SPEC = "plant pendulum(dt = 0.5)\nhorizon 4\nprop a = q > 0\nprop b = qdot > 0\nformula {}\n"


def _trace(rng: np.random.Generator, runs: int, n: int) -> np.ndarray:
    return np.stack([rng.uniform(-1, 1, (runs, n)), rng.uniform(-1, 1, (runs, n))], axis=2)


@settings(max_examples=150, deadline=None)
@given(
    formulas(atoms=("a", "b"), interval=grid_intervals(step=DT, max_end=4), max_leaves=5, weighted=False),
    st.sampled_from(["sparse", "robustness", "robustness-window"]),
    st.integers(1, 9),
    st.integers(0, 2**31 - 1),
)
def test_each_step_is_the_monitor_on_its_trace_or_window(f: A.Formula, design: str, n: int, seed: int) -> None:
    spec = parse_spec(SPEC.format(f))
    x = _trace(np.random.default_rng(seed), 3, n + 1)
    tr = TraceReward(spec, design, DT, ("q", "qdot"), runs=3)
    tr.reset(x[:, 0])
    got = np.stack([tr.step(x[:, k], last=k == n) for k in range(1, n + 1)], axis=1)
    h = formula_horizon(spec.monitor_formula)
    W = int(math.floor((h if math.isfinite(h) else 1.0) / DT + 1e-9)) + 1
    assert tr.window == W
    for k in range(1, n + 1):
        if design == "robustness-window":  # infinite robustness (no witness in the window) is paid finite
            want = np.clip(monitor(spec, x[:, max(0, k + 1 - W) : k + 1], DT).robustness, -tr.bound, tr.bound)
        elif k < n:
            want = np.zeros(3)
        else:
            res = monitor(spec, x, DT)
            want = res.satisfied.astype(float) if design == "sparse" else np.clip(res.robustness, -tr.bound, tr.bound)
        np.testing.assert_array_equal(got[:, k - 1], want)


def test_formula_horizon_by_hand() -> None:
    cases = {"a": 0.0, "F[0,2] a": 2.0, "G[1,2] F[0,0.5] a": 2.5, "a U[0,3] G[0,1] b": 4.0, "F G a": math.inf}
    for text, h in cases.items():
        assert formula_horizon(parse_formula(text)) == h, text


def _agent(design: str, runs: int = 4) -> Sacpn:
    spec = load_spec("pendulum/p1_swing_up")
    return Sacpn(compile_spec(spec, CompileOptions.from_spec(spec, reward=design)), SacpnSettings(), runs=runs, seed=3)


@pytest.mark.parametrize("design", ["sparse", "robustness", "robustness-window"])
def test_sacpn_is_paid_by_the_monitor(design: str) -> None:
    agent = _agent(design)
    assert agent.kernel == "numpy" and "monitor" in (agent.kernel_reason or "")
    with pytest.raises(TrainingError, match="paid by the monitor"):
        agent.train(1)
    pay(agent)
    returns = agent.train(3)
    ro = agent.rollout(agent.evaluation_states())
    res = monitor(agent.spec, ro.states, agent.dt)
    if design == "sparse":  # one 1 at the end of a satisfying trial, else nothing
        assert set(np.unique(returns)) <= {0.0, 1.0}
        np.testing.assert_array_equal(ro.rewards[:, :-1], 0.0)
        np.testing.assert_array_equal(ro.rewards[:, -1], res.satisfied.astype(float))
    elif design == "robustness":
        np.testing.assert_array_equal(ro.rewards[:, :-1], 0.0)
        np.testing.assert_array_equal(ro.rewards[:, -1], res.robustness)
    else:
        W = agent.trace_reward.window
        k = ro.rewards.shape[1]
        np.testing.assert_array_equal(
            ro.rewards[:, -1], monitor(agent.spec, ro.states[:, k + 1 - W :], agent.dt).robustness
        )
    assert np.isfinite(returns).all()


def test_the_same_seed_gives_the_same_numbers() -> None:
    a, b = pay(_agent("robustness-window", 2)), pay(_agent("robustness-window", 2))
    np.testing.assert_array_equal(a.train(2), b.train(2))
    np.testing.assert_array_equal(a.xi, b.xi)


def test_violations_apply_to_the_nets_rewards_only() -> None:
    spec = load_spec("pendulum/p2_avoid")
    with pytest.raises(CompileError, match="paid by the monitor"):
        compile_spec(spec, CompileOptions.from_spec(spec, reward="sparse", violations="permanent"))
    rs = compile_spec(spec, CompileOptions.from_spec(spec, reward="sparse"))
    assert rs.paid_by_monitor and rs.grader is None
    assert str(rs.reward) == str(compile_spec(spec).reward)  # the net the learner's places follow


def test_gymnasium_wrapper_pays_the_monitors_reward() -> None:
    gym = pytest.importorskip("gymnasium")
    from mitlc.gym import MitlRewardWrapper, pendulum_v1_state

    spec = load_spec("pendulum/p1_swing_up")
    for design in ("sparse", "robustness", "robustness-window"):
        rs = compile_spec(spec, CompileOptions.from_spec(spec, reward=design))
        env = MitlRewardWrapper(gym.make("Pendulum-v1"), rs, pendulum_v1_state, truncate_at_horizon=True)
        env.action_space.seed(5)
        obs, info = env.reset(seed=5)
        rewards, states = [], [env.state(obs["obs"])]
        while True:
            obs, r, terminated, truncated, info = env.step(env.action_space.sample())
            rewards.append(r)
            states.append(env.state(obs["obs"]))
            if terminated or truncated:
                break
        res = monitor(spec, np.array(states)[None], env.dt)
        if design == "robustness-window":
            assert rewards[-1] == monitor(spec, np.array(states)[None, -env._paid.window :], env.dt).robustness[0]  # noqa: SLF001
        else:
            assert rewards[:-1] == [0.0] * (len(rewards) - 1)
            assert rewards[-1] == (float(res.satisfied[0]) if design == "sparse" else res.robustness[0])
            assert rewards[-1] == (
                float(info["verdict"]["satisfied"]) if design == "sparse" else info["verdict"]["robustness"]
            )


def test_compile_says_who_pays() -> None:
    from click.testing import CliRunner

    from mitlc.cli.main import main

    for design, says in [
        ("sparse", "the learner is paid by the monitor instead"),
        ("shaped", "s_a = (p_a - p_not_a + g_a) / 2"),
        ("graded", "g_a = robustness of a over the state bounds"),
    ]:
        r = CliRunner().invoke(main, ["compile", "pendulum/p4_alternate", "--reward", design])
        assert r.exit_code == 0 and says in r.output, r.output
    r = CliRunner().invoke(main, ["compile", "pendulum/p4_alternate", "--reward", "dense"])
    assert r.exit_code == 2 and "'dense' is not one of" in r.output


def test_a_diverging_run_gets_nan_not_an_error() -> None:
    """A run whose state is no longer finite is paid nan (SACPN then stops that run); the others
    are paid as the monitor says."""
    spec = parse_spec(SPEC.format("F[0,1] a"))
    for design in ("sparse", "robustness", "robustness-window"):
        tr = TraceReward(spec, design, DT, ("q", "qdot"), runs=2)
        tr.reset(np.array([[0.5, 0.0], [0.5, 0.0]]))
        got = tr.step(np.array([[np.nan, 0.0], [0.2, 0.0]]), last=True)
        assert np.isnan(got[0]) and got[1] == (1.0 if design == "sparse" else 0.5)  # max of q over [0, 1] s


def test_infinite_robustness_is_paid_as_the_largest_margin() -> None:
    """F(1,2] a over a window that cannot reach 1 s has robustness -inf; a reward must be finite."""
    spec = parse_spec(SPEC.format("F(1,2] a & G a"))  # horizon inf (G): a window of 1 s = 3 samples
    tr = TraceReward(spec, "robustness-window", DT, ("q", "qdot"))
    assert tr.window == 3 and tr.bound == np.pi  # q > 0 over q in [-pi, pi]: margins up to pi
    tr.reset(np.array([[0.5, 0.0]]))
    r = tr.step(np.array([[0.5, 0.0]]), last=False)
    assert r[0] == -tr.bound
