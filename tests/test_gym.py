"""mitlc.gym: the Gymnasium wrapper against Gymnasium's checker and the built-in runtime."""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

gym = pytest.importorskip("gymnasium", reason="the gym extra is not installed: pip install '.[test]'")
from gymnasium.utils.env_checker import check_env  # noqa: E402

from mitlc.errors import InputError, MitlError  # noqa: E402
from mitlc.gym import MitlRewardWrapper, pendulum_v1_state  # noqa: E402
from mitlc.petri.compile import CompileOptions, compile_spec  # noqa: E402
from mitlc.plants.base import wrap_angle  # noqa: E402
from mitlc.runtime import NetRuntime  # noqa: E402
from mitlc.spec.parse import load_spec, parse_spec  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SPECS = ROOT / "specs" / "pendulum"
P1 = SPECS / "p1_swing_up.mitl"
P5 = SPECS / "p5_timed_visit.mitl"
PENDULUM_DT = 0.05  # Gymnasium's Pendulum-v1: env.unwrapped.dt
HAS_MONITOR = importlib.util.find_spec("mitlc.monitor") is not None

UPRIGHT = (
    "plant pendulum(u_max = 3)\ninit q in [-0.1, 0.1], qdot = 0\nhorizon 3\nprop kappa = abs(q) < 0.3\n"
    "formula F G kappa\n"
)
"""A spec whose pendulum starts inside kappa, near the top."""

# Warnings check_env gives for Pendulum-v1 itself, whatever wraps it.
KNOWN_WARNINGS = ("is different from the unwrapped version", "symmetric and normalized space")


def wrapped(spec=P1, **kwargs) -> MitlRewardWrapper:
    return MitlRewardWrapper(gym.make("Pendulum-v1"), spec, pendulum_v1_state, **kwargs)


def random_rollout(env, seed: int, steps: int):
    """A seeded random agent: the actions, observations, rewards and infos of one episode."""
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    actions, observations, rewards, infos, ends = [], [obs], [], [info], []
    for _ in range(steps):
        a = env.action_space.sample()
        obs, r, terminated, truncated, info = env.step(a)
        actions.append(a)
        observations.append(obs)
        rewards.append(r)
        infos.append(info)
        ends.append((terminated, truncated))
    return actions, observations, rewards, infos, ends


# ------------------------------------------------------------------ Gymnasium's checker


@pytest.mark.parametrize("marking_obs", ["dict", "box"])
@pytest.mark.parametrize("spec", [P1, P5], ids=["p1", "p5"])
def test_check_env_passes(spec: Path, marking_obs: str, monkeypatch) -> None:
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = wrapped(spec, marking_obs=marking_obs)
    # The render check draws Pendulum-v1 with pygame (gymnasium[classic-control]).
    skip_render = importlib.util.find_spec("pygame") is None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=skip_render)
    others = [str(w.message) for w in caught if not any(k in str(w.message) for k in KNOWN_WARNINGS)]
    assert others == []


