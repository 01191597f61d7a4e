"""Every example in examples/ runs (train_sb3.py where Stable-Baselines3 and PyTorch are installed, as in CI), and the
documentation's examples are real: docs/python.md as doctests (the pages' commands: test_docs_pages.py)."""

from __future__ import annotations

import doctest
import importlib.util
import json
import os
import py_compile
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import mitlc
from mitlc.petri.export import to_dict
from mitlc.petri.render import to_digraph

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
HAS_GYM = importlib.util.find_spec("gymnasium") is not None
HAS_DOT = shutil.which("dot") is not None
TESTED = {"compile_and_render.py", "wrap_pendulum_v1.py", "train_sb3.py", "train_pendulum.py"}


def run_example(name: str, *args: str, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(EXAMPLES / name), *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, "SDL_VIDEODRIVER": "dummy"},
    )


def test_every_example_is_tested() -> None:
    present = {p.name for p in EXAMPLES.glob("*.py")}
    assert present == TESTED, "every example needs a test here"


# ------------------------------------------------------------------ compile_and_render.py


def test_compile_and_render(tmp_path: Path) -> None:
    r = run_example("compile_and_render.py", "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "formula:  F G kappa & 10 * G !psi"
    assert lines[2] == "places:   p_kappa, p_psi, p_none_kappa_psi"
    assert lines[3] == "M0:       [0, 0, 1]"
    assert "  t1: p_kappa -> p_psi when psi" in lines
    assert lines[-2] == (
        "reward:   min((1 + ~p_kappa) * (p_kappa - (p_psi + p_none_kappa_psi)), "
        "10 * (1 + (~p_kappa + ~p_none_kappa_psi)) * ((p_kappa + p_none_kappa_psi) - p_psi))"
    )
    out = tmp_path / "out"
    rs = mitlc.compile_spec(mitlc.load_spec(ROOT / "specs" / "pendulum" / "p2_avoid.mitl"))
    assert (out / "p2_avoid.dot").read_text() == to_digraph(rs).source
    assert json.loads((out / "p2_avoid.json").read_text())["D"] == to_dict(rs)["D"]
    if HAS_DOT:
        assert (out / "p2_avoid.svg").read_text().lstrip().startswith(("<?xml", "<svg"))
        assert lines[-1] == f"wrote p2_avoid.dot, p2_avoid.json, p2_avoid.svg to {out}"


def test_compile_and_render_bad_spec(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mitl"
    bad.write_text("prop a = x < 1\nformula F G b\n")
    r = run_example("compile_and_render.py", str(bad), "--out", str(tmp_path), cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr.splitlines()[0] == f"{bad}:2:13: error: undefined proposition 'b'"
    assert "Traceback" not in r.stderr


# ------------------------------------------------------------------ wrap_pendulum_v1.py


@pytest.mark.skipif(not HAS_GYM, reason="needs the gym extra")
def test_wrap_pendulum_v1(tmp_path: Path) -> None:
    r = run_example("wrap_pendulum_v1.py", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "spec p1_swing_up.mitl: F G kappa"
    assert lines[1] == "places p_kappa, p_not_kappa; dt = 0.05 s; horizon 3.0 s"
    steps = [line for line in lines if line.startswith("tau ")]
    assert len(steps) == 61  # x_0 .. x_60: 3 s of 0.05 s
    assert steps[0] == "tau  0.00  q +0.074  M p_kappa"
    rewards = [float(line.split(" r ")[1].split()[0]) for line in steps[1:]]
    assert rewards[:6] == [2.0, 2.0, 2.0, -2.0, -1.0, -1.0]
    assert lines[-2].startswith(f"return {sum(rewards):+.2f} (Pendulum-v1's own reward would give ")
    if importlib.util.find_spec("mitlc.monitor") is not None:
        assert lines[-1].startswith("monitor: violated at 3.0 s by F G kappa, robustness ")


@pytest.mark.skipif(not HAS_GYM, reason="needs the gym extra")
def test_wrap_pendulum_v1_box_and_timed_spec(tmp_path: Path) -> None:
    r = run_example(
        "wrap_pendulum_v1.py",
        str(ROOT / "specs" / "pendulum" / "p5_timed_visit.mitl"),
        "--seed",
        "4",
        "--marking-obs",
        "box",
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    steps = [line for line in r.stdout.splitlines() if line.startswith("tau ")]
    timeline = [line.split(" M ")[1].split(",")[0] for line in steps]
    # the timeline token moves at tau > 1 and tau > 2 (net C-5)
    assert timeline[20] == "p_tau<=1" and timeline[21] == "p_1<tau<=2"
    assert timeline[40] == "p_1<tau<=2" and timeline[41] == "p_tau>2"


# ------------------------------------------------------------------ train_pendulum.py


def test_train_pendulum(tmp_path: Path) -> None:
    """The example's numbers are the trainer's: recomputed here with the same seed."""
    import numpy as np

    from mitlc.learn.sacpn import Sacpn, SacpnSettings
    from mitlc.monitor.offline import monitor

    out = tmp_path / "out"
    r = run_example(
        "train_pendulum.py",
        "--trials",
        "300",
        "--runs",
        "2",
        "--report",
        "3",
        "--seed",
        "7",
        "--out",
        str(out),
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "spec p1_swing_up.mitl: F G kappa"
    assert lines[1] == "2 runs x 300 trials of 100 steps (dt = 0.03 s), seed 7"

    rs = mitlc.compile_spec(mitlc.load_spec(ROOT / "specs" / "pendulum" / "p1_swing_up.mitl"))
    agent = Sacpn(rs, SacpnSettings(), runs=2, seed=7)
    for k, line in enumerate(lines[2:5]):
        returns = agent.train(100)
        assert line == f"trials {100 * (k + 1):5d}: mean return of the last 100 {returns.mean():+9.2f}"
    rollout = agent.rollout(agent.evaluation_states())
    verdict = monitor(rs.spec, rollout.states, rollout.dt)
    for run in range(2):
        assert lines[5 + run].startswith(
            f"run {run}: greedy return {rollout.returns[run]:+8.2f}, robustness {verdict.robustness[run]:+.3f}, "
        )
    assert lines[7] == f"satisfied {int(verdict.satisfied.sum())}/2"
    with np.load(out / "rollout.npz") as saved:
        np.testing.assert_array_equal(saved["states"], rollout.states)
        np.testing.assert_array_equal(saved["rewards"], rollout.rewards)
    with np.load(out / "params.npz") as saved:
        np.testing.assert_array_equal(saved["xi"], agent.xi)
        assert saved["returns"].shape == (2, 300)
    # the rollout file is a trace mitlc check reads: run 0's verdict
    from click.testing import CliRunner

    from mitlc.cli.main import main

    checked = CliRunner().invoke(
        main, ["check", str(ROOT / "specs" / "pendulum" / "p1_swing_up.mitl"), str(out / "rollout.npz")]
    )
    assert checked.exit_code == (0 if verdict.satisfied[0] else 1), checked.output


def test_train_pendulum_bad_spec(tmp_path: Path) -> None:
    bad = tmp_path / "noplant.mitl"
    bad.write_text("prop a = x < 1\nformula F a\n")
    r = run_example("train_pendulum.py", str(bad), "--trials", "1", cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "the spec names no plant" in r.stderr.splitlines()[0]


# ------------------------------------------------------------------ train_sb3.py


def test_train_sb3(tmp_path: Path) -> None:
    """With Stable-Baselines3 (CI installs it and PyTorch's CPU build) the example trains SAC briefly,
    saves the model and judges ten test episodes; without it, it says what to install."""
    py_compile.compile(str(EXAMPLES / "train_sb3.py"), cfile=str(tmp_path / "train_sb3.pyc"), doraise=True)
    if importlib.util.find_spec("stable_baselines3") is None:
        r = run_example("train_sb3.py", "--timesteps", "10", cwd=tmp_path)
        assert r.returncode == 1
        assert r.stderr.strip() == (
            "train_sb3.py needs Stable-Baselines3 (and PyTorch), which mitlc does not install: "
            "pip install stable-baselines3 'mitlc[gym]'"
        )
        return
    out = tmp_path / "sb"
    r = run_example("train_sb3.py", "--timesteps", "300", "--out", str(out), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "spec p1_swing_up.mitl: F G kappa"
    assert (out / "sac_p1_swing_up.zip").is_file()
    assert len([line for line in lines if line.startswith("test episode")]) == 10
    assert lines[-1].startswith("satisfied ") and lines[-1].endswith("/10")


# ------------------------------------------------------------------ the docs' examples


HAS_SB3 = importlib.util.find_spec("stable_baselines3") is not None
NEEDS_SB3 = doctest.register_optionflag("SB3")
"""``# doctest: +SB3`` on an example: its code block needs Stable-Baselines3, and is left out without it."""


def _doctest_page(name: str) -> doctest.TestResults:
    """Run a page's examples as doctest.testfile does; without Stable-Baselines3, leave out every code
    block with an example marked ``# doctest: +SB3``."""
    path = ROOT / "docs" / name
    text = path.read_text(encoding="utf-8")
    test = doctest.DocTestParser().get_doctest(text, {"__name__": "__main__"}, path.name, str(path), 0)
    if not HAS_SB3:
        block, fences = [], 0  # the code block of every line: the count of ``` fences above it
        for line in text.splitlines():
            fences += line.startswith("```")
            block.append(fences)
        needs = {block[ex.lineno] for ex in test.examples if ex.options.get(NEEDS_SB3)}
        test.examples = [ex for ex in test.examples if block[ex.lineno] not in needs]
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False)
    runner.run(test)
    runner.summarize(verbose=False)
    return doctest.TestResults(runner.failures, runner.tries)


@pytest.mark.skipif(not HAS_GYM, reason="docs/python.md shows the gym wrapper")
def test_python_md_examples_run(monkeypatch) -> None:
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    result = _doctest_page("python.md")
    assert result.failed == 0 and result.attempted >= 40


def test_monitor_md_examples_run(monkeypatch) -> None:
    monkeypatch.chdir(ROOT)
    result = _doctest_page("monitor.md")
    assert result.failed == 0 and result.attempted >= 5


# ------------------------------------------------------------------ docs/architecture.md


def _python_blocks(page: Path) -> list[str]:
    blocks, current = [], None
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.startswith("```python"):
            current = []
        elif line.startswith("```") and current is not None:
            blocks.append("\n".join(current))
            current = None
        elif current is not None:
            current.append(line)
    return blocks


@pytest.mark.parametrize("index", range(len(_python_blocks(ROOT / "docs" / "architecture.md"))))
def test_architecture_page_examples_run(index: int) -> None:
    """Each Python block of docs/architecture.md (a plant, a learner's loop, a sweep backend) runs as written."""
    code = _python_blocks(ROOT / "docs" / "architecture.md")[index]
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip()  # each block prints what it made


def test_architecture_figure_is_drawn_from_the_code(tmp_path: Path) -> None:
    """docs/make_architecture.py reads the imports and draws every stage."""
    if not HAS_DOT:
        pytest.skip("no Graphviz dot (.ci/run installs it)")
    r = subprocess.run(
        [sys.executable, str(ROOT / "docs" / "make_architecture.py"), "--out", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    svg = (tmp_path / "architecture.svg").read_text()
    assert (tmp_path / "architecture.png").read_bytes().startswith(b"\x89PNG")
    for stage in ("plants", "spec", "petri", "hybrid", "monitor", "learn", "sweep", "gym", "cli"):
        assert f">{stage}<" in svg, stage
