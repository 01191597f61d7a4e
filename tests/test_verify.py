"""``mitlc verify`` and :mod:`mitlc.verify`: the bound, the batched rollouts, falsification, the command."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli import main
from mitlc.spec.parse import parse_spec
from mitlc.verify import SearchSpace, clopper_pearson_lower, falsify, parse_disturb, parse_vary
from mitlc.verify.rollout import evaluate, roll_out
from mitlc.verify.stats import binomial_upper_tail

# ------------------------------------------------------------------ the bound

CASES = [(0, 1), (1, 1), (0, 10), (1, 10), (5, 10), (9, 10), (10, 10), (0, 1000), (987, 1000), (1000, 1000)]


@pytest.mark.parametrize("k, n", CASES)
@pytest.mark.parametrize("confidence", [0.95, 0.99])
def test_clopper_pearson_equals_the_beta_quantile(k, n, confidence):
    """The lower bound is the (1 - confidence) quantile of Beta(k, n - k + 1) (scipy's, computed
    independently of the bisection), 0 for k = 0."""
    stats = pytest.importorskip("scipy.stats", reason="the independent check is scipy's beta quantile")
    expected = 0.0 if k == 0 else stats.beta.ppf(1 - confidence, k, n - k + 1)
    assert clopper_pearson_lower(k, n, confidence) == pytest.approx(expected, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("n", [1, 2, 10, 59, 1000])
def test_clopper_pearson_closed_forms(n):
    """No failures: the bound solves p^n = alpha; 59 successes of 59 are the classic 95 % / 5 % case."""
    assert clopper_pearson_lower(n, n) == pytest.approx(0.05 ** (1 / n), rel=1e-14)
    assert clopper_pearson_lower(0, n) == 0.0
    if n == 59:  # docs/verify.md: 59 of 59 show 0.95; --require 0.99 needs 299 of 299
        assert clopper_pearson_lower(59, 59) > 0.95 > clopper_pearson_lower(58, 58)
        assert clopper_pearson_lower(299, 299) >= 0.99 > clopper_pearson_lower(298, 298)


@pytest.mark.parametrize("k, n", [(3, 10), (7, 10), (20, 40)])
def test_the_bound_is_where_the_binomial_tail_is_alpha(k, n):
    """At the bound, P(X >= k) = 0.05 by the binomial sum written out with math.comb."""
    p = clopper_pearson_lower(k, n)
    tail = sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k, n + 1))
    assert tail == pytest.approx(0.05, rel=1e-9)
    assert binomial_upper_tail(k, n, p) == pytest.approx(tail, rel=1e-12)


def test_bad_counts_are_refused():
    with pytest.raises(ValueError):
        clopper_pearson_lower(3, 2)
    with pytest.raises(ValueError):
        clopper_pearson_lower(0, 0)


# ------------------------------------------------------------------ a planted weakness

SPEC = parse_spec(
    "plant mass-damper\ninit q in [-1, 1], qdot in [-1, 1]\nhorizon 3\n"
    "prop home = abs(q) < 0.1\nformula F[0, 2] G home\n"
)


class Planted:
    """A PD controller behind the Policy interface, good on most of the init box, whose gain falls
    towards a start near (q, qdot) = (0.7, 0.6): the rollouts from within 0.15 of it become slow,
    and the closest ones miss the 2 s deadline (about 0.15 % of the box)."""

    runs = 1
    dt = 0.03
    spec = SPEC

    def __init__(self, centre=(0.7, 0.6), radius=0.15):
        self.centre, self.radius = np.array(centre), radius

    def reset(self, x0):
        d = np.linalg.norm(x0 - self.centre, axis=1)
        return 1.0 - 0.995 * np.maximum(0.0, 1.0 - d / self.radius)  # the gain of each rollout

    def act(self, x, gain):
        return -(20.0 * gain) * x[:, 0] - 6.0 * x[:, 1]

    def step(self, gain, x_next):
        return gain


STEPS = 100


def objective_of(policy, space):
    def objective(z):
        j = evaluate(policy, SPEC, space, z, STEPS)
        return j.robustness, j.satisfied

    return objective


def test_the_planted_weakness_is_small():
    space = SearchSpace.of(SPEC)
    j = evaluate(Planted(), SPEC, space, space.sample(4000, np.random.default_rng(5)), STEPS)
    assert 0.0 < 1 - j.satisfied.mean() < 0.005
    bad = j.z[~j.satisfied] * 2 - 1  # back to (q, qdot)
    assert np.all(np.linalg.norm(bad - [0.7, 0.6], axis=1) < 0.15)


def test_falsification_finds_the_weakness_more_often_than_uniform_sampling():
    """Differential evolution finds a counterexample within 500 rollouts in at least 9 of 10 seeds;
    uniform sampling with the same 500 rollouts in fewer (measured: 9/10 and 4/10, docs/verify.md)."""
    pytest.importorskip("scipy.optimize", reason="--method de is scipy's differential evolution")
    space = SearchSpace.of(SPEC)
    objective = objective_of(Planted(), space)
    found = {m: sum(falsify(objective, space.dim, 500, m, seed=s).found for s in range(10)) for m in ("de", "uniform")}
    assert found["de"] >= 9 and found["uniform"] < found["de"], found


def test_a_search_stops_at_its_budget_and_is_deterministic():
    space = SearchSpace.of(SPEC)
    objective = objective_of(Planted(centre=(5.0, 5.0)), space)  # no weakness inside the box
    a = falsify(objective, space.dim, 150, "uniform", seed=3)
    b = falsify(objective, space.dim, 150, "uniform", seed=3)
    assert (a.rollouts, a.found) == (150, False)
    assert np.array_equal(a.z, b.z) and np.array_equal(a.robustness, b.robustness)


def test_cma_respects_the_budget():
    pytest.importorskip("cma", reason="--method cma needs the cma package")
    space = SearchSpace.of(SPEC)
    s = falsify(objective_of(Planted(centre=(5.0, 5.0)), space), space.dim, 60, "cma", seed=1)
    assert s.rollouts == 60 and not s.found and np.all((s.z >= 0) & (s.z <= 1))


# ------------------------------------------------------------------ batched rollouts


def test_a_batch_with_varied_parameters_and_disturbances_equals_rollouts_one_by_one():
    """Scenarios rolled out together along the run axis, each with its own mass and disturbance,
    give the states each gives alone (its parameters as plain numbers)."""
    disturb = parse_disturb(["u=3", "qdot=2"], SPEC)
    space = SearchSpace.of(SPEC, parse_vary(["M=0.3:0.9", "B=0:0.2"], SPEC), disturb, pieces=2)
    assert space.names == ("q", "qdot", "M", "B", "u[0]", "u[1]", "qdot[0]", "qdot[1]")
    z = np.random.default_rng(2).random((4, space.dim))
    together, acts = roll_out(Planted(), SPEC, space, z, 40)
    for i in range(4):
        p = space.decode(z[i : i + 1]).params
        plant_line = f"plant mass-damper(M = {float(p['M'][0])!r}, B = {float(p['B'][0])!r})"
        alone_spec = parse_spec(SPEC.source.replace("plant mass-damper", plant_line))
        alone_space = SearchSpace.of(alone_spec, (), space.disturb, pieces=2)  # the parameters as numbers
        alone, _ = roll_out(Planted(), alone_spec, alone_space, np.r_[z[i, :2], z[i, 4:]][None, :], 40)
        assert not np.array_equal(
            alone[0], roll_out(Planted(), alone_spec, SearchSpace.of(alone_spec), z[i : i + 1, :2], 40)[0][0]
        )
        np.testing.assert_allclose(together[i], alone[0], rtol=1e-12, atol=1e-12)
    d = space.decode(z).disturbance[:, :, 0]
    assert np.all(np.abs(d) <= 3) and np.all(np.abs(acts) <= 10)  # u_max = 10
    assert acts.shape == (4, 40)


# ------------------------------------------------------------------ the command

P2_SHORT = """\
plant pendulum(u_max = 10)
init q in [2.4, pi], qdot = 0
horizon 1
prop kappa = abs(q) < 0.3
prop psi   = 0.3 < q < pi/2 + 0.5
formula F G kappa & 10 * G !psi
"""


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A SACPN policy of two runs trained two trials on problem 2 (1 s): it fails nearly everywhere."""
    folder = tmp_path_factory.mktemp("verify")
    spec = folder / "p2.mitl"
    spec.write_text(P2_SHORT)
    res = run(
        "train", "--spec", spec, "--runs", 2, "--trials", 2, "--out", folder / "pol", "-q", "--no-plots", "--no-race"
    )
    assert res.exit_code == 0, res.output
    return folder