def test_spaces() -> None:
    d = wrapped(P5)
    assert isinstance(d.observation_space, gym.spaces.Dict)
    assert d.observation_space["marking"] == gym.spaces.MultiBinary(5)
    assert d.observation_space["obs"] == d.env.observation_space
    b = wrapped(P5, marking_obs="box")
    assert b.observation_space.shape == (3 + 5,) and b.observation_space.dtype == np.float32
    np.testing.assert_array_equal(b.observation_space.low, [-1, -1, -8, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(b.observation_space.high, [1, 1, 8, 1, 1, 1, 1, 1])
    assert d.dt == PENDULUM_DT and b.dt == PENDULUM_DT


# ------------------------------------------------------------------ the reward is the runtime's


def test_200_steps_of_pendulum_v1_equal_the_runtime() -> None:
    seed, steps = 1, 200
    env = wrapped(P1, verdict="off")
    actions, observations, rewards, infos, ends = random_rollout(env, seed, steps)

    # The same states, from the bare environment with the same seed and actions.
    raw = gym.make("Pendulum-v1")
    raw_obs = [raw.reset(seed=seed)[0]]
    for a in actions:
        raw_obs.append(raw.step(a)[0])
    raw_obs = np.array(raw_obs)
    np.testing.assert_array_equal(np.array([o["obs"] for o in observations]), raw_obs)

    s = pendulum_v1_state(raw_obs)
    x = np.stack([s["q"], s["qdot"]], axis=1)  # (N+1, 2) in the plant's order (q, qdot)
    rt = NetRuntime(compile_spec(load_spec(P1)))
    M = rt.reset(x[:1])
    expected, markings = [], [M[0]]
    for k in range(1, steps + 1):
        M_next = rt.step(M, x[k : k + 1], k * PENDULUM_DT)
        expected.append(float(rt.reward(M, M_next)[0]))
        M = M_next
        markings.append(M[0])
    assert rewards == expected
    np.testing.assert_array_equal(np.array([i["marking"] for i in infos]), np.array(markings))
    np.testing.assert_array_equal(np.array([o["marking"] for o in observations]), np.array(markings))

    # And by hand: (4-12) r = (1 + ~p_kappa)(p_kappa - p_not_kappa), kappa = |q| < 0.3.
    kappa = np.abs(x[:, 0]) < 0.3
    by_hand = (1.0 + kappa[:-1]) * np.where(kappa[1:], 1.0, -1.0)
    np.testing.assert_array_equal(rewards, by_hand)
    values, counts = np.unique(rewards, return_counts=True)
    assert dict(zip(values.tolist(), counts.tolist(), strict=True)) == {-2.0: 4, -1.0: 178, 1.0: 3, 2.0: 15}
    # Pendulum-v1's TimeLimit ends the episode at step 200, and the wrapper passes it on.
    assert ends[-1] == (False, True) and all(e == (False, False) for e in ends[:-1])
    assert [i["tau"] for i in infos[:3]] == [0.0, 0.05, 0.1]
    assert all(isinstance(r, float) for r in rewards)
    assert all(math.isfinite(i["env_reward"]) for i in infos[1:])


@pytest.mark.parametrize("violations", ["off", "permanent"])
@pytest.mark.parametrize("spec_path", sorted(SPECS.glob("*.mitl")), ids=lambda p: p.stem)
def test_every_thesis_spec_rewards_as_the_runtime(spec_path: Path, violations: str) -> None:
    spec = load_spec(spec_path)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))
    env = MitlRewardWrapper(gym.make("Pendulum-v1"), rs, pendulum_v1_state, verdict="off", truncate_at_horizon=True)
    _, observations, rewards, infos, ends = random_rollout(env, seed=6, steps=60)
    assert ends[-1] == (False, True)
    x = np.array([env.state(o["obs"]) for o in observations])
    rt = NetRuntime(rs, dt=env.dt, steps=env.runtime.steps)  # the wrapper's clock: Pendulum-v1's dt
    M = rt.reset(x[:1])
    for k in range(1, 61):
        M_next = rt.step(M, x[k : k + 1], k * PENDULUM_DT)
        assert rewards[k - 1] == float(rt.reward(M, M_next)[0])
        np.testing.assert_array_equal(infos[k]["marking"], M_next[0])
        M = M_next
    if violations == "permanent":  # r' = r of the thesis's net, less c on every step from a violation on
        off = random_rollout(wrapped(spec_path, verdict="off", truncate_at_horizon=True), seed=6, steps=60)[2]
        m = np.array([i["marking"] for i in infos])
        watched = [i for i, p in enumerate(rs.net.places) if p.name.startswith(("p_violated_", "p_late_", "p_failed_"))]
        violated = m[1:, watched].sum(axis=1) > 0
        np.testing.assert_allclose(rewards, np.array(off) - rs.penalty * violated)
        assert violated.any()  # the random agent violates every spec at least once


@pytest.mark.parametrize("violations", ["off", "permanent"])
@pytest.mark.parametrize("spec_path", sorted(SPECS.glob("p*.mitl")), ids=lambda p: p.stem)
def test_one_sample_path_is_the_array_path(spec_path: Path, violations: str) -> None:
    """The thesis nets step one sample on Python numbers (NetRuntime.sample_stepper: clocks or none);
    forced onto the array path, the same wrapper gives the same rewards, markings and observations."""
    spec = load_spec(spec_path)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))
    fast = MitlRewardWrapper(gym.make("Pendulum-v1"), rs, pendulum_v1_state, verdict="end", truncate_at_horizon=True)
    slow = MitlRewardWrapper(gym.make("Pendulum-v1"), rs, pendulum_v1_state, verdict="end", truncate_at_horizon=True)
    assert fast._step1 is not None  # noqa: SLF001 - which path the wrapper takes
    slow._step1 = None  # noqa: SLF001
    a, b = random_rollout(fast, seed=3, steps=60), random_rollout(slow, seed=3, steps=60)
    assert a[2] == b[2] and a[4] == b[4]
    for oa, ob in zip(a[1], b[1], strict=True):
        assert oa.keys() == ob.keys()
        for key in oa:
            np.testing.assert_array_equal(oa[key], ob[key])
            assert oa[key].dtype == ob[key].dtype
    for ia, ib in zip(a[3], b[3], strict=True):
        np.testing.assert_array_equal(ia.pop("marking"), ib.pop("marking"))
        assert ia == ib  # tau, env_reward and the episode's verdict


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=-1.0, max_value=1.0, allow_nan=False), st.floats(-1.0, 1.0), st.floats(-8.0, 8.0))
def test_one_observation_reads_as_the_batch(c: float, s: float, thdot: float) -> None:
    """pendulum_v1_state and the wrapper's reader on one observation (floats, Python's %) give the
    numbers of the batch path (numpy arrays, wrap_angle), to the bit."""
    obs = np.array([c, s, thdot], dtype=np.float32)
    one, batch = pendulum_v1_state(obs), pendulum_v1_state(obs[None, :])
    assert one["q"] == batch["q"][0] and one["qdot"] == batch["qdot"][0]
    env = wrapped(P1, verdict="off")
    x = env.state(obs)
    assert x[0] == wrap_angle(np.arctan2(np.float64(obs[1]), np.float64(obs[0]))) and x[1] == np.float64(obs[2])
    raw = 3.5 * np.pi * c + 40 * s  # angles far outside [-pi, pi)
    wrapping = MitlRewardWrapper(gym.make("Pendulum-v1"), P1, {"q": lambda o: raw, "qdot": 2}, verdict="off")
    assert wrapping.state(obs)[0] == wrap_angle(np.array([raw]))[0]


