"""mitlc.crm: counterfactual experience over markings in a Stable-Baselines3 replay buffer, against
the runtime's array path (markings, not the wrapper's tables)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 and PyTorch: pip install 'mitlc[sb3]'")
gym = pytest.importorskip("gymnasium")

from mitlc.crm import CounterfactualReplayBuffer, counterfactual_codes  # noqa: E402
from mitlc.errors import InputError  # noqa: E402
from mitlc.gym import MitlRewardWrapper, pendulum_v1_state  # noqa: E402
from mitlc.learn.runtime import NetRuntime  # noqa: E402
from mitlc.petri.compile import CompileOptions, compile_spec  # noqa: E402
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
