"""Plants with several inputs: the protocol (InputVar, boxes, refusals), the unicycle, SACPN with
an actor output per input (saturation, checkpoints, policies), the Gymnasium side and HyRL's refusal.

The fused kernel's bit-equality on two inputs is in tests/test_kernel.py, with the others."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli.main import main
from mitlc.errors import InputError, SpecError, TrainingError
from mitlc.learn.policy import load_policy, load_sacpn
from mitlc.learn.sacpn import Sacpn, SacpnSettings, read_meta
from mitlc.petri.compile import compile_spec
from mitlc.plants import PLANTS, InputVar, Plant, StateVar, make_integrator
from mitlc.spec.parse import load_spec, parse_spec

ROOT = Path(__file__).resolve().parent.parent
UNICYCLE = PLANTS["unicycle"]

REACH = """plant unicycle
init x in [-1.2, -0.8], y in [-0.2, 0.2], theta in [-pi/4, pi/4]
horizon 2
prop goal = (x - 1) * (x - 1) + y * y < 0.25
prop rock = x * x + (y - 0.7) * (y - 0.7) < 0.16
formula F G goal & 10 * G !rock
"""


def run(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="mitlc")


def one_error(r) -> str:
    """The one line of a refused command: exit 2, no traceback."""
    assert r.exit_code == 2, (r.exit_code, r.output)
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    assert "Traceback" not in r.output
    return r.stderr.rstrip("\n").splitlines()[0]


pytestmark = pytest.mark.usefixtures("forget_user_plants")  # tests/conftest.py


def _plant(**kw) -> Plant:
    args = {
        "name": "rover",
        "state": (StateVar("x", -2.0, 2.0), StateVar("y", -2.0, 2.0)),
        "defaults": {"dt": 0.1},
        "dynamics": lambda x, u, p: u.astype(float),
        "inputs": (InputVar("vx", -1.0, 1.0), InputVar("vy", -0.5, 2.0)),
    }
    return Plant(**{**args, **kw})


# ---------------------------------------------------------------- the protocol


def test_a_plant_without_inputs_has_one_input_u_bounded_by_u_max() -> None:
    p = PLANTS["pendulum"]
    assert p.inputs is None and p.input_names == ("u",) and p.n_inputs == 1
    lo, hi = p.input_box(p.params({"u_max": 10.0}))  # a spec's plant pendulum(u_max = 10)
    assert lo.tolist() == [-10.0] and hi.tolist() == [10.0]
    assert [b.tolist() for b in p.input_box()] == [[-3.0], [3.0]]  # its default


def test_declared_inputs_are_input_vars_in_order() -> None:
    p = _plant(inputs=(("vx", -1, 1), InputVar("vy", -0.5, 2.0)))  # a tuple (name, lo, hi) will do
    assert p.inputs == (InputVar("vx", -1.0, 1.0), InputVar("vy", -0.5, 2.0))
    assert p.input_names == ("vx", "vy") and p.n_inputs == 2
    lo, hi = p.input_box()
    assert lo.tolist() == [-1.0, -0.5] and hi.tolist() == [1.0, 2.0]


WHERE = "plant 'rover'"


@pytest.mark.parametrize(
    "kw,message",
    [
        ({"inputs": ()}, f"{WHERE}: inputs is empty: a plant needs at least one input (leave inputs out for one "
         "input u bounded by the parameter u_max)"),
        ({"inputs": (("vx", -1.0),)}, f"{WHERE}: input 1 must be InputVar(name, lo, hi) or (name, lo, hi), "
         "got 2 entries"),
        ({"inputs": (("vx", -1.0, 1.0), ("vy", 0.0, 1.0, 2.0))}, f"{WHERE}: input 2 must be InputVar(name, lo, hi) "
         "or (name, lo, hi), got 4 entries"),
        ({"inputs": (("vx", 1.0, -1.0),)}, f"{WHERE}: input 'vx': its box must be finite numbers with lo < hi, "
         "got [1, -1]"),
        ({"inputs": (("vx", 1.0, 1.0),)}, f"{WHERE}: input 'vx': its box must be finite numbers with lo < hi, "
         "got [1, 1]"),
        ({"inputs": (("vx", 0.0, math.inf),)}, f"{WHERE}: input 'vx': its box must be finite numbers with lo < hi, "
         "got [0, inf]"),
        ({"inputs": (("vx", -1, 1), ("vx", -2, 2))}, f"{WHERE}: input 'vx' is given twice"),
        ({"inputs": "vx"}, f"{WHERE}: inputs must be a sequence of InputVar (or (name, lo, hi)), got 'vx'"),
        ({"defaults": {"dt": 0.1, "u_max": 2.0}}, f"{WHERE}: it declares its inputs (vx, vy), each with its box, "
         "and a parameter 'u_max', which would bound nothing: drop u_max from defaults"),
    ],
)  # fmt: skip
def test_bad_inputs_are_refused_when_the_plant_is_built(kw, message) -> None:
    with pytest.raises(ValueError) as err:
        _plant(**kw)
    assert str(err.value) == message


def test_an_input_var_checks_its_name_and_box() -> None:
    with pytest.raises(ValueError, match=r"^an input's name must be a name such as 'v' or 'omega', got '2v'$"):
        InputVar("2v", -1.0, 1.0)
    with pytest.raises(ValueError, match=r"^input 'v': its box must be finite numbers with lo < hi, got \[nan, 1\]$"):
        InputVar("v", math.nan, 1.0)


def test_step_clips_each_input_to_its_box_and_checks_the_shape() -> None:
    p = _plant()
    x = np.zeros((2, 2))
    y = p.step(x.copy(), np.array([[5.0, -5.0], [0.5, 1.0]]), p.params())
    assert y.tolist() == [[0.1, -0.05], [0.05, 0.1]]  # (1, -0.5) and (0.5, 1) for 0.1 s
    with pytest.raises(InputError, match=r"u has shape \(2,\), expected \(2, 2\) \(inputs: vx, vy\)"):
        p.step(x.copy(), np.array([0.5, 1.0]), p.params())


def test_one_declared_input_gets_u_as_a_row_with_its_own_box() -> None:
    seen = []

    def dynamics(x, u, p):
        seen.append(u.shape)
        return np.stack([u, -u], axis=1)

    p = _plant(state=(StateVar("x", -2.0, 2.0), StateVar("y", -2.0, 2.0)), dynamics=dynamics,
               inputs=(("f", 0.0, 3.0),))  # fmt: skip
    y = p.step(np.zeros((3, 2)), np.array([-1.0, 1.0, 9.0]), p.params())
    assert seen[0] == (3,) and y[:, 0].tolist() == pytest.approx([0.0, 0.1, 0.3], abs=1e-15)


# ---------------------------------------------------------------- the unicycle


def test_the_unicycle_step_is_the_hand_computed_rk4() -> None:
    """RK4 of xdot = v cos(theta), ydot = v sin(theta), thetadot = omega: theta is linear in time, so
    the stages are Simpson's rule, x1 = x0 + dt/6 v (cos t0 + 4 cos(t0 + omega dt/2) + cos(t0 + omega dt))."""
    p = UNICYCLE.params()
    dt = p["dt"]
    x0, y0, t0, v, w = 0.3, -0.4, 1.0, 0.7, -1.5
    got = UNICYCLE.step(np.array([[x0, y0, t0]]), np.array([[v, w]]), p)[0]
    mid, end = t0 + w * dt / 2, t0 + w * dt
    want = [
        x0 + dt / 6 * v * (math.cos(t0) + 4 * math.cos(mid) + math.cos(end)),
        y0 + dt / 6 * v * (math.sin(t0) + 4 * math.sin(mid) + math.sin(end)),
        t0 + w * dt,
    ]
    assert got.tolist() == pytest.approx(want, rel=1e-14, abs=1e-15)
    # out of its box, each input saturates at its own bound: v at 1 m/s, omega at -2 rad/s
    sat = UNICYCLE.step(np.array([[x0, y0, t0]]), np.array([[3.0, -9.0]]), p)
    np.testing.assert_array_equal(sat, UNICYCLE.step(np.array([[x0, y0, t0]]), np.array([[1.0, -2.0]]), p))
    # the walls: x and y stay in the arena; the heading wraps
    edge = UNICYCLE.step(np.array([[1.99, 0.0, 0.0], [0.0, 0.0, 3.1]]), np.array([[1.0, 0.0], [0.0, 2.0]]), p)
    assert edge[0, 0] == 2.0 and edge[1, 2] == pytest.approx(3.1 + 0.2 - 2 * math.pi)


