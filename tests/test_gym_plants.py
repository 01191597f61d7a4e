"""Gymnasium environments as plants: 'plant gym:ID' with 'state' lines, stepped by SACPN."""

from __future__ import annotations

import json

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from click.testing import CliRunner  # noqa: E402

from mitlc.cli import main  # noqa: E402
from mitlc.errors import MitlError, SpecError, TrainingError  # noqa: E402
from mitlc.gym import MitlRewardWrapper  # noqa: E402
from mitlc.learn.sacpn import Sacpn, SacpnSettings  # noqa: E402
from mitlc.petri.compile import compile_spec  # noqa: E402
from mitlc.spec.library import find  # noqa: E402
from mitlc.spec.parse import load_spec, parse_spec  # noqa: E402

MC = """
plant gym:MountainCarContinuous-v0(dt = 1)
state x = obs[0], v = obs[1]
horizon 200
prop goal = x >= 0.45
formula F[0,150] G goal
"""


def test_state_lines_make_the_plant():
    spec = parse_spec(MC)
    p = spec.plant
    assert p is not None and p.name == "gym:MountainCarContinuous-v0" and p.stepped
    assert [(v.name, v.lo, v.hi, v.periodic) for v in p.state] == [
        ("x", -1.2, 0.6, False),
        ("v", -0.07, 0.07, False),
    ]
    assert p.defaults == {"dt": 1.0, "u_max": 1.0}
    assert spec.param("dt") == 1.0


def test_pendulum_v1_angle_and_the_environment_dt():
    spec = parse_spec(
        "plant gym:Pendulum-v1\nstate q = atan2(obs[1], obs[0]), w = obs[2]\nhorizon 1\n"
        "prop up = abs(q) < 0.5\nformula F G up\n"
    )
    q, w = spec.plant.state
    assert q.periodic and (q.lo, q.hi) == (-np.pi, np.pi)
    assert not w.periodic and (w.lo, w.hi) == (-8.0, 8.0)
    assert spec.param("dt") == 0.05  # Pendulum-v1's own dt
    assert spec.plant.defaults["u_max"] == 2.0
    # the mapping itself: the angle read off [cos, sin, w]
    flat = np.array([[np.cos(2.0), np.sin(2.0), 0.3], [np.cos(-0.1), np.sin(-0.1), -1.0]])
    assert np.allclose([o.read(flat) for o in spec.plant.observation], [[2.0, -0.1], [0.3, -1.0]])


def test_an_expression_needs_its_range_and_parameters_reach_make():
    spec = parse_spec(
        "plant gym:Pendulum-v1(g = 5)\nstate h = obs[0] + 1 in [0, 2], w = obs[2]\nprop up = h > 1.9\nformula F up\n"
    )
    assert spec.plant.var("h").lo == 0.0 and spec.plant_params == (("g", 5.0), ("dt", 0.05))
    sim = spec.plant.simulator(spec.plant.params(dict(spec.plant_params)))
    sim.reset([np.random.default_rng(0)])
    assert sim._envs[1].envs[0].unwrapped.g == 5  # integral values go to gymnasium.make as int


