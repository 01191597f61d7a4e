"""``mitlc train`` and ``mitlc simulate`` through click's CliRunner."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli import main


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def test_train_writes_everything(short_spec, tmp_path):
    out = tmp_path / "out"
    res = run(
        "train", "--plant", "pendulum", "--spec", short_spec, "--runs", 3, "--trials", 4, "--out", out, "-q",
        "--learner", "sacpn",
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "success rate" in res.output
    for name in ("metrics.json", "params.npz", "learning_curve.png", "rollout.png"):
        assert (out / name).stat().st_size > 0
    m = json.loads((out / "metrics.json").read_text())
    assert np.array(m["returns"]).shape == (3, 4)
    assert 0.0 <= m["success_rate"] <= 1.0 and len(m["satisfied"]) == 3
    steps = round(1.0 / 0.03)  # short_spec: a 1 s trial at the pendulum's 0.03 s
    assert m["wall_s"] > 0 and m["settings"]["gamma"] == 1 - 3 / steps
    race = m["race"]  # 5 designs, half the trials each; the winner's settings trained
    assert (race["runs"], race["trials"], len(race["designs"])) == (1, 2, 5)  # a quarter of the runs, rounded up
    won = dict(part.split("=") for part in race["winner"].split())
    assert {k: float(v) for k, v in won.items()} == {k: m["settings"][k] for k in ("sigma_frac", "rbf_width")}
    assert not list(out.glob(".*"))  # no temporary files left


def test_same_seed_same_returns_and_resume(short_spec, tmp_path):
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    # --no-race: a race over 6 trials and one over 2 may choose different designs; a resumed run keeps its own
    common = ("--spec", short_spec, "--runs", 2, "--seed", 3, "-q", "--no-plots", "--no-race")
    assert run("train", *common, "--trials", 6, "--out", a).exit_code == 0
    assert run("train", *common, "--trials", 6, "--out", b).exit_code == 0
    ra = json.loads((a / "metrics.json").read_text())["returns"]
    assert ra == json.loads((b / "metrics.json").read_text())["returns"]
    assert run("train", *common, "--trials", 2, "--out", c).exit_code == 0
    res = run("train", "--resume", c, "--trials", 6, "-q", "--no-plots")
    assert res.exit_code == 0, res.output
    with np.load(a / "params.npz") as pa, np.load(c / "params.npz") as pc:
        np.testing.assert_array_equal(pa["xi"], pc["xi"])
        np.testing.assert_array_equal(pa["theta"], pc["theta"])
    assert json.loads((c / "metrics.json").read_text())["returns"] == ra


def test_ctrl_c_writes_a_checkpoint_that_resumes(short_spec, tmp_path, monkeypatch):
    from mitlc.learn import sacpn

    whole, cut = tmp_path / "whole", tmp_path / "cut"
    common = ("--spec", short_spec, "--runs", 2, "-q", "--no-plots", "--no-race")
    assert run("train", *common, "--trials", 5, "--out", whole).exit_code == 0
    real = sacpn.Sacpn._trial
    calls = {"n": 0}

    def interrupted(self):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(self)

    monkeypatch.setattr(sacpn.Sacpn, "_trial", interrupted)
    res = run("train", *common, "--trials", 5, "--out", cut)
    assert res.exit_code == 130
    assert "--resume" in res.output
    m = json.loads((cut / "metrics.json").read_text())
    assert m["interrupted"] and m["trials"] == 2
    monkeypatch.setattr(sacpn.Sacpn, "_trial", real)
    assert run("train", "--resume", cut, "--trials", 5, "-q", "--no-plots").exit_code == 0
    with np.load(whole / "params.npz") as pw, np.load(cut / "params.npz") as pc:
        np.testing.assert_array_equal(pw["xi"], pc["xi"])


def test_simulate_prints_a_verdict_per_rollout(short_spec, tmp_path):
    out = tmp_path / "pol"
    args = ("--runs", 2, "--trials", 2, "--out", out, "-q", "--no-plots", "--learner", "sacpn")  # a SACPN policy
    assert run("train", "--spec", short_spec, *args).exit_code == 0
    res = run("simulate", "--policy", out, "--rollouts", 3)
    assert res.exit_code == 0, res.output
    assert res.output.count("rollout ") == 3
    assert "rollouts satisfy F G kappa & 10 * G !psi (fresh starts drawn from the initial set, seed 0)" in res.output
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json", "metrics.json", "params.npz"]  # no figure unasked
    plot = tmp_path / "sim.png"
    assert run("simulate", "--policy", out, "--rollouts", 3, "--plot", plot).exit_code == 0
    assert plot.read_bytes()[:4] == b"\x89PNG"
    res = run("simulate", "--policy", out, "--policy", out)
    assert res.exit_code == 2
    assert res.output.strip() == (
        "--policy: error: only HyRL policies (classical criteria) run composed; give one SACPN policy"
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (("train",), "give --plant or --spec"),
        (("train", "--plant", "mass-damper", "--spec", "SPEC"), "not 'mass-damper'"),
        (("train", "--plant", "nosuch"), "unknown plant"),
        (("simulate", "--policy", "EMPTY"), "no params.npz"),
    ],
)
def test_user_errors_are_one_line_and_exit_2(short_spec, tmp_path, args, message):
    empty = tmp_path / "empty"
    empty.mkdir()
    args = tuple(str(short_spec) if a == "SPEC" else str(empty) if a == "EMPTY" else a for a in args)
    res = CliRunner().invoke(main, list(args))
    assert res.exit_code == 2, res.output
    assert message in res.output
    assert "Traceback" not in res.output


def test_diverging_training_is_a_clean_error(short_spec, tmp_path, monkeypatch):
    from mitlc.learn import sacpn

    def nan_trial(self):
        self.xi[0, 0, 0] = np.inf
        return np.zeros(self.runs)

    monkeypatch.setattr(sacpn.Sacpn, "_trial", nan_trial)
    res = CliRunner().invoke(
        main,
        ["train", "--spec", str(short_spec), "--runs", "2", "--trials", "3", "--out", str(tmp_path / "o"), "-q"]
        + ["--learner", "sacpn"],
    )
    assert res.exit_code == 0, res.output  # run 1 is healthy: it is kept, run 0 is marked
    assert "1 of 2 runs diverged (NaN or inf) and kept their last finite parameters: run 0 (trial 1)" in res.output
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert metrics["diverged"] == [{"run": 0, "trial": 1}] and metrics["returns"][0] == [None, None, None]


def test_set_overrides_any_trainer_setting_sacpn_and_hyrl(short_spec, spec_dir, tmp_path):
    out = tmp_path / "sacpn"
    res = run(
        "train",
        "--spec",
        short_spec,
        "--runs",
        2,
        "--trials",
        2,
        "--out",
        out,
        "-q",
        "--no-plots",
        "--set",
        "rbf=5x4",
        "--set",
        "sigma_frac=0.2",
        "--set",
        "bootstrap_timeout=false",
    )
    assert res.exit_code == 0, res.output
    s = json.loads((out / "metrics.json").read_text())["settings"]
    assert s["rbf"] == [5, 4] and s["sigma_frac"] == 0.2 and s["bootstrap_timeout"] is False
    out = tmp_path / "hyrl"
    res = run(
        "train",
        "--spec",
        spec_dir / "mass_damper" / "overshoot.mitl",
        "--runs",
        1,
        "--trials",
        1,
        "--out",
        out,
        "-q",
        "--no-plots",
        "--set",
        "alpha_a=0.08",
        "--set",
        "rbf=6x6x3",
        "--set",
        "q_warp=none",
    )
    assert res.exit_code == 0, res.output
    m = json.loads((out / "metrics.json").read_text())
    assert m["settings"]["alpha_a"] == 0.08 and m["settings"]["q_warp"] is None and m["n_features"] == 108


@pytest.mark.parametrize(
    "spec, args, message",
    [
        ("short", ("--set", "alpha=1"), "--set: error: unknown setting 'alpha' (did you mean 'alpha_a' or 'alpha_c'?)"),
        ("short", ("--set", "gama=0.9"), "--set: error: unknown setting 'gama' (did you mean 'gamma'?)"),
        ("short", ("--set", "zeta=1"), "--set: error: unknown setting 'zeta' (known: gamma, lam,"),
        ("overshoot", ("--set", "sigmaa=1"), "--set: error: unknown setting 'sigmaa' (did you mean 'sigma'?)"),
        ("short", ("--set", "gamma"), "--set: error: 'gamma' is not NAME=VALUE"),
        ("short", ("--set", "gamma=high"), "--set: error: gamma: 'high' is not a number"),
        ("short", ("--set", "gamma=3"), "--set: error: gamma must be in [0, 1], got 3.0"),
        ("short", ("--sigma", "-1"), "--sigma: error: sigma must be a number in [0, 1e+12], got -1.0"),
        ("overshoot", ("--set", "rbf=10x10"), "--set: error: rbf: '10x10' is not 3 counts such as 10x10x10"),
        ("overshoot", ("--set", "q_warp=2"), "--set: error: q_warp must be in (0, 1], got 2.0"),
    ],
)
def test_bad_settings_are_one_line_errors_naming_the_option(short_spec, spec_dir, tmp_path, spec, args, message):
    path = short_spec if spec == "short" else spec_dir / "mass_damper" / "overshoot.mitl"
    res = CliRunner().invoke(
        main,
        [
            "train",
            "--spec",
            str(path),
            "--runs",
            "1",
            "--trials",
            "1",
            "-q",
            "--no-plots",
            "--out",
            str(tmp_path / "o"),
            *args,
        ],
    )
    assert res.exit_code == 2, res.output
    assert res.output.strip().startswith(message) and len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_ctrl_c_during_the_race_saves_nothing_and_says_so(short_spec, tmp_path, monkeypatch):
    from mitlc.learn import sacpn

    real = sacpn.Sacpn._trial
    calls = {"n": 0}

    def interrupted(self):
        calls["n"] += 1
        if calls["n"] == 3:  # in the race's first design (2 trials each of the 4 designs, then the training)
            raise KeyboardInterrupt
        return real(self)

    monkeypatch.setattr(sacpn.Sacpn, "_trial", interrupted)
    out = tmp_path / "cut"
    res = run("train", "--spec", short_spec, "--runs", 2, "--trials", 5, "-q", "--no-plots", "--out", out)
    assert res.exit_code == 130
    assert "interrupted during the race" in res.output and "nothing saved" in res.output
    assert not (out / "params.npz").exists() and not (out / "metrics.json").exists()


def test_settings_given_are_left_out_of_the_race(short_spec, tmp_path):
    """--set sigma_frac=1 races the two widths only, and the training keeps the exploration given."""
    from mitlc.sweep.race import designs

    assert len(designs(set())) == 5 and len(designs({"sigma"})) == 2 and len(designs({"rbf_width"})) == 3
    assert len(designs({"sigma_frac", "rbf_width"})) == 1
    res = run(
        "train",
        "--spec",
        short_spec,
        "--runs",
        2,
        "--trials",
        4,
        "-q",
        "--no-plots",
        "--set",
        "sigma_frac=1",
        "--out",
        tmp_path / "o",
    )
    assert res.exit_code == 0, res.output
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert [d["name"] for d in m["race"]["designs"]] == ["rbf_width=0.5", "rbf_width=1"]
    assert m["settings"]["sigma_frac"] == 1.0