def test_the_unicycle_integrator_takes_u_with_a_column_per_input() -> None:
    p = UNICYCLE.params()
    x = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, math.pi / 2]])
    step = make_integrator(UNICYCLE, p)
    step(x, np.array([[1.0, 0.0], [0.5, 0.0]]))
    assert x.round(12).tolist() == [[0.1, 0.0, 0.0], [1.0, 1.05, round(math.pi / 2, 12)]]


def test_the_unicycle_spec_compiles_and_a_spec_cannot_set_u_max() -> None:
    spec = load_spec(ROOT / "specs" / "unicycle" / "reach_avoid.mitl")
    assert spec.plant is UNICYCLE and UNICYCLE.default_spec == "unicycle/reach_avoid.mitl"
    assert compile_spec(spec).net.place_names
    text = spec.source.replace("plant unicycle", "plant unicycle(u_max = 2)")
    with pytest.raises(SpecError, match="plant 'unicycle' has no parameter 'u_max'"):
        parse_spec(text)


# ---------------------------------------------------------------- SACPN with two inputs


def agent(text: str = REACH, runs: int = 2, seed: int = 3, **settings) -> Sacpn:
    return Sacpn(compile_spec(parse_spec(text)), SacpnSettings(**settings), runs=runs, seed=seed)