def test_counting_nets_observe_counts_in_a_box() -> None:
    spec = load_spec(SPECS / "p2_avoid.mitl")
    rs = compile_spec(spec, CompileOptions(violations="counted"))
    d = MitlRewardWrapper(gym.make("Pendulum-v1"), rs, pendulum_v1_state)
    counters = [i for i, n in enumerate(d.place_names) if n.startswith("p_count_")]
    assert [d.place_names[i] for i in counters] == ["p_count_G_not_psi"]
    marking = d.observation_space["marking"]
    assert isinstance(marking, gym.spaces.Box) and marking.dtype == np.float32
    assert np.isinf(marking.high[counters]).all() and (np.delete(marking.high, counters) == 1).all()
    b = MitlRewardWrapper(gym.make("Pendulum-v1"), rs, pendulum_v1_state, marking_obs="box")
    assert np.isinf(b.observation_space.high[3:][counters]).all()


def test_box_observation_is_obs_then_marking() -> None:
    env = wrapped(P5, marking_obs="box", verdict="off")
    _, observations, _, infos, _ = random_rollout(env, seed=4, steps=30)
    for o, info in zip(observations, infos, strict=True):
        assert o.dtype == np.float32 and o.shape == (8,)
        np.testing.assert_array_equal(o[3:], info["marking"])
        assert o[3:].sum() == 2  # one token in the timeline, one in kappa's region net


def test_reset_restores_the_initial_marking() -> None:
    env = wrapped(P5, verdict="off")
    net = env.reward_system.net
    assert env.place_names == ("p_tau<=1", "p_1<tau<=2", "p_tau>2", "p_kappa", "p_not_kappa")
    env.action_space.seed(0)
    obs, info = env.reset(seed=0)
    for _ in range(45):  # past tau = 2 s: the timeline token is in p_tau>2
        obs, *_, info = env.step(env.action_space.sample())
    assert info["marking"][:3].tolist() == [0, 0, 1]
    obs, info = env.reset(seed=5)
    np.testing.assert_array_equal(info["marking"][:3], net.M0[:3])  # timeline back at p_tau<=1
    x0 = env.state(obs["obs"])
    np.testing.assert_array_equal(info["marking"], NetRuntime(env.reward_system).reset(x0[None])[0])
    kappa = abs(x0[0]) > math.pi - 0.5  # kappa is the bottom in problem 5
    assert info["marking"][3:].tolist() == ([1, 0] if kappa else [0, 1])
    assert info["tau"] == 0.0 and env.trace.shape == (1, 2)


@pytest.mark.parametrize("seed", [1, 2])
def test_reset_is_deterministic(seed: int) -> None:
    a = random_rollout(wrapped(P5, verdict="off"), seed, 20)
    b = random_rollout(wrapped(P5, verdict="off"), seed, 20)
    assert a[2] == b[2]
    for ia, ib in zip(a[3], b[3], strict=True):
        np.testing.assert_array_equal(ia["marking"], ib["marking"])


def test_truncate_at_horizon() -> None:
    env = wrapped(P1, verdict="off", truncate_at_horizon=True)
    _, _, _, infos, ends = random_rollout(env, seed=0, steps=60)  # 3 s at 0.05 s
    assert ends[-1] == (False, True) and not any(tr for _, tr in ends[:-1])
    assert infos[-1]["tau"] == pytest.approx(3.0)


# ------------------------------------------------------------------ info: marking and verdict


