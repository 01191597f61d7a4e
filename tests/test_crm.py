"""mitlc.gym.crm: counterfactual experience over markings in a Stable-Baselines3 replay buffer, against
the runtime's array path (markings, not the wrapper's tables)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 and PyTorch: pip install 'mitlc[sb3]'")
gym = pytest.importorskip("gymnasium")

from mitlc.errors import InputError  # noqa: E402
from mitlc.gym import MitlRewardWrapper, pendulum_v1_state  # noqa: E402
from mitlc.gym.crm import CounterfactualReplayBuffer, counterfactual_codes, find_net_env  # noqa: E402
from mitlc.petri.compile import CompileOptions, compile_spec  # noqa: E402
from mitlc.runtime import NetRuntime  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402


def _env(spec="pendulum/p4_alternate", **kw) -> MitlRewardWrapper:
    kw = {"marking_obs": "box", "verdict": "off", "truncate_at_horizon": True, **kw}
    return MitlRewardWrapper(gym.make("Pendulum-v1"), spec, pendulum_v1_state, **kw)


def _fill(env: MitlRewardWrapper, steps: int, seed: int = 2) -> CounterfactualReplayBuffer:
    buf = CounterfactualReplayBuffer(10_000, env.observation_space, env.action_space, device="cpu", wrapper=env)
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    for _ in range(steps):
        a = env.action_space.sample()
        nxt, r, term, trunc, info = env.step(a)
        buf.add(obs[None], nxt[None], a[None], np.array([r]), np.array([term]), [info])
        obs = nxt
        if term or trunc:
            obs, _ = env.reset()
    return buf


@pytest.mark.parametrize("violations", ["off", "permanent"])
def test_counterfactual_transitions_are_the_nets_own(violations: str) -> None:
    spec = load_spec("pendulum/p4_alternate")
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))
    env = _env(rs)
    others = counterfactual_codes(env)
    assert all(len(o) >= 1 for o in others.values())  # the recurrence (and the violation record) vary
    steps = 60
    buf = _fill(env, steps)
    assert buf.pos == steps + buf.added and buf.added >= steps
    rt = NetRuntime(rs, env.state_names, dt=env.dt)
    b, p = int(np.prod(env.env.observation_space.shape)), len(env.place_names)
    real_rows = 0
    for i in range(buf.pos):
        o, o1 = buf.observations[i, 0], buf.next_observations[i, 0]
        np.testing.assert_array_equal(o[:b], buf.observations[i, 0, :b])  # the state part is the real one
        m, m1 = o[b : b + p].astype(np.int64)[None], o1[b : b + p].astype(np.int64)[None]
        x1 = env.state(o1[:b])[None]
        tau = None
        # the array path from m at x': the same next marking and reward, whatever the clock phase the
        # timeline holds (its places are kept from the real step)
        for k in range(1, 61):
            if np.array_equal(rt.step(m, x1, k * env.dt), m1):
                tau = k * env.dt
                break
        assert tau is not None, f"row {i}: no step of the net from its marking reaches its next marking"
        assert float(buf.rewards[i, 0]) == pytest.approx(float(rt.reward(m, m1, x1)[0]), rel=0, abs=1e-6)
        real_rows += 1
    assert real_rows == buf.pos


def test_a_net_without_memory_has_no_counterfactuals_and_the_errors_say_why() -> None:
    env = _env("pendulum/p1_swing_up")
    assert all(len(o) == 0 for o in counterfactual_codes(env).values())  # region only: the state decides
    assert _fill(env, 30).added == 0
    space, act = env.observation_space, env.action_space
    with pytest.raises(InputError, match="marking_obs='box'"):
        d = _env(marking_obs="dict")
        CounterfactualReplayBuffer(100, d.observation_space, act, device="cpu", wrapper=d)
    spec = load_spec("pendulum/p4_alternate")
    sparse = _env(compile_spec(spec, CompileOptions.from_spec(spec, reward="sparse")))
    with pytest.raises(InputError, match="paid by the monitor"):
        CounterfactualReplayBuffer(100, sparse.observation_space, act, device="cpu", wrapper=sparse)
    nested = _env("pendulum/n3_bounded_response")
    with pytest.raises(InputError, match="timed obligations"):
        CounterfactualReplayBuffer(100, nested.observation_space, act, device="cpu", wrapper=nested)
    with pytest.raises(InputError, match="n_envs=1"):
        CounterfactualReplayBuffer(100, space, act, device="cpu", n_envs=2, wrapper=env)


def test_sac_learns_with_the_buffer_briefly() -> None:
    from stable_baselines3 import SAC

    env = _env()
    model = SAC(
        "MlpPolicy",
        env,
        learning_starts=40,
        batch_size=32,
        seed=0,
        device="cpu",
        replay_buffer_class=CounterfactualReplayBuffer,
        replay_buffer_kwargs={"wrapper": env},
    )
    model.learn(120)
    assert model.replay_buffer.added >= 120 and model.replay_buffer.pos == 120 + model.replay_buffer.added


def _memory_size(rs) -> int:
    """How many markings the net can be in at one state and clock: every combination of one place
    in each sub-net that is neither a region net nor the timeline (the formula's memory)."""
    return int(np.prod([len(s.places) for s in rs.net.subnets if s.role not in ("region", "timeline")]))


@pytest.mark.parametrize("violations", ["off", "permanent"])
def test_the_registered_environment_fills_the_buffer(violations: str) -> None:
    """gymnasium.make("mitlc/Pendulum-v0") (wrapped in OrderEnforcing and PassiveEnvChecker) takes the
    buffer as the wrapper does: with each real step, one transition per other memory the net allows,
    stepped and paid by the net at the real next state."""
    import mitlc.gym  # noqa: F401 - registers the environments

    spec = load_spec("pendulum/p4_alternate")
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))
    env = gym.make("mitlc/Pendulum-v0", spec=rs, marking_obs="box", verdict="off")
    base = env.unwrapped
    assert type(env).__name__ != "MitlPlantEnv" and base.marking_offset == 2
    per_step = _memory_size(rs) - 1
    assert per_step == (1 if violations == "off" else 3)
    buf = CounterfactualReplayBuffer(10_000, env.observation_space, env.action_space, device="cpu", wrapper=env)
    rt = NetRuntime(rs, dt=base.dt, steps=base.steps)
    p, b = len(base.place_names), base.marking_offset
    env.action_space.seed(5)
    obs, _ = env.reset(seed=5)
    for k in range(1, 41):
        a = env.action_space.sample()
        nxt, r, term, trunc, info = env.step(a)
        before = buf.pos
        buf.add(obs[None], nxt[None], a[None], np.array([r]), np.array([term]), [info])
        assert buf.pos - before == 1 + per_step  # the real transition, then the counterfactual ones
        rows = range(before + 1, buf.pos)
        starts = {tuple(buf.observations[i, 0, b : b + p].astype(int)) for i in rows}
        real = tuple(obs[b : b + p].astype(int))
        assert len(starts) == per_step and real not in starts
        for i in rows:
            m = buf.observations[i, 0, b : b + p].astype(np.int64)[None]
            m1 = buf.next_observations[i, 0, b : b + p].astype(np.int64)[None]
            np.testing.assert_array_equal(buf.observations[i, 0, :b], obs[:b])  # the same real state
            np.testing.assert_array_equal(m1, rt.step(m, nxt[None, :b].astype(float), k * base.dt))
            assert buf.rewards[i, 0] == pytest.approx(float(rt.reward(m, m1)[0]), abs=1e-6)
            for s in rs.net.subnets:  # the region the state decides is the real one
                if s.role == "region":
                    assert [m[0, j] for j in s.places] == [real[j] for j in s.places]
        obs = nxt
    assert buf.added == 40 * per_step