def test_counterexamples_are_traces_mitlc_check_rejects(trained, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing may land in the working folder
    out = tmp_path / "out"
    out.mkdir()
    (out / "cex_007.npz").write_bytes(b"a previous verification's")
    (out / "notes.txt").write_text("the user's")
    res = run("verify", "--policy", trained / "pol", "--samples", 50, "--budget", 40, "--out", out, "--keep", 2)
    assert res.exit_code == 1, res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    (out / "notes.txt").unlink()
    report = json.loads((out / "report.json").read_text())
    assert report["violating_rollouts"] >= 50 - report["sampling"]["satisfied"]
    s = report["sampling"]
    assert s["samples"] == 50 and s["lower_bound"] == clopper_pearson_lower(s["satisfied"], 50)
    assert report["exit_status"] == 1 and len(report["counterexamples"]) == 2
    first = report["counterexamples"][0]
    assert first["robustness"] < 0 and 2.4 <= first["start"]["q"] <= math.pi
    assert first["robustness"] <= report["counterexamples"][1]["robustness"]
    checked = run("check", out / "spec.mitl", out / first["trace"])
    assert checked.exit_code == 1 and "VIOLATED" in checked.output
    with np.load(out / first["trace"]) as trace:
        assert trace["q"][0] == pytest.approx(first["start"]["q"]) and trace["start_qdot"] == 0
    assert (out / "cex_000.png").read_bytes().startswith(b"\x89PNG")
    with np.load(out / "counterexamples.npz") as cex:
        assert cex["x0"].shape == (2, 2) and cex["x0"][0, 0] == pytest.approx(first["start"]["q"])
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["report.json", "report.html", "spec.mitl", "counterexamples.npz"]
        + ["cex_000.npz", "cex_000.png", "cex_001.npz", "cex_001.png"]
    )