@pytest.mark.skipif(not HAS_MONITOR, reason="mitlc.monitor is not there yet")
def test_info_has_the_monitors_verdict_so_far() -> None:
    from mitlc.monitor.offline import monitor

    env = wrapped(P1)
    _, observations, _, infos, _ = random_rollout(env, seed=1, steps=40)
    spec = env.mitl_spec
    states = np.array([env.state(o["obs"]) for o in observations])
    for k in range(41):  # every prefix, from the online monitor
        res = monitor(spec, states[: k + 1], PENDULUM_DT)
        v = infos[k]["verdict"]
        assert v == {"satisfied": bool(res.satisfied[0]), "robustness": float(res.robustness[0])}
    # at the episode's end: the offline monitor's whole verdict, when and why it failed
    env = wrapped(P1, truncate_at_horizon=True)
    _, observations, _, infos, ends = random_rollout(env, seed=1, steps=60)
    assert ends[-1] == (False, True)
    states = np.array([env.state(o["obs"]) for o in observations])
    res = monitor(spec, states, PENDULUM_DT)
    last = infos[-1]["verdict"]
    assert last["satisfied"] == bool(res.satisfied[0]) and last["robustness"] == float(res.robustness[0])
    assert last["failing"] == res.failing[0] and last["violation_time"] == float(res.violation_time[0])
    # F G kappa over x_0..x_k: the pendulum starts in kappa (q = 0.074) and falls out.
    assert infos[0]["verdict"]["satisfied"] is True
    assert infos[40]["verdict"]["satisfied"] is False


@pytest.mark.skipif(not HAS_MONITOR, reason="mitlc.monitor is not there yet")
@pytest.mark.parametrize(
    "spec",
    [
        "pendulum/p3_avoid_speed_limit",  # constant time: the one-run monitor on floats
        "pendulum/p4_alternate",  # its check line reads the prefix again: the array monitor
        "plant pendulum\nhorizon 1\nprop slow = abs(qdot) < 100\nformula G slow",  # satisfied to the end
    ],
)
def test_every_steps_verdict_is_the_offline_monitors(spec: str) -> None:
    """verdict="step": each prefix's verdict and robustness, and the whole episode's at its end
    (when and why it failed, or that it did not), are the offline monitor's to the bit."""
    from mitlc.monitor.offline import monitor

    env = wrapped(parse_spec(spec) if "\n" in spec else spec, truncate_at_horizon=True)
    assert env._online_scalar is ("p4" not in spec)  # noqa: SLF001 - which monitor the test is about
    _, observations, _, infos, ends = random_rollout(env, seed=3, steps=int(round(env.mitl_spec.horizon / 0.05)))
    assert ends[-1] == (False, True)
    states = np.array([env.state(o["obs"]) for o in observations])
    for k, info in enumerate(infos):
        res = monitor(env.mitl_spec, states[: k + 1], PENDULUM_DT)
        want = {"satisfied": bool(res.satisfied[0]), "robustness": float(res.robustness[0])}
        if k == len(infos) - 1:
            t = float(res.violation_time[0])
            want.update(violation_time=None if math.isnan(t) else t, failing=res.failing[0])
        assert info["verdict"] == want, k


def test_verdict_modes() -> None:
    off = random_rollout(wrapped(P1, verdict="off"), 1, 3)[3]
    assert all("verdict" not in i and "marking" in i for i in off)
    if HAS_MONITOR:
        end = random_rollout(wrapped(P1, verdict="end", truncate_at_horizon=True), 1, 60)[3]
        assert [k for k, i in enumerate(end) if "verdict" in i] == [60]


def test_without_the_monitor_there_is_no_verdict(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "mitlc.monitor", None)  # import mitlc.monitor raises ImportError
    env = wrapped(P1)
    _, info = env.reset(seed=1)
    assert "verdict" not in info and info["marking"].tolist() == [1, 0]


# ------------------------------------------------------------------ observe mappings


def test_observe_mapping_of_indices_and_functions() -> None:
    observe = {"q": lambda o: math.atan2(float(o[1]), float(o[0])), "qdot": 2}
    a = random_rollout(MitlRewardWrapper(gym.make("Pendulum-v1"), P1, observe, verdict="off"), 2, 50)
    b = random_rollout(wrapped(P1, verdict="off"), 2, 50)
    assert a[2] == b[2]


