"""``mitlc automaton`` and the HyRL training entry point of ``mitlc train``."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from mitlc.cli.hybrid import automaton, train_hybrid_cli
from mitlc.learn.hyrl import HyrlSettings, load_learner


def test_automaton_text_json_dot(spec_dir, tmp_path):
    spec = str(spec_dir / "mass_damper" / "overshoot.mitl")
    runner = CliRunner()
    res = runner.invoke(automaton, [spec])
    assert res.exit_code == 0, res.output
    assert "E_Mp -> P  [violation]  (q0 < 0 & q > 0) | (q0 >= 0 & q < 0)" in res.output
    res = runner.invoke(automaton, [spec, "--format", "json"])
    d = json.loads(res.output)
    assert [m["name"] for m in d["modes"]] == ["I", "E_Mp", "S", "P"]
    out = tmp_path / "h.dot"
    res = runner.invoke(automaton, [spec, "--format", "dot", "-o", str(out)])
    assert res.exit_code == 0 and out.read_text().startswith("digraph automaton")


def test_automaton_errors_are_one_line_and_exit_2(tmp_path):
    bad = tmp_path / "bad.mitl"
    bad.write_text("plant mass-damper\ninit q in [-1, 1]\nrequire overshoot in [0.1, 0.2]\n")
    res = CliRunner().invoke(automaton, [str(bad)])
    assert res.exit_code == 2
    assert "bad.mitl:3:9: error: overshoot takes an upper bound only" in res.output
    res = CliRunner().invoke(automaton, [str(bad).replace("bad", "missing")])
    assert res.exit_code == 2 and "Traceback" not in res.output
    formula = tmp_path / "f.mitl"
    formula.write_text("prop k = abs(q) < 1\nformula F k\n")
    res = CliRunner().invoke(automaton, [str(formula), "--format", "png"])
    assert res.exit_code == 2 and "no 'require'" in res.output


def test_train_hybrid_cli_writes_everything(spec_dir, tmp_path, capsys):
    out = tmp_path / "run"
    m = train_hybrid_cli(
        spec_dir / "mass_damper" / "overshoot.mitl",
        runs=2,
        trials=3,
        seed=4,
        out=out,
        progress=False,
        settings=HyrlSettings(trial_s=0.6),
        n_init=5,
    )
    line = capsys.readouterr().out.strip()
    # q0 in {-1, -0.5, 0, 0.5, 1}: the start at the set-point is reported apart (section 3-3-1)
    assert (
        line.startswith("2 runs x 3 trials in ")
        and (
            f"success rate {m['success_rate']:.2f} (5 initial states per run; "
            f"{m['success_rate_step_ge_0.1']:.2f} from the 4 at least 0.1 from the set-point); results in {out}"
        )
        in line
    )
    for f in ("metrics.json", "params.npz", "learning_curve.png", "rollout.png"):
        assert (out / f).is_file(), f
    on_disk = json.loads((out / "metrics.json").read_text())
    assert on_disk == json.loads(json.dumps(m))
    assert np.array(on_disk["returns"]).shape == (2, 3)
    assert on_disk["initial_states"] == 5 and 0.0 <= on_disk["success_rate"] <= 1.0
    assert on_disk["initial_states_step_ge_0.1"] == 4
    assert set(on_disk["success_rate_by_requirement"]) == {"overshoot"}
    assert on_disk["interrupted"] is False and on_disk["wall_s"] > 0
    learner = load_learner(out / "params.npz")
    np.testing.assert_allclose(learner.returns, on_disk["returns"], atol=1e-6)
    assert (out / "rollout.png").read_bytes()[:4] == b"\x89PNG"


def test_train_hybrid_cli_resumes_to_the_same_numbers(spec_dir, tmp_path):
    spec = spec_dir / "mass_damper" / "overshoot.mitl"
    settings = HyrlSettings(trial_s=0.3)
    straight = train_hybrid_cli(spec, 2, 4, 1, tmp_path / "a", progress=False, settings=settings, n_init=3, plots=False)
    train_hybrid_cli(spec, 2, 2, 1, tmp_path / "b", progress=False, settings=settings, n_init=3, plots=False)
    resumed = train_hybrid_cli(
        None, 0, 4, 0, tmp_path / "b", progress=False, n_init=3, plots=False, resume=tmp_path / "b"
    )
    assert resumed["trials"] == 4 and resumed["returns"] == straight["returns"]


def test_compose_command_runs_policies_trained_separately(spec_dir, tmp_path):
    from mitlc.cli.hybrid import compose_cmd

    d = spec_dir / "mass_damper"
    settings = HyrlSettings(trial_s=0.9)
    train_hybrid_cli(
        d / "rise_time.mitl", 2, 2, 0, tmp_path / "rise", progress=False, settings=settings, n_init=2, plots=False
    )
    train_hybrid_cli(
        d / "overshoot.mitl", 2, 2, 0, tmp_path / "over", progress=False, settings=settings, n_init=2, plots=False
    )
    plot = tmp_path / "composed.png"
    res = CliRunner().invoke(
        compose_cmd,
        [
            str(d / "overshoot_rise_time.mitl"),
            "--policy",
            str(tmp_path / "rise"),
            "--policy",
            str(tmp_path / "over"),
            "--initial-states",
            "4",
            "--plot",
            str(plot),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "mode E_Mp  policy overshoot:E_Mp" in res.output and "mode E_tr  policy rise_time:E_tr" in res.output
    assert res.output.count("initial states succeed") == 2 and plot.read_bytes()[:4] == b"\x89PNG"
    assert "braking at the bound from the states handed over to E_Mp" in res.output
    res = CliRunner().invoke(
        compose_cmd,
        [
            str(d / "overshoot_rise_time.mitl"),
            "--policy",
            str(tmp_path / "rise"),
            "--policy",
            str(tmp_path / "over"),
            "--initial-states",
            "2",
            "--handover-trials",
            "2",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "retrained overshoot's modes for 2 trials from the handed-over states, exploring with 2 N" in res.output
    assert res.output.count("initial states succeed") == 2
    res = CliRunner().invoke(
        compose_cmd,
        [
            str(d / "overshoot_rise_time.mitl"),
            "--policy",
            str(tmp_path / "rise"),
            "--policy",
            str(tmp_path / "over"),
            "--initial-states",
            "2",
            "--handover-trials",
            "2",
            "--handover-sigma",
            "0.5",
        ],
    )
    assert res.exit_code == 0 and "exploring with 0.5 N" in res.output
    res = CliRunner().invoke(
        compose_cmd,
        [
            str(d / "overshoot_rise_time.mitl"),
            "--policy",
            str(tmp_path / "rise"),
            "--policy",
            str(tmp_path / "over"),
            "--handover-sigma",
            "-1",
        ],
    )
    assert res.exit_code == 2 and "--handover-sigma" in res.output and "Traceback" not in res.output
    res = CliRunner().invoke(compose_cmd, [str(d / "overshoot_rise_time.mitl"), "--policy", str(tmp_path / "over")])
    assert res.exit_code == 2
    assert "overshoot_rise_time.mitl: error: no learned policy for mode(s) I, E_tr" in res.output


def test_simulate_judges_hyrl_policies_alone_and_composed(spec_dir, tmp_path):
    from mitlc.cli.train import simulate
    from mitlc.hybrid.criteria import measure
    from mitlc.learn.hyrl import compose
    from mitlc.spec.parse import load_spec

    md = spec_dir / "mass_damper"
    over, rise = tmp_path / "over", tmp_path / "rise"
    train_hybrid_cli(md / "overshoot.mitl", runs=2, trials=3, seed=1, out=over, progress=False, n_init=3)
    train_hybrid_cli(md / "rise_time.mitl", runs=2, trials=3, seed=2, out=rise, progress=False, n_init=3)
    runner = CliRunner()

    res = runner.invoke(simulate, ["--policy", str(over), "--rollouts", "4", "--seed", "3"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert len(lines) == 5
    assert lines[-1].endswith("rollouts meet overshoot and stabilise (fresh starts drawn from the initial set, seed 3)")
    # the same rollouts by hand: initial states from the seed, rollout i on run i mod 2, the checker
    learner = load_learner(over / "params.npz")
    rng = np.random.default_rng(3)
    x0 = np.stack([rng.uniform(-1, 1, 4), rng.uniform(0, 0, 4)], axis=1)
    ro = learner.rollout(x0, np.arange(4) % 2)
    m = measure(ro.states[:, :, 0], ro.dt, 0.0)
    for i, line in enumerate(lines[:4]):
        assert line.startswith(f"rollout   {i} (run   {i % 2}, q0={x0[i, 0]:.3f}")
        assert f"overshoot {m.overshoot[i]:.3g} " in line
        assert f"return {ro.returns[i]:.1f}" in line
    assert not (over / "simulate.png").exists()  # a figure only when asked for (--plot)

    # --starts train: the evenly spaced initial states the training judged, and its number again
    res = runner.invoke(simulate, ["--policy", str(over), "--starts", "train"])
    assert res.exit_code == 0, res.output
    m = json.loads((over / "metrics.json").read_text())
    *per_run, last = res.output.splitlines()
    assert last.startswith(f"success rate {m['success_rate']:.2f} (3 initial states per run, as mitlc train judged")
    assert [line.startswith(f"run {r:3d}: 3/3 ") for r, line in enumerate(per_run)] == m["runs_succeeding"]
    res = runner.invoke(simulate, ["--policy", str(over), "--starts", "train", "--rollouts", "2"])
    assert res.exit_code == 2 and "leave out --rollouts" in res.output

    combined = md / "overshoot_rise_time.mitl"
    plot = tmp_path / "composed.png"
    res = runner.invoke(
        simulate,
        ["--policy", str(rise), "--policy", str(over), "--spec", str(combined), "--rollouts", "3", "--plot", str(plot)],
    )
    assert res.exit_code == 0, res.output
    assert "rise_time" in res.output and "overshoot" in res.output and plot.is_file()
    ctl = compose(load_spec(combined), [load_learner(rise / "params.npz"), learner])
    rng = np.random.default_rng(0)
    x0 = np.stack([rng.uniform(-1, -0.5, 3), rng.uniform(0, 0, 3)], axis=1)
    ro = ctl.rollout(x0, np.arange(3) % 2)
    for i, line in enumerate(res.output.splitlines()[:3]):
        assert f"return {ro.returns[i]:.1f}" in line

    res = runner.invoke(simulate, ["--policy", str(rise), "--policy", str(over)])
    assert res.exit_code == 2 and res.output.strip() == (
        "--spec: error: name the combined spec to run several HyRL policies on"
    )


def test_train_parses_the_spec_once_fresh_and_resumed(spec_dir, tmp_path, monkeypatch):
    """``mitlc train`` on a require spec reads it once, also on --resume (the HyRL entry
    point and the checkpoint loader take the parsed spec instead of the text again)."""
    import mitlc.spec.parse as parse_mod
    from mitlc.cli import main

    calls: list[str] = []
    real = parse_mod.parse_spec

    def counted(*a, **k):  # load_spec reads the file and calls this
        calls.append(str(k.get("path") or (a[1] if len(a) > 1 else "")))
        return real(*a, **k)

    monkeypatch.setattr(parse_mod, "parse_spec", counted)
    spec = str(spec_dir / "mass_damper" / "overshoot.mitl")
    out = tmp_path / "o"
    args = ["train", "--plant", "mass-damper", "--spec", spec, "--runs", "1", "--trials", "2", "-q", "--no-plots"]
    res = CliRunner().invoke(main, [*args, "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert len(calls) == 1, calls
    calls.clear()
    res = CliRunner().invoke(main, ["train", "--resume", str(out), "--trials", "3", "-q", "--no-plots"])
    assert res.exit_code == 0, res.output
    assert len(calls) == 1, calls