def test_exit_0_when_satisfied_and_1_when_the_bound_falls_short(trained, tmp_path):
    """Judged by a spec of the same plant that every rollout meets: exit 0; the same 100 rollouts
    cannot show 0.99 at 95 % (0.05^(1/100) = 0.9705), so --require 0.99 is exit 1."""
    easy = tmp_path / "easy.mitl"
    easy.write_text(P2_SHORT.replace("formula F G kappa & 10 * G !psi", "formula G abs(qdot) < 1000"))
    common = ("verify", "--policy", trained / "pol", "--spec", easy, "--samples", 100, "--budget", 30)
    ok = run(*common)
    assert ok.exit_code == 0, ok.output
    assert "100/100 rollouts satisfy" in ok.output and "lower bound 0.9705" in ok.output
    short = run(*common, "--require", 0.99)
    assert short.exit_code == 1 and "below --require 0.99" in short.output
    assert run(*common, "--require", 0.97).exit_code == 0


@pytest.mark.parametrize(
    "args, message",
    [
        (("--vary", "mass=1:2"), "--vary: error: 'mass' is not a parameter of plant 'pendulum'"),
        (("--vary", "M=0.2:0.1"), "--vary: error: 'M=0.2:0.1': an empty range"),
        (("--vary", "M=0.2"), "--vary: error: 'M=0.2': expected NAME=LO:HI"),
        (("--vary", "dt=0.01:0.02"), "--vary: error: 'dt' cannot vary"),
        (("--disturb", "w=1"), "--disturb: error: 'w' is neither an input nor a state variable of plant 'pendulum'"),
        (("--disturb", "u=-1"), "--disturb: error: 'u=-1': a bound is 0 or more"),
        (("--samples", 0), "--samples: error: 0 is not in the range"),
        (("--spec", "mass_damper/overshoot"), "--spec mass_damper/overshoot: error: the policy was trained for plant"),
        (("--method", "nelder"), "--method: error:"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(trained, tmp_path, args, message):
    out = tmp_path / "out"
    res = run("verify", "--policy", trained / "pol", "--budget", 0, "--samples", 5, *args, "--out", out)
    assert res.exit_code == 2, res.output
    assert res.output.startswith(message) and len(res.output.strip().splitlines()) == 1, res.output
    assert not out.exists() or not any(out.iterdir())  # nothing written


def test_the_policy_folder_is_no_place_for_the_report(trained):
    before = sorted(p.name for p in (trained / "pol").iterdir())
    res = run("verify", "--policy", trained / "pol", "--samples", 5, "--out", trained / "pol")
    assert res.exit_code == 2 and "the policy's own folder" in res.output
    assert sorted(p.name for p in (trained / "pol").iterdir()) == before


def test_a_folder_that_is_no_training_is_one_line(tmp_path):
    res = run("verify", "--policy", tmp_path, "--samples", 5)
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1 and "no params.npz" in res.output


class OneBadRun(Planted):
    """Three trained runs behind one policy, as mitlc train saves them: row b acts with run b % 3;
    run 2 has almost no gain (it fails from nearly every start), runs 0 and 1 are good."""

    runs = 3

    def reset(self, x0):
        return np.where(np.arange(x0.shape[0]) % 3 == 2, 0.005, 1.0)


def test_each_scenario_acts_with_its_own_run_in_any_batch():
    space = SearchSpace.of(SPEC, runs=3)
    assert space.names == ("run", "q", "qdot")
    z = np.random.default_rng(1).random((25, 3))
    z[:, 1:] = 0.1 + 0.3 * z[:, 1:]  # starts away from q = 0, which run 2 would also meet
    j = evaluate(OneBadRun(), SPEC, space, z, STEPS)
    run = space.decode(z).run
    assert set(run) == {0, 1, 2}
    assert np.array_equal(j.satisfied, run != 2)
    for i in (0, 7, 19):  # alone, each scenario rolls out as it did in the batch
        alone = evaluate(OneBadRun(), SPEC, space, z[i : i + 1], STEPS)
        np.testing.assert_array_equal(alone.states[0], j.states[i])


def test_the_pages_python_runs(capsys):
    """docs/verify.md's Python block runs as written: the PD controller satisfies every sample, and
    the bound is the closed form for 1000 of 1000."""
    from pathlib import Path

    page = (Path(__file__).resolve().parent.parent / "docs" / "verify.md").read_text(encoding="utf-8")
    [code] = [b.split("\n", 1)[1] for b in page.split("```")[1::2] if b.startswith("python\n")]
    exec(compile(code, "docs/verify.md", "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"1000 {0.05 ** (1 / 1000)}" and lines[1] == "False 200"


# ------------------------------------------------------------------ falsification-guided training


def test_guided_trials_start_from_the_given_states_and_evaluation_from_the_box():
    from mitlc.cli.guided import guide_starts
    from mitlc.learn.sacpn import Sacpn
    from mitlc.petri.compile import compile_spec

    spec = parse_spec(P2_SHORT)
    guided, plain = (Sacpn(compile_spec(spec), runs=4, seed=3) for _ in range(2))
    starts = np.array([[1.0, 0.5], [-1.0, 0.25]])
    guide_starts(guided, starts, share=1.0)
    x = guided.sample_init(guided.rngs)
    assert all(any(np.array_equal(row, s) for s in starts) for row in x)
    np.testing.assert_array_equal(guided.evaluation_states(), plain.evaluation_states())
    half = Sacpn(compile_spec(spec), runs=200, seed=3)
    guide_starts(half, starts)  # share 1/2: some runs from the states, the rest from the box
    x = half.sample_init(half.rngs)
    given = np.isin(x[:, 1], starts[:, 1])
    assert 60 < given.sum() < 140 and np.all((x[~given, 0] >= 2.4) & (x[~given, 0] <= np.pi))


def test_resume_with_the_counterexamples_starts(trained, tmp_path):
    import shutil

    pol = tmp_path / "pol"
    shutil.copytree(trained / "pol", pol)
    out = tmp_path / "cex"
    assert run("verify", "--policy", pol, "--samples", 20, "--budget", 0, "--keep", 5, "--out", out).exit_code == 1
    res = run("train", "--resume", pol, "--trials", 4, "--starts", out / "counterexamples.npz", "-q", "--no-plots")
    assert res.exit_code == 0, res.output
    assert len(json.loads((pol / "metrics.json").read_text())["returns"][0]) == 4


@pytest.mark.parametrize(
    "arrays, message",
    [
        ({"z": np.zeros((1, 1))}, "no array 'x0'"),
        ({"x0": np.zeros((2, 3))}, "x0 has shape (2, 3); expected (K, 2)"),
        ({"x0": np.zeros((0, 2))}, "no states in it"),
        ({"x0": np.zeros((1, 2)), "state_names": np.array(["x", "v"])}, "its states are (x, v)"),
    ],
)
def test_bad_starts_are_one_line(trained, tmp_path, arrays, message):
    f = tmp_path / "starts.npz"
    np.savez(f, **arrays)
    res = run("train", "--resume", trained / "pol", "--out", tmp_path / "o", "--trials", 3, "--starts", f, "-q")
    assert res.exit_code == 2 and message in res.output and len(res.output.strip().splitlines()) == 1, res.output
    res = run("train", "--spec", trained / "p2.mitl", "--starts", f, "-q")
    assert res.exit_code == 2 and "--starts: error: --starts guides a resumed training" in res.output


def test_a_rollout_that_diverges_is_a_counterexample_not_an_error():
    from mitlc.verify.rollout import DIVERGED, judge

    states = np.zeros((3, 5, 2))
    states[1, 2:, 0] = np.inf
    states[2, 4, 1] = np.nan
    res = judge(SPEC, states, 0.5)
    assert res.satisfied.tolist() == [True, False, False]
    assert res.robustness[1] == res.robustness[2] == -np.inf and res.violation_time[1:].tolist() == [1.0, 2.0]
    assert res.failing[1:] == (DIVERGED, DIVERGED)


def test_a_stable_baselines3_model_is_verified_through_its_policy(tmp_path):
    """``--policy model.zip --spec SPEC``: the model acts through mitlc.gym.Sb3Policy, judged as any policy."""
    pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 and PyTorch: pip install 'mitlc[sb3]'")
    gym = pytest.importorskip("gymnasium")
    import torch
    from stable_baselines3 import SAC

    import mitlc.gym  # noqa: F401 - registers the environments

    torch.set_num_threads(1)
    spec = tmp_path / "p2.mitl"
    spec.write_text(P2_SHORT)
    env = gym.make("mitlc/Pendulum-v0", spec=str(spec), marking_obs="box", verdict="off")
    SAC("MlpPolicy", env, seed=0, device="cpu", learning_starts=50, batch_size=32).learn(60).save(tmp_path / "m.zip")
    out = tmp_path / "out"
    res = run("verify", "--policy", tmp_path / "m.zip", "--spec", spec, "--samples", 8, "--budget", 4, "--out", out)
    assert res.exit_code in (0, 1) and "/8 rollouts satisfy" in res.output, res.output
    report = json.loads((out / "report.json").read_text())
    assert report["sampling"]["samples"] == 8 and report["falsification"]["rollouts"] == 4
    assert res.exit_code == (1 if report["violating_rollouts"] else 0)
    no_spec = run("verify", "--policy", tmp_path / "m.zip")
    assert no_spec.exit_code == 2 and no_spec.output.startswith("--spec: error: a Stable-Baselines3 model")


def test_verify_policy_counts_bounds_and_keeps_the_least_robust():
    from mitlc.verify import verify_policy

    space = SearchSpace.of(SPEC, runs=3)
    a = verify_policy(OneBadRun(), SPEC, space, STEPS, samples=90, budget=30, method="uniform", seed=4, keep=5)
    b = verify_policy(OneBadRun(), SPEC, space, STEPS, samples=90, budget=30, method="uniform", seed=4, keep=5)
    s = a.sampled
    assert s.lower_bound == clopper_pearson_lower(s.satisfied, 90) and 0 < s.satisfied < 90
    assert a.search is not None and a.search.rollouts == 30
    assert a.violations == (90 - s.satisfied) + int((~a.search.satisfied).sum())
    cex = a.counterexamples
    assert cex is not None and cex.z.shape[0] == 5 and len({tuple(z) for z in cex.z}) == 5
    assert np.all(np.diff(cex.robustness) >= 0) and not cex.satisfied.any()
    assert np.array_equal(cex.z, b.counterexamples.z) and s.satisfied == b.sampled.satisfied
    assert cex.robustness[0] <= min(s.least_robustness, a.search.robustness.min())


class Idle(Planted):
    """No input at all."""

    def act(self, x, gain):
        return np.zeros(x.shape[0])


def test_a_state_disturbance_moves_the_state_by_its_rate():
    """With no input and no velocity, a disturbance d on q's rate moves q by d per second, and by -d
    in the second half of the horizon when the second piece is -d."""
    spec = parse_spec(SPEC.source.replace("qdot in [-1, 1]", "qdot = 0").replace("q in [-1, 1]", "q = 0"))
    space = SearchSpace.of(spec, (), parse_disturb(["q=0.5"], spec), pieces=2)
    assert space.names == ("q[0]", "q[1]")
    states, _ = roll_out(Idle(), spec, space, np.array([[1.0, 0.0]]), 40)  # d = +0.5, then -0.5
    t = np.arange(41) * 0.03
    expected = np.where(t <= 0.6, 0.5 * t, 0.5 * 0.6 - 0.5 * (t - 0.6))
    np.testing.assert_allclose(states[0, :, 0], expected, atol=1e-12)
    assert np.all(states[0, :, 1] == 0)


def test_a_hyrl_policy_is_verified_by_a_spec_with_a_formula(tmp_path):
    """A HyRL training (classical criteria, no formula) needs --spec with a formula on its plant."""
    res = run("train", "--spec", "mass_damper/overshoot", "--runs", 2, "--trials", 5, "--out", tmp_path / "hy", "-q")
    assert res.exit_code == 0, res.output
    alone = run("verify", "--policy", tmp_path / "hy", "--samples", 5)
    assert alone.exit_code == 2 and "no 'formula' nor 'check' line" in alone.output
    assert len(alone.output.strip().splitlines()) == 1
    spec = tmp_path / "near.mitl"
    spec.write_text(
        "plant mass-damper\ninit q in [-1, 1], qdot = 0\nhorizon 5\nprop near = abs(q) < 0.2\nformula F[0,4] G near\n"
    )
    out = tmp_path / "out"
    res = run("verify", "--policy", tmp_path / "hy", "--spec", spec, "--samples", 20, "--budget", 10, "--out", out)
    report = json.loads((out / "report.json").read_text())
    assert res.exit_code == report["exit_status"] == (1 if report["violating_rollouts"] else 0), res.output
    assert report["space"]["coordinates"] == ["run", "q"] and report["steps"] == round(5 / 0.03)
    assert report["counterexamples"]  # five trials are far from enough: it fails from some starts
    for c in report["counterexamples"]:
        assert run("check", out / "spec.mitl", out / c["trace"]).exit_code == 1


def test_a_plant_that_reads_a_parameter_as_one_number_is_refused_for_vary():
    from mitlc.errors import InputError
    from mitlc.plants import Plant, StateVar
    from mitlc.verify.rollout import check_batched_params

    def scalar(x, u, p):  # float(): one number for every copy
        return np.stack([x[:, 1], (u - float(p["c"]) * x[:, 1]) / p["m"]], axis=1)

    def first(x, u, p):  # silently the first copy's value
        c = np.atleast_1d(p["c"])[0]
        return np.stack([x[:, 1], (u - c * x[:, 1]) / p["m"]], axis=1)

    for dynamics, why in ((scalar, "cannot step copies with a parameter each"), (first, "differently")):
        plant = Plant(
            "probe",
            (StateVar("q", -1, 1), StateVar("qdot", -1, 1)),
            {"m": 1.0, "c": 0.1, "u_max": 1.0, "dt": 0.1},
            dynamics,
        )
        check_batched_params(plant, plant.params(), (("m", 0.5, 2.0),))  # m is read per copy: fine
        with pytest.raises(InputError, match=why) as err:
            check_batched_params(plant, plant.params(), (("c", 0.0, 1.0),))
        assert err.value.file == "--vary"