def test_spec_without_plant_uses_the_propositions_variables_and_given_dt() -> None:
    spec = parse_spec("prop fast = abs(w) > 4\nformula G !fast")
    env = MitlRewardWrapper(gym.make("Pendulum-v1"), spec, {"w": 2}, dt=0.1, verdict="off")
    assert env.state_names == ("w",) and env.dt == 0.1
    _, observations, rewards, infos, _ = random_rollout(env, 0, 20)
    assert infos[3]["tau"] == pytest.approx(0.3)
    fast = np.array([abs(o["obs"][2]) > 4 for o in observations])
    # G !fast: r = (1 + ~h)(p_not_fast - p_fast) with h = ~p_not_fast
    m = np.array([i["marking"] for i in infos])  # places: p_fast, p_not_fast
    np.testing.assert_array_equal(m[:, 0], fast)
    np.testing.assert_array_equal(rewards, (1 + m[:-1, 1]) * (m[1:, 1] - m[1:, 0]))
    assert fast.any() and not fast.all()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"marking_obs": "flat"}, "marking_obs must be one of dict, box"),
        ({"verdict": "always"}, "verdict must be one of step, end, off"),
        ({"observe": {"theta": 0, "q": 1}}, "observe maps 'theta', which is not a state variable"),
        ({"observe": {"qdot": 2}}, "no value for state variable 'q'"),
        ({"observe": {"q": 7}}, "index 7, outside the flattened observation of size 3"),
        ({"observe": {"q": "cos"}}, "expected an index or a function"),
        ({"observe": 3}, "observe must be a function or a mapping"),
        ({"dt": -0.05}, "dt must be positive and finite"),
        ({"spec": 42}, "expected a RewardSystem, a Spec or the path"),
    ],
)
def test_bad_arguments_are_one_line_input_errors(kwargs: dict, message: str) -> None:
    args = {"spec": P1, "observe": pendulum_v1_state, **kwargs}
    with pytest.raises(InputError, match=message.replace("(", r"\(")) as err:
        MitlRewardWrapper(gym.make("Pendulum-v1"), args.pop("spec"), args.pop("observe"), **args)
    assert "\n" not in str(err.value)


def test_bad_observations_are_input_errors() -> None:
    env = MitlRewardWrapper(gym.make("Pendulum-v1"), P1, lambda o: {"q": float("nan"), "qdot": 0.0})
    with pytest.raises(InputError, match="non-finite value for 'q'"):
        env.reset(seed=0)
    env = MitlRewardWrapper(gym.make("Pendulum-v1"), P1, lambda o: {"qdot": 0.0})
    with pytest.raises(InputError, match="no value for state variable 'q'"):
        env.reset(seed=0)
    env = MitlRewardWrapper(gym.make("Pendulum-v1"), P1, lambda o: {"x": 0.0, "q": 0.0})
    with pytest.raises(InputError, match="'x', which is not a state variable of the spec \\(q, qdot\\)"):
        env.reset(seed=0)
    with pytest.raises(InputError, match="3 entries"):
        pendulum_v1_state(np.zeros(2))


def test_no_dt_anywhere_is_an_input_error() -> None:
    class NoDt(gym.Env):
        observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
        action_space = gym.spaces.Discrete(2)

    spec = parse_spec("prop a = x > 0\nformula F a")
    with pytest.raises(InputError, match="no dt"):
        MitlRewardWrapper(NoDt(), spec, {"x": 0})
    assert MitlRewardWrapper(NoDt(), P1, pendulum_v1_state).dt == 0.03  # the plant's dt


def test_without_gymnasium_the_import_error_says_what_to_install() -> None:
    code = "import sys; sys.modules['gymnasium'] = None\nimport mitlc.gym"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert r.returncode == 1
    assert "ImportError: mitlc.gym needs Gymnasium, an optional dependency: pip install 'mitlc[gym]'" in r.stderr


def test_nested_spec_observation_carries_the_obligation_clocks() -> None:
    """A bounded response: the response obligation's age over 0.5 s rides beside the marking."""
    from gymnasium.utils.env_checker import check_env

    spec = SPECS / "n3_bounded_response.mitl"
    env = MitlRewardWrapper(gym.make("Pendulum-v1"), spec, pendulum_v1_state, verdict="off", truncate_at_horizon=True)
    assert env.observation_space["clocks"].shape == (2,)  # the F[0,0.5] node and the G root
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"obs", "marking", "clocks"}
    open_f = env.place_names.index("p_open_F1")  # the response F[0,0.5] !fast
    ages, opened = [], []
    for _ in range(40):  # full torque one way: the pendulum spins up past |qdot| = 3
        obs, *_ = env.step(np.array([2.0], np.float32))
        ages.append(float(obs["clocks"][0]))
        opened.append(bool(obs["marking"][open_f]))
        assert env.observation_space.contains(obs)
    ages_a = np.array(ages)
    assert np.any(ages_a > 0) and any(opened)
    # while one response obligation lives its clock grows by dt / 0.5 a step
    grow = np.diff(ages_a)[(ages_a[:-1] > 0) & (ages_a[1:] > ages_a[:-1])]
    np.testing.assert_allclose(grow, env.dt / 0.5, rtol=1e-6)
    assert env.runtime.obligation_clocks().shape == (1, 2)
    check_env(env, skip_render_check=True)
    box = MitlRewardWrapper(gym.make("Pendulum-v1"), spec, pendulum_v1_state, marking_obs="box", verdict="off")
    o, _ = box.reset(seed=1)
    assert o.shape == (3 + len(box.place_names) + 2,)