def test_sacpn_has_an_actor_row_per_place_and_input_and_explores_each_box() -> None:
    a = agent(rbf=(3, 3, 2))
    assert a.n_inputs == 2 and a.xi.shape == (2, a.n_places, 2, a.n_features)
    assert a.u_lo.tolist() == [-1.0, -2.0] and a.u_hi.tolist() == [1.0, 2.0] and a.u_max is None
    assert a.sigmas.tolist() == [0.3, 0.6]  # sigma_frac 0.3 of each half-range
    _, noise = a._trial_start()
    assert noise.shape == (a.n_steps, 2, 2)
    ro = a.rollout(a.evaluation_states())
    assert ro.actions.shape == (2, a.n_steps, 2) and np.all(ro.actions == 0.0)  # untrained: xi = 0


def test_sacpn_refuses_one_sigma_for_several_inputs() -> None:
    with pytest.raises(TrainingError, match=r"sigma is the exploration of one input; plant 'unicycle' has 2 "):
        agent(sigma=0.5)


def test_the_policy_saturates_each_input_at_its_own_bound() -> None:
    a = agent(rbf=(3, 3, 2))
    a.xi[:, :, 0, :] = 50.0  # v far above its box, omega far below its box
    a.xi[:, :, 1, :] = -50.0
    x = a.evaluation_states()
    u = a.policy(x, a.runtime.reset_code(x))
    assert u.tolist() == [[1.0, -2.0], [1.0, -2.0]]


def _v_outputs(a: Sacpn) -> np.ndarray:
    """Every place row's raw output for v (no clip) over states across the arena."""
    x = np.random.default_rng(0).uniform([-2, -2, -math.pi], [2, 2, math.pi], (300, 3))
    return np.einsum("rpf,bf->rpb", a.xi[:, :, 0, :], a.features(x))


