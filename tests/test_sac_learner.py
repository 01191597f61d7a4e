"""``mitlc train --learner sac``: Stable-Baselines3's SAC run by run on the compiled reward
(mitlc.gym.sac), its output set, ``mitlc simulate`` and ``mitlc.gym.load_policy`` on it, and its
bad input (one line, exit 2)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli.main import main
from mitlc.errors import InputError

EASY = """plant mass-damper
init q in [-1, -0.5], qdot = 0
horizon 1
prop near = abs(q) < 0.2
formula F[0,0.8] G near
"""

SMALL = ["--set", "learning_starts=20", "--set", "net=16x16", "--set", "batch_size=32"]


def _spec(tmp_path: Path, text: str = EASY) -> Path:
    p = tmp_path / "easy.mitl"
    p.write_text(text)
    return p


def _train(tmp_path: Path, *extra: str, out: str = "out") -> tuple[int, str, Path]:
    r = CliRunner().invoke(
        main,
        ["train", "--spec", str(_spec(tmp_path)), "--learner", "sac", "--out", str(tmp_path / out), "-q", *extra],
    )
    return r.exit_code, r.output, tmp_path / out


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--sigma", "1"], "--sigma"),
        (["--mask", "next"], "--mask"),
        (["--no-race"], "--no-race"),
        (["--preset", "thesis"], "--preset"),
        (["--penalty-ramp", "0.5"], "--penalty-ramp"),
        (["--set", "net=0x4"], "--set"),
        (["--set", "gama=0.9"], "--set"),
        (["--set", "gamma=1.5"], "--set"),
    ],
)
def test_options_that_are_not_sacs_are_one_line(tmp_path: Path, extra: list[str], named: str) -> None:
    code, output, out = _train(tmp_path, *extra)
    assert code == 2, output
    lines = [ln for ln in output.splitlines() if ln.strip()]
    assert len(lines) == 1 and named in lines[0], output
    assert "Traceback" not in output and not out.exists()


def test_a_misspelt_setting_is_named_with_the_close_one(tmp_path: Path) -> None:
    code, output, _ = _train(tmp_path, "--set", "gama=0.9")
    assert code == 2 and "did you mean 'gamma'" in output, output


def test_a_require_spec_or_a_gymnasium_spec_is_refused(tmp_path: Path) -> None:
    hyrl = CliRunner().invoke(
        main,
        ["train", "--spec", "specs/mass_damper/overshoot.mitl", "--learner", "sac", "-q", "--out", str(tmp_path / "h")],
    )
    assert hyrl.exit_code == 2 and "--learner sac takes a formula" in hyrl.output, hyrl.output
    gym_spec = _spec(
        tmp_path,
        "plant gym:Pendulum-v1\nstate q = atan2(obs[1], obs[0]), qdot = obs[2]\nhorizon 2\n"
        "prop up = abs(q) < 0.3\nformula F G up\n",
    )
    r = CliRunner().invoke(
        main, ["train", "--spec", str(gym_spec), "--learner", "sac", "-q", "--out", str(tmp_path / "g")]
    )
    assert r.exit_code == 2 and "Gymnasium environment" in r.output and "MitlRewardWrapper" in r.output, r.output
    assert not (tmp_path / "g").exists()


def test_without_stable_baselines3_the_extra_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # import fails as if not installed
    code, output, out = _train(tmp_path, "--runs", "1", "--trials", "1")
    assert code == 2 and "pip install 'mitlc[sb3]'" in output, output
    assert not out.exists()


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> Path:
    pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 and PyTorch: pip install 'mitlc[sb3]'")
    tmp = tmp_path_factory.mktemp("sac")
    code, output, out = _train(tmp, "--runs", "2", "--trials", "4", "--seed", "3", *SMALL)
    assert code == 0, output
    assert "2 SAC runs x 4 trials" in output
    return out


def test_the_output_set_holds_a_model_per_run_and_sacpns_metrics(trained: Path) -> None:
    names = sorted(p.name for p in trained.iterdir())
    assert names == [
        "learning_curve.png",
        "manifest.json",
        "metrics.json",
        "report.html",
        "rollout.png",
        "sac_000.zip",
        "sac_001.zip",
    ]
    m = json.loads((trained / "metrics.json").read_text())
    assert m["learner"] == "sac" and m["runs"] == 2 and m["trials"] == 4 and m["seed"] == 3
    assert np.asarray(m["returns"]).shape == (2, 4) and np.isfinite(m["returns"]).all()
    from mitlc.plants import PLANTS

    n = round(1.0 / PLANTS["mass-damper"].params({})["dt"])  # steps in the horizon of 1 s
    assert m["run_steps"] == 2 * 4 * n
    assert m["gamma"] == pytest.approx(1 - 3 / n)  # SACPN's rule
    assert m["settings"]["net"] == [16, 16] and m["settings"]["learning_starts"] == 20
    assert len(m["satisfied"]) == 2 and m["success_rate"] == np.mean(m["satisfied"])
    # each episode's return sums the compiled net's rewards, each in [-2, 2] for F[0,0.8] G near
    # ((1 + ~p_near) * (p_near - p_not_near) at most 2; p_near - p_not_near - 1 once failed, at least -2)
    assert all(-2 * n <= v <= 2 * n for row in m["returns"] for v in row)


def test_simulate_reproduces_the_training_verdicts_and_loads_through_gym(trained: Path) -> None:
    r = CliRunner().invoke(main, ["simulate", "--policy", str(trained), "--starts", "train"])
    assert r.exit_code == 0, r.output
    m = json.loads((trained / "metrics.json").read_text())
    k = sum(m["satisfied"])
    assert f"{k}/2 rollouts satisfy F[0,0.8] G near (each run's evaluation start, as mitlc train judged)" in r.output
    from mitlc.gym import load_policy
    from mitlc.learn.policy import load_policy as load_learned

    pol = load_policy(trained)
    assert pol.runs == 2
    ro = pol.learner.rollout(np.asarray(m["evaluation_starts"]))
    assert np.allclose(ro.returns, m["greedy_returns"], atol=1e-6)
    # the Policy interface steps the same numbers as the rollout
    x = np.asarray(m["evaluation_starts"], dtype=float)
    M = pol.reset(x)
    u = pol.act(x, M)
    assert np.allclose(u, ro.actions[:, 0])
    with pytest.raises(InputError, match="mitlc.gym.load_policy"):
        load_learned(trained)


def test_the_same_seed_gives_the_same_returns(trained: Path, tmp_path: Path) -> None:
    code, output, out = _train(tmp_path, "--runs", "2", "--trials", "4", "--seed", "3", *SMALL)
    assert code == 0, output
    a = json.loads((trained / "metrics.json").read_text())
    b = json.loads((out / "metrics.json").read_text())
    assert a["returns"] == b["returns"] and a["satisfied"] == b["satisfied"]


def test_sac_learns_a_reach_and_stay_in_3300_samples(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 and PyTorch: pip install 'mitlc[sb3]'")
    code, output, out = _train(
        tmp_path, "--runs", "2", "--trials", "100", "--set", "net=64x64", "--set", "learning_starts=200"
    )
    assert code == 0, output
    m = json.loads((out / "metrics.json").read_text())
    assert m["success_rate"] == 1.0, m["satisfied"]
    first, last = np.asarray(m["returns"])[:, :5].mean(), np.asarray(m["returns"])[:, -5:].mean()
    assert last > first + 10, (first, last)