def test_registered_environments_of_mitlc_plants() -> None:
    """gymnasium.make("mitlc/Pendulum-v0", spec=...): the compiled reward, the spec's init, the marking."""
    from gymnasium.utils.env_checker import check_env

    import mitlc.gym as mg

    assert set(mg.ENV_IDS) <= set(gym.registry)
    env = gym.make("mitlc/Pendulum-v0", spec="pendulum/p2_avoid")
    check_env(env.unwrapped, skip_render_check=True)
    starts = []
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        starts.append(obs["obs"].copy())
        assert env.observation_space.contains(obs)
    starts_a = np.array(starts)
    assert np.all((starts_a[:, 0] >= 2.4 - 1e-6) & (starts_a[:, 0] <= np.pi + 1e-6)) and np.all(starts_a[:, 1] == 0)
    # the reward is the runtime's, step by step, and the episode ends at the horizon (3 s / 0.03 s)
    base = env.unwrapped
    obs, _ = env.reset(seed=3)
    rt = NetRuntime(base.reward_system, dt=base.dt, steps=base.steps)
    M = rt.reset(obs["obs"][None].astype(float))
    k, done = 0, False
    while not done:
        obs, r, term, trunc, info = env.step(np.array([1.5], np.float32))
        k += 1
        M1 = rt.step(M, base._x, k * base.dt)
        assert r == float(rt.reward(M, M1)[0]) and np.array_equal(info["marking"], M1[0])
        M, done = M1, term or trunc
    assert k == 100 and not term
    nested = gym.make("mitlc/Pendulum-v0", spec="pendulum/n3_bounded_response", marking_obs="box")
    check_env(nested.unwrapped, skip_render_check=True)
    assert nested.observation_space.shape == (2 + len(nested.unwrapped.place_names) + 2,)
    with pytest.raises(InputError, match="the spec is for plant 'pendulum', not 'mass-damper'"):
        gym.make("mitlc/MassDamper-v0", spec="pendulum/p2_avoid")
    from mitlc.spec.parse import parse_spec

    text = "plant mass-damper\ninit q in [-1, -0.5], qdot = 0\nhorizon 3\nprop near = abs(q) < 0.1\nformula F G near\n"
    md = gym.make("mitlc/MassDamper-v0", spec=parse_spec(text))
    check_env(md.unwrapped, skip_render_check=True)
    with pytest.raises(MitlError, match="no 'formula'"):  # its default spec has classical criteria only
        gym.make("mitlc/MassDamper-v0")


@pytest.mark.skipif(not HAS_MONITOR, reason="mitlc.monitor is not there yet")
def test_registered_environment_gives_the_monitors_verdict() -> None:
    """info["verdict"] of mitlc/Pendulum-v0 is the monitor's on the episode's states so far (the online
    monitor per step, the offline one's whole verdict at the horizon), with the wrapper's verdict= option."""
    import mitlc.gym  # noqa: F401 - registers the environments
    from mitlc.monitor.offline import monitor

    up = parse_spec(UPRIGHT)
    env = gym.make("mitlc/Pendulum-v0", spec=up)
    base = env.unwrapped
    obs, info = env.reset(seed=4)
    states, infos, done = [base._x[0].copy()], [info], False  # noqa: SLF001 - the plant's float64 state
    while not done:  # no input: it starts inside kappa near the top and falls out
        obs, _, term, trunc, info = env.step(np.array([0.0], np.float32))
        states.append(base._x[0].copy())  # noqa: SLF001
        infos.append(info)
        done = term or trunc
    x = np.array(states)
    assert x.shape == (101, 2) and np.array_equal(base.trace, x)
    np.testing.assert_allclose(obs["obs"], x[-1], rtol=1e-6)  # the observation shows the same state
    spec = base.mitl_spec
    seen = set()
    for k in range(100):  # every prefix, from the online monitor
        res = monitor(spec, x[: k + 1], base.dt)
        assert infos[k]["verdict"] == {"satisfied": bool(res.satisfied[0]), "robustness": float(res.robustness[0])}
        seen.add(bool(res.satisfied[0]))
    assert infos[0]["verdict"]["satisfied"] is True and seen == {True, False}  # F G kappa, then not
    res = monitor(spec, x, base.dt)
    last = infos[-1]["verdict"]
    assert last["satisfied"] == bool(res.satisfied[0]) and last["robustness"] == float(res.robustness[0])
    assert last["failing"] == res.failing[0] and last["violation_time"] == float(res.violation_time[0])
    assert last["satisfied"] is False and last["failing"] == "F G kappa"

    def verdict_steps(**kw) -> list[int]:
        e = gym.make("mitlc/Pendulum-v0", spec=up, **kw)
        _, i0 = e.reset(seed=4)
        out = [0] if "verdict" in i0 else []
        for k in range(1, 101):
            if "verdict" in e.step(np.array([0.0], np.float32))[4]:
                out.append(k)
        return out

    assert verdict_steps(verdict="end") == [100] and verdict_steps(verdict="off") == []
    with pytest.raises(InputError, match="verdict must be one of step, end, off"):
        gym.make("mitlc/Pendulum-v0", spec="pendulum/p2_avoid", verdict="always")