@pytest.mark.parametrize("kernel", ["numpy", "auto"])
def test_anti_windup_holds_per_input(kernel: str) -> None:
    """v's output starts far past its bound (5 m/s against 1): with saturation applied a trial never
    pushes it further out (its exploration beyond the bound is never applied, never reinforced),
    while omega, inside its box, still learns; without, v winds up."""
    runs = []
    for saturation in ("applied", "none"):
        a = agent(runs=4, rbf=(3, 3, 2), sigma_frac=1.0, kernel=kernel, saturation=saturation)
        a.xi[:, :, 0, :] = 5.0  # pi_v = 5 in every state (the features sum to 1)
        before = a.xi.copy()
        a.train(5)
        assert not np.array_equal(a.xi[:, :, 1, :], before[:, :, 1, :])  # omega learned
        runs.append(_v_outputs(a).max())
    applied, none = runs
    assert applied <= 5.0 + 1e-12 < none


def test_a_two_input_checkpoint_round_trips_and_records_its_inputs(tmp_path) -> None:
    a = agent(rbf=(3, 3, 2))
    a.train(2)
    a.save(tmp_path / "params.npz")
    meta = read_meta(tmp_path / "params.npz")
    assert meta["inputs"] == ["v", "omega"]
    with np.load(tmp_path / "params.npz") as z:
        assert z["xi"].shape == (2, a.n_places, 2, a.n_features)
    b = load_sacpn(tmp_path / "params.npz", meta)
    np.testing.assert_array_equal(a.xi, b.xi)
    pol = load_policy(tmp_path)
    x = a.evaluation_states()
    u = pol.act(x, pol.reset(x))
    np.testing.assert_array_equal(u, a.policy(x, a.runtime.reset_code(x)))
    assert u.shape == (2, 2)


def test_a_checkpoint_with_the_wrong_input_axis_is_one_line(tmp_path) -> None:
    a = agent(rbf=(3, 3, 2))
    d = a.state_dict()
    from mitlc.fileio import save_npz

    save_npz(tmp_path / "p.npz", {**d, "xi": d["xi"][:, :, :1, :]})
    with pytest.raises(InputError, match=r"array 'xi' has shape \(2, \d+, 1, 18\), not \(runs = 2, rows, inputs = 2, "):
        read_meta(tmp_path / "p.npz")


def test_an_old_scalar_checkpoint_still_loads() -> None:
    """A checkpoint written before inputs were recorded (the golden P1 training: no 'inputs' in its
    meta, xi of shape (runs, places, features)) loads, acts and trains as before."""
    ckpt = ROOT / "tests" / "fixtures" / "golden" / "train-p1.params.npz"
    meta = read_meta(ckpt)
    assert "inputs" not in meta
    old = load_sacpn(ckpt, meta)
    assert old.n_inputs == 1 and old.xi.ndim == 3
    x = old.evaluation_states()
    assert old.policy(x, old.runtime.reset_code(x)).shape == (old.runs,)
    old.train(1)


def test_a_checkpoint_of_another_input_count_is_refused(tmp_path) -> None:
    a = agent(rbf=(3, 3, 2))
    a.save(tmp_path / "params.npz")
    meta = read_meta(tmp_path / "params.npz")
    one_input = """plant rover2
init x in [-1, 1], y in [-1, 1], theta = 0
horizon 2
prop goal = (x - 1) * (x - 1) + y * y < 0.25
prop rock = x * x + (y - 0.7) * (y - 0.7) < 0.16
formula F G goal & 10 * G !rock
"""
    rover = Plant(
        name="rover2",
        state=UNICYCLE.state,
        defaults={"u_max": 1.0, "dt": 0.1},
        dynamics=lambda x, u, p: np.zeros_like(x),
    )
    PLANTS["rover2"] = rover
    with pytest.raises(InputError, match=r"trained on the inputs \(v, omega\); the spec's plant 'rover2' has \(u\)"):
        load_sacpn(tmp_path / "params.npz", meta, parse_spec(one_input))


# ---------------------------------------------------------------- the command line


