"""The numpy twins of Pendulum-v1 and MountainCarContinuous-v0 (mitlc.plants.gym_twins): the environment's
own numbers to the bit, used by the trainers' copies only where they agree, and the policy search on an
environment (candidates of a run reset with the same seeds)."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from mitlc.learn.search import SearchRuns, SearchSettings  # noqa: E402
from mitlc.monitor.offline import monitor  # noqa: E402
from mitlc.petri.compile import compile_spec  # noqa: E402
from mitlc.plants import gym_twins  # noqa: E402
from mitlc.plants.gym_twins import MountainCarTwin, PendulumTwin, compare, twin_for  # noqa: E402
from mitlc.spec.parse import parse_spec  # noqa: E402

MC = """
plant gym:MountainCarContinuous-v0(dt = 1)
state x = obs[0], v = obs[1]
init x in [-0.6, -0.4], v = 0
horizon 200
prop left = x < -0.8
prop goal = x >= 0.45
formula F[0,50] (left & F[0,100] G goal)
"""

PEND = """
plant gym:Pendulum-v1
state q = atan2(obs[1], obs[0]), w = obs[2]
init q in [-pi, pi], w in [-1, 1]
horizon 3
prop up = abs(q) < 0.3
formula F[0,2] up
"""


@pytest.mark.parametrize(
    "env_id, kwargs",
    [
        ("Pendulum-v1", {}),
        ("Pendulum-v1", {"g": 9.81}),
        ("MountainCarContinuous-v0", {}),
        ("MountainCarContinuous-v0", {"goal_velocity": 0.01}),
    ],
)
def test_twin_gives_the_environments_numbers_to_the_bit(env_id, kwargs):
    ok, ends = compare(env_id, kwargs, steps=1500, copies=9)
    assert ok
    if env_id.startswith("Mountain"):
        assert ends > 10  # the goal (termination, a reset, the twin reading the new state) was reached


def test_the_mountain_cars_wall_and_speed_limit_are_exercised():
    """The branches the comparison must cover: the velocity clipped at 0.07, the car stopped at the wall."""
    env = gym.make("MountainCarContinuous-v0", disable_env_checker=True, max_episode_steps=10**9)
    env.reset(seed=0)
    twin = MountainCarTwin(env.unwrapped, 1)
    twin.load([env])
    speeds, wall = [], 0
    for _ in range(600):
        a = np.array([[1.0 if twin.vel[0] >= 0 else -1.0]], dtype=np.float32)
        obs, _ = twin.step(a)
        o, *_ = env.step(a[0])
        assert np.array_equal(o, obs[0])
        speeds.append(abs(float(obs[0, 1])))
        wall += float(obs[0, 0]) == float(np.float32(-1.2))
    assert max(speeds) == pytest.approx(0.07) and wall > 0


def test_twins_only_for_the_environments_they_reproduce():
    vec = gym.make_vec("Pendulum-v1", num_envs=2, vectorization_mode="sync")
    assert isinstance(twin_for("Pendulum-v1", {}, vec), PendulumTwin)
    other = gym.make_vec("Acrobot-v1", num_envs=2, vectorization_mode="sync")
    assert twin_for("Acrobot-v1", {}, other) is None
    # an id with a twin whose environment is another class (registered by a user over it): no twin
    assert twin_for("Pendulum-v1", {}, other) is None


def test_a_twin_that_disagrees_is_not_used(monkeypatch):
    class Off(PendulumTwin):
        def step(self, action):
            obs, term = super().step(action)
            obs[:, 2] += np.float32(1e-3)
            return obs, term

    monkeypatch.setitem(gym_twins.TWINS, "Pendulum-v1", Off)
    monkeypatch.setattr(gym_twins, "_CHECKED", {})
    vec = gym.make_vec("Pendulum-v1", num_envs=2, vectorization_mode="sync")
    assert not compare("Pendulum-v1", {}, steps=5)[0]
    assert twin_for("Pendulum-v1", {}, vec) is None


def _twin_in_the_kernel(env_id, twin_cls, B, compiled):
    """``B`` seeded copies of ``env_id``, their twin, and its kernel physics (compiled by numba or plain)."""
    from mitlc.learn.sacpn import kernel as fk

    if compiled:
        pytest.importorskip("numba")
    jit = fk.jit if compiled else fk.identity
    envs = [gym.make(env_id, disable_env_checker=True) for _ in range(B)]
    for b, env in enumerate(envs):
        env.reset(seed=b)
    twin = twin_cls(envs[0].unwrapped, B)
    twin.load(envs)
    physics, consts, h, k = twin.kernel_physics(jit)
    return envs, twin, (jit(physics), consts, h, k)


@pytest.mark.parametrize("compiled", [False, True])
def test_the_pendulum_twins_kernel_physics_is_its_step(compiled):
    """What SACPN's fused kernel steps a copy by (PendulumTwin.kernel_physics, one copy at a time, plain
    Python or compiled by numba) gives the twin's numbers to the bit: actions beyond the torque's bounds,
    and pumping that reaches the speed limit."""
    B = 6
    _, twin, (physics, consts, h, k) = _twin_in_the_kernel("Pendulum-v1", PendulumTwin, B, compiled)
    states = twin.hidden()
    assert states.shape == (B, h) == (B, 2)
    obs_k = np.empty(k)
    rng = np.random.default_rng(4)
    fastest = 0.0
    for step in range(400):
        a = rng.uniform(-3.0, 3.0, size=(B, 1))
        a[::2, 0] = np.where(states[::2, 1] >= 0, 2.5, -2.5)  # pump
        a = a.astype(np.float32)
        obs, _ = twin.step(a)
        for b in range(B):
            physics(states[b], a[b, 0], consts, obs_k)
            assert np.array_equal(obs_k, obs[b].astype(float)), (step, b)
        assert np.array_equal(states, twin.hidden())
        fastest = max(fastest, float(np.abs(states[:, 1]).max()))
    assert fastest == twin.max_speed  # the clip was exercised


@pytest.mark.parametrize("compiled", [False, True])
def test_the_mountain_cars_kernel_physics_is_its_step(compiled):
    """MountainCarTwin.kernel_physics one copy at a time (plain Python or compiled): the twin's numbers to
    the bit from float64 states just reset and float32 ones after, with actions inside, on and beyond the
    bounds, pumping that reaches the goal, the top of the hill and the speed limit, and pushing into the
    wall; a copy that terminates is stepped no more until it is reset (or told to go on, as the twin does)."""
    B = 9
    envs, twin, (physics, consts, h, k) = _twin_in_the_kernel("MountainCarContinuous-v0", MountainCarTwin, B, compiled)
    states = twin.hidden()
    assert states.shape == (B, h) == (B, 4) and (states[:, 2] == 1.0).all()
    o = np.empty(k)
    rng = np.random.default_rng(5)
    ends = walls = tops = 0
    fastest = 0.0
    for step in range(1500):
        a = rng.uniform(-1.5, 1.5, size=(B, 1))
        kind = np.arange(B) % 3
        pump = np.where(states[:, 1] >= 0, 1.0, -1.0) * (1.2 if step % 2 else 1.0)
        push = np.full(B, 1.0 if step % 7 == 0 else -1.0)
        a[:, 0] = np.where(kind == 1, pump, np.where(kind == 2, push, a[:, 0]))
        a = a.astype(np.float32)
        obs, term = twin.step(a)
        for b in range(B):
            assert physics(states[b], a[b, 0], consts, o)
            assert np.array_equal(o, obs[b].astype(float)) and bool(states[b, 3]) == bool(term[b]), (step, b)
            if term[b]:
                before = states[b].copy()
                assert not physics(states[b], a[b, 0], consts, o)  # ended: not stepped
                assert np.array_equal(states[b], before)
                ends += 1
                if b % 2:  # on past the goal, as the twin goes (the top of the hill, the speed limit)
                    states[b, 3] = 0.0
                    continue
                envs[b].reset(seed=1000 * b + step)
                twin.load(envs, np.arange(B) == b)
                states[b] = twin.hidden()[b]
        assert np.array_equal(states[:, :2], np.stack([twin.pos, twin.vel], axis=1))
        walls += int((obs[:, 0] == np.float32(-1.2)).sum())
        tops += int((obs[:, 0] == np.float32(0.6)).sum())
        fastest = max(fastest, float(np.abs(obs[:, 1]).max()))
    assert ends > 10 and walls > 0 and tops > 0 and fastest == pytest.approx(0.07)


@pytest.mark.parametrize("text", [MC, PEND])
def test_the_kernels_step_is_the_simulators(text):
    """kernel.env_step (the twin's physics, the spec's reads of the observation) one copy at a time against
    GymSimulator.step on all copies, from the same resets, with pumping actions beyond the bounds: the same
    states to the bit, a mountain car that reaches its goal keeping its state to the end."""
    from mitlc.learn.sacpn import kernel as fk
    from mitlc.runtime.atoms import compile_observe

    spec = parse_spec(text)
    plant = spec.plant
    sim = plant.simulator(plant.params(), {r.var: (r.lo, r.hi) for r in spec.init})
    B = 6
    x = sim.reset([np.random.default_rng(s) for s in range(B)])
    physics, consts, h, k = sim.kernel_step(B)
    obs = plant.observation
    observe = compile_observe(
        [o.expr for o in obs], {f"obs[{j}]": j for j in range(k)}, [o.var.periodic for o in obs], fk.identity
    )
    step = fk.env_step(physics, observe, len(obs), fk.identity)
    xk = sim.kernel_states(x)
    w = np.empty(k)
    u_max = consts[0]
    for i in range(300):
        u = np.where(x[:, 1] >= 0, 1.3, -1.3) * u_max * (1 + 0.1 * (i % 3))
        sim.step(x, u)
        for b in range(B):
            step(xk[b], u[b], consts, w)
        assert np.array_equal(xk[:, : len(obs)], x), i
    if text is MC:
        assert sim._done[B].all()  # every copy reached the goal and kept its state


def test_the_simulator_gives_the_kernel_its_twins_parts():
    sim = parse_spec(PEND).plant.simulator(parse_spec(PEND).plant.params(), {})
    physics, consts, h, k = sim.kernel_step(3)
    assert (h, k) == (2, 3) and consts[0] == 2.0  # the torque bound first, then the twin's
    spec = parse_spec(MC)
    sim = spec.plant.simulator(spec.plant.params(), {})
    physics, consts, h, k = sim.kernel_step(3)
    assert (h, k) == (4, 2) and consts[0] == 1.0


def test_the_simulator_keeps_an_action_per_batch_size():
    """Copies of two batch sizes stepped in turn (a loaded policy's kernel check builds its runs' batch,
    then mitlc simulate resets fewer): each batch steps with its own actions, as a simulator of its own."""
    spec = parse_spec(PEND)
    sims = [spec.plant.simulator(spec.plant.params(), {}) for _ in range(3)]
    both = sims[0]
    x4 = both.reset([np.random.default_rng(s) for s in range(4)])
    x2 = both.reset([np.random.default_rng(s) for s in range(2)])
    y4 = sims[1].reset([np.random.default_rng(s) for s in range(4)])
    y2 = sims[2].reset([np.random.default_rng(s) for s in range(2)])
    for k in range(5):
        both.step(x4, np.full(4, 0.3 * k))
        both.step(x2, np.full(2, -0.5))
        sims[1].step(y4, np.full(4, 0.3 * k))
        sims[2].step(y2, np.full(2, -0.5))
    np.testing.assert_array_equal(x4, y4)
    np.testing.assert_array_equal(x2, y2)


def _rollout(spec, seeds, steps):
    sim = spec.plant.simulator(spec.plant.params(), {r.var: (r.lo, r.hi) for r in spec.init})
    x = sim.reset([np.random.default_rng(s) for s in seeds])
    out = [x.copy()]
    for k in range(steps):
        sim.step(x, np.where(x[:, 1] >= 0, 1.0, -1.0) * (0.5 + 0.1 * (k % 5)))
        out.append(x.copy())
    return np.stack(out), sim


@pytest.mark.parametrize("text", [MC, PEND])
def test_the_simulator_gives_the_same_states_with_and_without_the_twin(monkeypatch, text):
    spec = parse_spec(text)
    fast, sim = _rollout(spec, range(6), 120)
    assert any(t is not None for t in sim._twins.values())
    monkeypatch.setattr(gym_twins, "TWINS", {})
    slow, sim = _rollout(spec, range(6), 120)
    assert all(t is None for t in sim._twins.values())
    np.testing.assert_array_equal(fast, slow)


def _judge(spec):
    return lambda states, dt, mean=False: monitor(spec, states, dt, spec.monitor_formula, blame=False, mean=mean)


def test_the_search_runs_on_an_environment_with_one_start_per_seed():
    spec = parse_spec(MC)
    rs = compile_spec(spec)
    search = SearchRuns(rs, 2, seed=3, settings=SearchSettings(popsize=4, starts=2), judge=_judge(spec))
    rngs = [np.random.default_rng([3, r, 0]) for r in range(2)]
    x = search._starts(rngs, 4, 2)  # (R * P * S, n): run r's S starts, the same for its P candidates
    x = x.reshape(2, 4, 2, -1)
    for r in range(2):
        for p in range(4):
            np.testing.assert_array_equal(x[r, p], x[r, 0])
    assert not np.array_equal(x[0, 0, 0], x[0, 0, 1]) and not np.array_equal(x[0, 0], x[1, 0])
    assert np.all((x[..., 0] >= -0.6) & (x[..., 0] <= -0.4)) and np.all(x[..., 1] == 0)


def test_the_search_learns_the_mountain_cars_left_hill_first():
    """The check half's gym_mountain_car_left_first (0.32 with SACPN's designs, docs/suite.md record 21):
    the linear search learns it; the same seed gives the same gains."""
    spec = parse_spec(MC)
    rs = compile_spec(spec)
    a = SearchRuns(rs, 4, seed=0, judge=_judge(spec))
    a.train(25)
    ro = a.rollout(a.evaluation_states())
    ok = monitor(spec, ro.states, ro.dt).satisfied
    assert ok.sum() >= 3
    b = SearchRuns(rs, 4, seed=0, judge=_judge(spec))
    b.train(25)
    np.testing.assert_array_equal(a.weights, b.weights)