@pytest.mark.skipif(not HAS_MONITOR, reason="mitlc.monitor is not there yet")
def test_registered_environment_pays_a_monitor_reward_by_the_monitor() -> None:
    """reward = robustness: 0 on every step, the whole trace's robustness on the last (as the wrapper)."""
    import mitlc.gym as mg

    spec = load_spec("pendulum/p2_avoid")
    env = mg.MitlPlantEnv(compile_spec(spec, CompileOptions.from_spec(spec, reward="robustness")))
    env.reset(seed=4)
    rewards, done = [], False
    while not done:
        _, r, term, trunc, info = env.step(np.array([2.5], np.float32))
        rewards.append(r)
        done = term or trunc
    assert rewards[:-1] == [0.0] * 99
    assert rewards[-1] == info["verdict"]["robustness"] < 0


def test_registered_environment_passes_sb3s_checker() -> None:
    sb3 = pytest.importorskip("stable_baselines3", reason="Stable-Baselines3 is an optional extra")
    from stable_baselines3.common.env_checker import check_env as sb3_check

    import mitlc.gym  # noqa: F401 - registers the environments

    assert sb3
    sb3_check(gym.make("mitlc/Pendulum-v0", spec="pendulum/p2_avoid").unwrapped)


def test_dt_from_where_gymnasium_keeps_it() -> None:
    """CartPole keeps its step as ``tau``; an env may also say ``metadata['dt']``; the error names all."""
    spec = parse_spec("prop right = x > 0\nformula G right")
    cart = MitlRewardWrapper(gym.make("CartPole-v1"), spec, {"x": 0})
    assert cart.dt == 0.02

    class Meta(gym.Env):
        metadata = {"dt": 0.125}
        observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
        action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    assert MitlRewardWrapper(Meta(), spec, {"x": 0}).dt == 0.125
    with pytest.raises(InputError, match=r"no 'dt' or 'tau' attribute and no metadata\['dt'\]"):
        MitlRewardWrapper(gym.make("MountainCarContinuous-v0"), spec, {"x": 0})
    assert MitlRewardWrapper(gym.make("MountainCarContinuous-v0"), spec, {"x": 0}, dt=1.0).dt == 1.0


def test_registered_environment_starts_where_asked() -> None:
    import mitlc.gym  # noqa: F401 - registers the environments

    env = gym.make("mitlc/Pendulum-v0", spec="pendulum/p2_avoid", verdict="off")
    obs, info = env.reset(seed=0, options={"x0": [0.1, -0.2]})
    assert env.unwrapped.trace[0].tolist() == [0.1, -0.2]  # as given, to the bit
    assert obs["obs"].tolist() == np.array([0.1, -0.2], np.float32).tolist() and info["marking"].tolist() == [1, 0, 0]
    env.reset(options={"x0": np.array([4.0, 0.0])})  # an angle outside [-pi, pi) is wrapped
    assert env.unwrapped.trace[0][0] == pytest.approx(4.0 - 2 * np.pi, abs=1e-15)
    for bad in ([1.0], [0.0, np.nan], "up"):
        with pytest.raises(InputError, match=r"options\['x0'\] must be 2 finite numbers \(q, qdot\), got "):
            env.reset(options={"x0": bad})


class _Feedback:
    """A stand-in for a Stable-Baselines3 model: ``predict`` is a fixed state feedback ``u = -k q - d qdot``
    read off the observation as a mitlc environment gives it (only the model's interface is used)."""

    def __init__(self, space, k: float = 2.0, d: float = 0.5) -> None:
        self.observation_space, self.k, self.d, self.calls = space, k, d, 0

    def predict(self, obs, deterministic: bool = False):
        assert deterministic
        self.calls += 1
        x = obs["obs"] if isinstance(obs, dict) else obs[:, :2]
        assert x.dtype == np.float32 and x.shape == (1, 2)  # one row at a time, as the env shows it
        return (-(self.k * x[:, :1] + self.d * x[:, 1:2])).astype(np.float32), None