PLANT_FILE = """\
import numpy as np
from mitlc.plants import InputVar, Plant, StateVar


def reads_a_third(x, u, p):
    return np.stack([u[:, 0], u[:, 2]], axis=1)


ROVER = Plant(name="rover", state=(StateVar("x", -2.0, 2.0), StateVar("y", -2.0, 2.0)), defaults={"dt": 0.1},
              dynamics=reads_a_third, inputs=(InputVar("vx", -1, 1), InputVar("vy", -1, 1)))
"""


def test_a_dynamics_reading_an_input_it_does_not_have_is_one_line(tmp_path) -> None:
    path = tmp_path / "rover.py"
    path.write_text(PLANT_FILE)
    spec = tmp_path / "r.mitl"
    spec.write_text("plant rover\ninit x in [-0.2, 0.2], y = 0\nhorizon 1\nprop there = x > 1\nformula F there\n")
    r = run("train", "--plant-file", str(path), "--spec", str(spec), "--runs", "2", "--trials", "2", "-q",
            "--no-plots", "--out", str(tmp_path / "out"))  # fmt: skip
    assert one_error(r) == (
        f"{path.resolve()}:6: error: plant 'rover': its dynamics raised IndexError: index 2 is out of bounds for "
        "axis 1 with size 2 (is it reading an input it does not have? the plant has 2 inputs: u is an array of "
        "shape (R, 2), u[:, 0] = vx, u[:, 1] = vy)"
    )


@pytest.mark.parametrize(
    "inputs,message",
    [
        ("()", "plant 'rover': inputs is empty: a plant needs at least one input"),
        ("(('vx', -1),)", "plant 'rover': input 1 must be InputVar(name, lo, hi) or (name, lo, hi), got 2 entries"),
        ("(('vx', 2, 2),)", "plant 'rover': input 'vx': its box must be finite numbers with lo < hi, got [2, 2]"),
        ("(InputVar('vx', 1, -1),)", "input 'vx': its box must be finite numbers with lo < hi, got [1, -1]"),
    ],
)
def test_a_plant_file_with_bad_inputs_is_one_line_and_exit_2(tmp_path, inputs, message) -> None:
    path = tmp_path / "bad.py"
    path.write_text(PLANT_FILE.replace('(InputVar("vx", -1, 1), InputVar("vy", -1, 1))', inputs))
    line = one_error(run("plants", "--plant-file", str(path)))
    assert line.startswith(f"{path.resolve()}:")
    assert f": error: importing the plant file failed: ValueError: {message}" in line


def test_train_and_simulate_write_one_input_column_per_input(tmp_path) -> None:
    spec = tmp_path / "reach.mitl"
    spec.write_text(REACH)
    out = tmp_path / "run"
    r = run("train", "--spec", str(spec), "--runs", "2", "--trials", "3", "--set", "rbf=3x3x2", "-q", "--out",
            str(out))  # fmt: skip
    assert r.exit_code == 0, r.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["sigma"] == [0.3, 0.6] and (out / "rollout.png").is_file()
    r = run("simulate", "--policy", str(out), "--rollouts", "2", "--trace", str(tmp_path / "t.npz"))
    assert r.exit_code == 0, r.output
    with np.load(tmp_path / "t_000.npz") as z:
        assert {"t", "x", "y", "theta", "u_v", "u_omega"} <= set(z.files) and "u" not in z.files
        assert z["u_v"].shape == z["u_omega"].shape == (z["t"].shape[0] - 1,)
    listed = run("plants").output
    assert "  input  v in [-1, 1]\n  input  omega in [-2, 2]\n" in listed


def test_hyrl_refuses_a_plant_with_declared_inputs(tmp_path) -> None:
    spec = tmp_path / "h.mitl"
    spec.write_text(
        "plant unicycle\ninit x in [-1, 1], y = 0, theta = 0\nhorizon 5\nsetpoint 0\nrequire overshoot <= 0\n"
    )
    assert one_error(
        run("train", "--spec", str(spec), "--trials", "2", "--no-plots", "--out", str(tmp_path / "o"))
    ) == (
        f"{spec}: error: HyRL drives one input u bounded by the parameter u_max; plant 'unicycle' declares 2 inputs "
        "(v, omega) (train it with SACPN: a spec with a formula)"
    )