def test_the_buffer_names_its_wrapper_argument() -> None:
    """A wrong environment is named by its classes, and the error by the buffer's argument."""
    import mitlc.gym  # noqa: F401

    env = gym.make("mitlc/Pendulum-v0", spec="pendulum/p4_alternate", marking_obs="box")
    cart = gym.make("CartPole-v1")
    with pytest.raises(InputError) as err:
        CounterfactualReplayBuffer(100, env.observation_space, env.action_space, device="cpu", wrapper=cart)
    assert str(err.value) == (
        "CounterfactualReplayBuffer(wrapper=): error: wrapper must be the environment the learner steps, "
        "a MitlRewardWrapper or a MitlPlantEnv (gymnasium.make('mitlc/Pendulum-v0', ...)), or a Gymnasium "
        "wrapper of one; got TimeLimit<OrderEnforcing<PassiveEnvChecker<CartPoleEnv>>>"
    )
    d = gym.make("mitlc/Pendulum-v0", spec="pendulum/p4_alternate")
    with pytest.raises(InputError, match=r"^CounterfactualReplayBuffer\(wrapper=\): error: .*marking_obs='box'"):
        CounterfactualReplayBuffer(100, d.observation_space, d.action_space, device="cpu", wrapper=d)
    spec = load_spec("pendulum/p4_alternate")
    counted = compile_spec(spec, CompileOptions.from_spec(spec, violations="counted"))
    c = gym.make("mitlc/Pendulum-v0", spec=counted, marking_obs="box")
    with pytest.raises(InputError, match=r"counting places \(violations = counted\)"):
        CounterfactualReplayBuffer(100, c.observation_space, c.action_space, device="cpu", wrapper=c)


def test_sac_learns_on_the_registered_environment_briefly() -> None:
    from stable_baselines3 import SAC

    import mitlc.gym  # noqa: F401

    env = gym.make("mitlc/Pendulum-v0", spec="pendulum/p4_alternate", marking_obs="box", verdict="off")
    model = SAC(
        "MlpPolicy",
        env,
        learning_starts=40,
        batch_size=32,
        seed=0,
        device="cpu",
        replay_buffer_class=CounterfactualReplayBuffer,
        replay_buffer_kwargs={"wrapper": env},
    )
    model.learn(100)
    assert model.replay_buffer.added == 100 and model.replay_buffer.pos == 200


def test_the_old_module_warns_and_gives_the_same_objects(monkeypatch: pytest.MonkeyPatch) -> None:
    """mitlc.crm, where the buffer was, stays one release: importing it warns once, naming the
    importer's line, and gives mitlc.gym.crm's own objects."""
    import linecache
    import warnings

    monkeypatch.delitem(sys.modules, "mitlc.crm", raising=False)  # imported afresh: its warning again
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        import mitlc.crm as old  # the only import of the old module in the project
    moved = [w for w in caught if issubclass(w.category, DeprecationWarning)]
    assert len(moved) == 1, [str(w.message) for w in caught]
    assert str(moved[0].message).startswith("mitlc.crm moved to mitlc.gym.crm; ")
    assert moved[0].filename == __file__  # the importer's line, not the shim's
    assert "import mitlc.crm as old" in linecache.getline(__file__, moved[0].lineno)
    assert old.CounterfactualReplayBuffer is CounterfactualReplayBuffer
    assert old.counterfactual_codes is counterfactual_codes
    assert old.find_net_env is find_net_env
    assert old.__all__ == ["CounterfactualReplayBuffer", "counterfactual_codes", "find_net_env"]