@pytest.mark.parametrize("marking_obs", ["dict", "box"])
def test_sb3policy_rolls_out_what_the_environment_does(marking_obs: str) -> None:
    """Sb3Policy with any object that has a model's observation_space and predict: its rollouts are the
    registered environment's episodes from the same starts, states, inputs and rewards to the bit,
    nested intervals' clocks included."""
    import mitlc.gym as mg

    spec = "pendulum/n3_bounded_response"
    env = gym.make("mitlc/Pendulum-v0", spec=spec, marking_obs=marking_obs, verdict="end")
    model = _Feedback(env.observation_space, k=3.0)
    pol = mg.Sb3Policy(model, spec)
    assert pol.n_clocks == 2 and pol.marking_obs == marking_obs and pol.runs == 1
    x0 = np.array([[0.2, 0.0], [-1.0, 2.0], [2.9, -1.0]])
    ro = pol.rollout(x0)
    assert model.calls == 3 * pol.n_steps
    for b in range(3):
        obs, _ = env.reset(options={"x0": x0[b]})
        us, rewards, done = [], [], False
        while not done:
            a, _ = model.predict(obs[None] if marking_obs == "box" else {k: v[None] for k, v in obs.items()}, True)
            obs, r, term, trunc, info = env.step(a[0])
            us.append(float(np.clip(a[0, 0], -pol.u_max, pol.u_max)))
            rewards.append(r)
            done = term or trunc
        np.testing.assert_array_equal(ro.states[b], env.unwrapped.trace)
        np.testing.assert_array_equal(ro.actions[b], us)
        np.testing.assert_array_equal(ro.rewards[b], rewards)
        if HAS_MONITOR:
            from mitlc.monitor.offline import monitor

            assert info["verdict"]["satisfied"] == bool(monitor(pol.spec, ro.states[b], ro.dt).satisfied[0])


def test_sb3policy_refuses_what_it_cannot_roll_out() -> None:
    import mitlc.gym as mg

    env = gym.make("mitlc/Pendulum-v0", spec="pendulum/p2_avoid", marking_obs="box")
    with pytest.raises(InputError, match="the model observes 5 numbers, and the plant's 2 with the marking make 4"):
        mg.Sb3Policy(_Feedback(env.observation_space), "pendulum/p1_swing_up")
    d = gym.make("mitlc/Pendulum-v0", spec="pendulum/p2_avoid")
    with pytest.raises(InputError, match="the model observes 3 marking entries and 0 clocks, the spec's net has 2"):
        mg.Sb3Policy(_Feedback(d.observation_space), "pendulum/p1_swing_up")
    with pytest.raises(InputError, match="is not one a mitlc environment gives"):
        mg.Sb3Policy(_Feedback(gym.spaces.Discrete(3)), "pendulum/p1_swing_up")
    gym_spec = parse_spec(
        "plant gym:Pendulum-v1\nstate q = atan2(obs[1], obs[0]), w = obs[2]\nhorizon 1\n"
        "prop up = abs(q) < 0.5\nformula F G up\n"
    )
    with pytest.raises(InputError, match="is for plant gym:Pendulum-v1, a Gymnasium environment: an SB3 model"):
        mg.Sb3Policy(_Feedback(env.observation_space), gym_spec)
    # a wrapper of another observation: obs_of maps the plant's states to it
    obs_of = lambda x: np.stack([np.cos(x[:, 0]), np.sin(x[:, 0]), x[:, 1]], axis=1)  # noqa: E731
    space = gym.spaces.Box(-np.inf, np.inf, (3 + 2,), np.float32)
    pol = mg.Sb3Policy(_Feedback(space), "pendulum/p1_swing_up", obs_of=obs_of)
    o = pol.observation(np.array([[np.pi / 2, 1.0]]), np.array([[0, 1]]))
    np.testing.assert_allclose(o, [[0.0, 1.0, 1.0, 0.0, 1.0]], atol=1e-7)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_pendulum_reader_reads_each_observation_as_the_batch_does(dtype) -> None:
    """The wrapper's Pendulum-v1 reader (numpy's arctan2 on arrays of one it keeps) gives, bit for bit, the
    angle pendulum_v1_state finds for the whole batch at once, wrapped as the reader wraps a periodic
    variable, and the speed as it is, on 20,000 observations over every angle."""
    from gymnasium import spaces

    from mitlc.gym.observation import state_reader

    rng = np.random.default_rng(7)
    theta = rng.uniform(-4.0, 4.0, 20_000)
    obs = np.stack([np.cos(theta), np.sin(theta), rng.uniform(-8.0, 8.0, theta.size)], axis=1).astype(dtype)
    space = spaces.Box(-8.0, 8.0, (3,), dtype)
    read = state_reader(pendulum_v1_state, space, ["q", "qdot"], ["q", "qdot"], np.array([True, False]))
    got = np.array([read(o) for o in obs])
    batch = pendulum_v1_state(obs)
    q = (batch["q"] + math.pi) % (2 * math.pi) - math.pi  # the reader's wrap of a periodic variable
    assert got[:, 0].tobytes() == q.tobytes()
    assert got[:, 1].tobytes() == batch["qdot"].astype(float).tobytes()


def test_a_dict_observations_marking_is_the_info_marking() -> None:
    """One copy of the marking a step: the observation's and info's are the same array, equal to the marking."""
    env = wrapped(verdict="off", truncate_at_horizon=True)
    env.reset(seed=0)
    obs, _, _, _, info = env.step(np.array([0.5], dtype=np.float32))
    assert obs["marking"] is info["marking"]
    np.testing.assert_array_equal(obs["marking"], env.marking)