@pytest.mark.parametrize(
    "text, message",
    [
        ("plant gym:NoSuchEnv-v9\nstate x = obs[0]\nprop a = x < 1\nformula F a", "Gymnasium has no environment"),
        ("plant gym:MountainCarContinuous-v0\nstate x = obs[0]\nprop a = x < 1\nformula F a", "dt = ..."),
        ("plant gym:Pendulum-v1\nprop a = x < 1\nformula F a", "needs its state variables mapped"),
        ("plant gym:Pendulum-v1\nstate x = obs[3]\nprop a = x < 1\nformula F a", "outside the observation"),
        ("plant gym:Pendulum-v1\nstate x = obs[0]\nprop a = y < 1\nformula F a", "unknown state variable 'y'"),
        ("plant gym:Pendulum-v1\nstate x = obs[0]\nprop a = obs[0] < 1\nformula F a", "only in a 'state' line"),
        ("plant gym:Pendulum-v1\nstate x = 2 * obs[0]\nprop a = x < 1\nformula F a", "give the range of 'x'"),
        ("plant gym:Pendulum-v1\nstate x = q\nprop a = x < 1\nformula F a", "write obs[i]"),
        ("plant gym:Pendulum-v1\nstate x = obs[0], x = obs[1]\nprop a = x < 1\nformula F a", "mapped twice"),
        ("plant gym:Pendulum-v1(zz = 1)\nstate x = obs[0]\nprop a = x < 1\nformula F a", "does not take"),
        ("plant pendulum\nstate x = obs[0]\nprop a = q < 1\nformula F a", "declares its own state"),
    ],
)
def test_bad_gym_specs_are_one_located_error(text, message):
    with pytest.raises(SpecError) as err:
        parse_spec(text, "s.mitl")
    assert message in err.value.message
    assert err.value.headline().startswith("s.mitl:") and "\n" not in err.value.headline()


def test_cli_errors_exit_2_with_one_line(tmp_path):
    runner = CliRunner()
    bad = tmp_path / "cart.mitl"
    bad.write_text("plant gym:CartPole-v1\nstate th = obs[2]\nhorizon 2\nprop up = abs(th) < 0.2\nformula G up\n")
    r = runner.invoke(main, ["train", "--spec", str(bad), "--runs", "1", "--trials", "1", "--out", str(tmp_path / "o")])
    assert r.exit_code == 2
    assert "Discrete(2), not continuous" in r.output and "Traceback" not in r.output
    assert r.output.strip().splitlines()[0].startswith(f"{bad}: error:")
    unmapped = tmp_path / "u.mitl"
    unmapped.write_text("plant gym:Pendulum-v1\nstate q = atan2(obs[1], obs[0])\nprop a = abs(w) < 1\nformula F a\n")
    r = runner.invoke(main, ["compile", str(unmapped)])
    assert r.exit_code == 2 and f"{unmapped}:3:14: error: unknown state variable 'w'" in r.output
    assert "state w = obs[i]" in r.output


def test_simulator_agrees_with_the_environment_stepped_by_hand():
    spec = parse_spec(MC)
    sim = spec.plant.simulator(spec.plant.params())
    rngs = [np.random.default_rng(s) for s in (3, 4)]
    x = sim.reset(rngs)
    seeds = [int(np.random.default_rng(s).integers(2**31)) for s in (3, 4)]
    u = np.array([0.7, -0.4])
    for _ in range(5):
        sim.step(x, u)
    for b, seed in enumerate(seeds):  # the independent reading: one env, the same seed and inputs
        env = gym.make("MountainCarContinuous-v0")
        obs, _ = env.reset(seed=seed)
        for _ in range(5):
            obs, *_ = env.step(np.array([u[b]], dtype=np.float32))
        np.testing.assert_array_equal(x[b], obs)  # the twin steps it: the same float32 numbers


def test_a_run_start_does_not_depend_on_how_many_runs():
    spec = parse_spec(MC)
    one = spec.plant.simulator(spec.plant.params()).reset([np.random.default_rng(7)])
    three = spec.plant.simulator(spec.plant.params()).reset([np.random.default_rng(s) for s in (7, 8, 9)])
    np.testing.assert_array_equal(one[0], three[0])


