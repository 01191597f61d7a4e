"""Policies out of mitlc: ``simulate --trace`` writes what ``check`` reads, ``load_policy`` acts."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner

import mitlc
from mitlc.cli.main import main

ROOT = Path(__file__).resolve().parent.parent


def test_simulate_traces_are_checked_like_the_rollouts(tmp_path) -> None:
    run = tmp_path / "p1"
    r = CliRunner().invoke(
        main, ["train", "--spec", "pendulum/p1_swing_up", "--runs", "3", "--trials", "150", "--out", str(run), "-q"]
    )
    assert r.exit_code == 0, r.output
    for suffix in (".csv", ".npz"):
        base = tmp_path / f"ro{suffix}"
        sim = CliRunner().invoke(main, ["simulate", "--policy", str(run), "--rollouts", "3", "--trace", str(base)])
        assert sim.exit_code == 0, sim.output
        verdicts = ["satisfied" in line for line in sim.output.splitlines() if line.startswith("rollout")]
        assert len(verdicts) == 3
        for i, ok in enumerate(verdicts):
            trace = tmp_path / f"ro_{i:03d}{suffix}"
            got = CliRunner().invoke(main, ["check", "pendulum/p1_swing_up", str(trace), "--json"])
            assert got.exit_code == (0 if ok else 1), got.output
            assert json.loads(got.output)["samples"] == 101
    bad = CliRunner().invoke(main, ["simulate", "--policy", str(run), "--trace", str(tmp_path / "x.txt")])
    assert bad.exit_code == 2 and "--trace" in bad.output


def test_load_policy_acts_as_the_trainer_does(tmp_path) -> None:
    run = tmp_path / "p2"
    r = CliRunner().invoke(
        main, ["train", "--spec", "pendulum/p2_avoid", "--runs", "2", "--trials", "30", "--out", str(run), "-q"]
    )
    assert r.exit_code == 0, r.output
    pol = mitlc.load_policy(run)
    assert pol.spec.plant_name == "pendulum" and pol.runs == 2
    agent = pol.agent
    x0 = np.array([[2.8, 0.0], [3.0, 0.0]])
    ro = agent.rollout(x0)
    m = pol.reset(x0)
    x = x0.copy()
    for k in range(ro.actions.shape[1]):
        u = pol.act(x, m)
        np.testing.assert_array_equal(u, ro.actions[:, k])  # greedy: the same inputs, to the bit
        agent.integrate(x, u)
        m = pol.step(m, x)
    np.testing.assert_array_equal(x, ro.states[:, -1])


def test_load_policy_of_a_hyrl_run(tmp_path) -> None:
    run = tmp_path / "md"
    r = CliRunner().invoke(
        main, ["train", "--plant", "mass-damper", "--runs", "2", "--trials", "3", "--out", str(run), "-q"]
    )
    assert r.exit_code == 0, r.output
    pol = mitlc.load_policy(run)
    x0 = np.array([[-1.0, 0.0], [-0.7, 0.0]])
    state = pol.reset(x0)
    u = pol.act(x0, state)
    assert u.shape == (2,) and np.all(np.abs(u) <= pol.learner.u_max)
    mode, t, q0 = pol.step(state, x0 + 0.01)
    assert mode.shape == (2,) and np.array_equal(q0, x0[:, 0])
    missing = CliRunner().invoke(main, ["simulate", "--policy", str(tmp_path)])
    assert missing.exit_code == 2