# ---------------------------------------------------------------- Gymnasium


def test_the_unicycle_as_a_gymnasium_environment_takes_both_inputs() -> None:
    gym = pytest.importorskip("gymnasium")
    import mitlc.gym  # noqa: F401  (registers mitlc/Unicycle-v0)

    env = gym.make("mitlc/Unicycle-v0")
    space = env.action_space
    assert space.shape == (2,) and space.low.tolist() == [-1.0, -2.0] and space.high.tolist() == [1.0, 2.0]
    env.reset(seed=0, options={"x0": [0.0, 0.0, 0.0]})
    obs, reward, terminated, truncated, info = env.step(np.array([3.0, 0.0], dtype=np.float32))
    assert obs["obs"].tolist() == pytest.approx([0.1, 0.0, 0.0])  # v saturated at 1 m/s for 0.1 s
    with pytest.raises(InputError, match=r"the action has 1 entries; plant 'unicycle' has 2 inputs \(v, omega\)"):
        env.step(np.array([1.0], dtype=np.float32))
    env.close()


def test_a_gymnasium_environment_with_two_action_entries_is_a_plant_with_two_inputs() -> None:
    gym = pytest.importorskip("gymnasium")

    class Slide(gym.Env):
        """A point on a plane driven by its two velocities: a Box of two entries, the second not symmetric."""

        action_space = gym.spaces.Box(np.array([-1.0, 0.0]), np.array([1.0, 0.5]), dtype=np.float64)
        observation_space = gym.spaces.Box(-5.0, 5.0, (2,), dtype=np.float64)
        dt = 0.1

        def reset(self, *, seed=None, options=None):
            super().reset(seed=seed)
            self.x = np.zeros(2)
            return self.x.copy(), {}

        def step(self, action):
            self.x = self.x + self.dt * np.asarray(action, dtype=float)
            return self.x.copy(), 0.0, False, False, {}

    env_id = "mitlc_test/Slide2d-v0"
    if env_id not in gym.registry:
        gym.register(id=env_id, entry_point=Slide)
    spec = parse_spec(
        f"plant gym:{env_id}\nstate x = obs[0], y = obs[1]\nhorizon 1\nprop far = x > 0.5\nformula F far\n"
    )
    plant = spec.plant
    assert plant.input_names == ("a0", "a1") and plant.input_box()[1].tolist() == [1.0, 0.5]
    a = Sacpn(compile_spec(spec), SacpnSettings(rbf=(3, 3)), runs=2, seed=0)
    assert a.kernel == "numpy" and a.xi.shape == (2, a.n_places, 2, a.n_features)
    a.train(2)
    a.xi[:, :, 0, :] = 9.0  # full speed along x (clipped to 1), a1 at its top (0.5)
    a.xi[:, :, 1, :] = 9.0
    x0 = a.evaluation_states()
    ro = a.rollout(x0)
    assert ro.actions[:, 0].tolist() == [[1.0, 0.5], [1.0, 0.5]]
    np.testing.assert_allclose(ro.states[:, -1], x0 + 10 * 0.1 * np.array([1.0, 0.5]), atol=1e-12)


def test_sacpn_learns_the_unicycles_reach_avoid_spec(tmp_path) -> None:
    """The default spec: reach the goal disc within 4 s and stay, never touching the rock (the monitor
    judges one greedy rollout per run). 0.80 with these seeds after 300 trials; a controller that does
    nothing stays at the start and gets 0."""
    out = tmp_path / "uni"
    r = run("train", "--spec", "unicycle/reach_avoid", "--runs", "10", "--trials", "300", "--set", "rbf_width=0.5",
            "--no-plots", "-q", "--out", str(out))  # fmt: skip
    assert r.exit_code == 0, r.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["success_rate"] >= 0.6