def test_init_selects_among_the_environment_starts():
    spec = parse_spec(MC.replace("horizon 200", "init x in [-0.5, -0.45], v = 0\nhorizon 200"))
    sim = spec.plant.simulator(spec.plant.params(), {r.var: (r.lo, r.hi) for r in spec.init})
    x = sim.reset([np.random.default_rng(s) for s in range(20)])
    assert np.all((x[:, 0] >= -0.5) & (x[:, 0] <= -0.45)) and np.all(x[:, 1] == 0)
    # the env's own starts are x in [-0.6, -0.4]: about three in four are redrawn, and some were
    plain = parse_spec(MC).plant.simulator(spec.plant.params()).reset([np.random.default_rng(s) for s in range(20)])
    assert np.any(plain[:, 0] < -0.5)
    impossible = {"x": (0.5, 0.55)}  # the environment never starts on the hill
    with pytest.raises(TrainingError, match="did not start inside the spec's init"):
        spec.plant.simulator(spec.plant.params(), impossible).reset([np.random.default_rng(0)])
    # the wrapper conditions its resets the same way, reproducibly from the seed
    env = MitlRewardWrapper(gym.make("MountainCarContinuous-v0"), spec)
    starts = [env.reset(seed=s)[0]["obs"][0] for s in range(10)]
    assert all(-0.5 <= s <= -0.45 for s in starts)
    assert env.reset(seed=3)[0]["obs"][0] == starts[3]


def test_a_terminated_copy_keeps_its_last_state():
    spec = parse_spec(MC)
    sim = spec.plant.simulator(spec.plant.params())
    x = sim.reset([np.random.default_rng(0), np.random.default_rng(1)])
    reached = None
    for k in range(400):  # energy pumping: push along the velocity
        u = np.where(x[:, 1] >= 0, 1.0, -1.0)
        before = x.copy()
        sim.step(x, u)
        if reached is None and np.all(x[:, 0] >= 0.45):
            reached = k
        if reached is not None and k > reached + 3:
            np.testing.assert_array_equal(x, before)  # the episodes ended: the states hold
    assert reached is not None


def test_rollouts_start_where_the_reset_left_the_copies():
    rs = compile_spec(parse_spec(MC))
    agent = Sacpn(rs, runs=2, seed=0)
    with pytest.raises(TrainingError, match="cannot be set to a given state"):
        agent.rollout(np.array([[-0.5, 0.0], [-0.5, 0.0]]))
    ro = agent.rollout(agent.evaluation_states())
    assert ro.states.shape == (2, 201, 2)


def test_sacpn_is_deterministic_on_an_environment():
    rs = compile_spec(parse_spec(MC))
    a = Sacpn(rs, SacpnSettings(gamma=0.99), runs=2, seed=5)
    b = Sacpn(rs, SacpnSettings(gamma=0.99), runs=2, seed=5)
    np.testing.assert_array_equal(a.train(3), b.train(3))
    np.testing.assert_array_equal(a.xi, b.xi)


def test_hyrl_refuses_an_environment():
    from mitlc.learn.hyrl import HybridLearner

    spec = parse_spec("plant gym:Pendulum-v1\nstate q = obs[0], qdot = obs[2]\nrequire overshoot <= 0.1\n")
    with pytest.raises(MitlError, match="can only be reset and stepped"):
        HybridLearner(spec)


def test_mountain_car_learns_from_the_cli(tmp_path):
    """The shipped timed reach trains with SACPN from the command line, with docs/gymnasium.md's settings
    (Table 4-4's and gamma 0.99: 4 runs x 300 trials is too few for the defaults' race to choose well)."""
    out = tmp_path / "mc"
    r = CliRunner().invoke(
        main,
        ["train", "--spec", "gym/mountain_car_reach", "--runs", "4", "--trials", "300", "--preset", "thesis"]
        + ["--set", "gamma=0.99"]
        + ["--seed", "0", "--out", str(out), "--no-plots"],
    )
    assert r.exit_code == 0, r.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["success_rate"] >= 0.75
    trace = tmp_path / "ro.csv"
    r = CliRunner().invoke(main, ["simulate", "--policy", str(out), "--trace", str(trace), "--rollouts", "2"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["check", "gym/mountain_car_reach", str(tmp_path / "ro_000.csv")])
    assert r.exit_code in (0, 1) and "Traceback" not in r.output


def test_shipped_gym_specs_parse():
    for name in ("gym/mountain_car_reach", "gym/pendulum_v1_swing_up"):
        spec = load_spec(str(find(name).path))
        assert spec.plant is not None and spec.plant.stepped
