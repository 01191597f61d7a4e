"""A training folder is used again as it is (issue 28): it remembers its plant file, a default
``--out`` never lands on another run, an occupied ``--out`` of another spec is refused, and
``train`` and ``simulate`` say which initial states they judged."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import mitlc
from mitlc.cli.main import main
from mitlc.cli.outputs import read_manifest
from mitlc.plants import PLANTS
from tests.conftest import P2_SHORT

ROOT = Path(__file__).resolve().parent.parent
CART = ROOT / "examples" / "cart" / "cart_plant.py"
RAIL_SPEC = """\
plant rail_t
init x in [-0.2, 0.2], v = 0
horizon 1
prop there = abs(x - 0.3) < 0.2
formula F[0,1] G there
"""


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


pytestmark = pytest.mark.usefixtures("forget_user_plants")  # tests/conftest.py


# ---------------------------------------------------------------- item 2: the plant


def test_a_run_remembers_its_plant_file(tmp_path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    plant_file = src / "rail_plant.py"
    text = CART.read_text().replace('name="cart"', 'name="rail_t"')
    plant_file.write_text(text)
    spec = tmp_path / "rail.mitl"
    spec.write_text(RAIL_SPEC)
    out = tmp_path / "run"
    r = run("train", "--plant-file", plant_file, "--spec", spec, "--runs", 3, "--trials", 4, "--out", out, "-q")
    assert r.exit_code == 0, r.output
    copy = out / "plants" / "rail_plant.py"
    assert copy.read_bytes() == plant_file.read_bytes()
    manifest = read_manifest(out)
    assert manifest["plant"] == {
        "name": "rail_t",
        "kind": "file",
        "path": str(plant_file.resolve()),
        "attr": "",
        "sha256": sha(plant_file.read_bytes()),
        "file": "plants/rail_plant.py",
    }
    assert manifest["files"]["plants/rail_plant.py"] == sha(plant_file.read_bytes())
    assert manifest["spec"] == str(spec) and manifest["spec_sha256"] == sha(RAIL_SPEC.encode())
    before = run("simulate", "--policy", out, "--rollouts", 5)
    assert before.exit_code == 0, before.output

    # the plant file moved away and the plant forgotten: only the folder knows it now
    plant_file.rename(src / "elsewhere.py")
    del PLANTS["rail_t"]
    assert "unknown plant 'rail_t'" in run("compile", spec).output
    after = run("simulate", "--policy", out, "--rollouts", 5)
    assert after.exit_code == 0, after.output
    assert after.output == before.output  # the same policy on the same plant: the same verdicts, no note
    verdicts = [line for line in after.output.splitlines() if line.startswith("rollout ")]
    assert len(verdicts) == 5
    k = sum("satisfied" in line for line in verdicts)
    assert f"{k}/5 rollouts satisfy F[0,1] G there (fresh starts drawn from the initial set, seed 0)" in after.output

    del PLANTS["rail_t"]
    r = run("train", "--resume", out, "--trials", 7, "-q", "--no-plots")
    assert r.exit_code == 0, r.output
    assert json.loads((out / "metrics.json").read_text())["trials"] == 7
    assert read_manifest(out)["plant"]["path"] == str(plant_file.resolve())  # still the original's path
    assert copy.read_bytes() == text.encode() and "plants/rail_plant.py" in read_manifest(out)["files"]

    del PLANTS["rail_t"]
    pol = mitlc.load_policy(out)
    assert pol.spec.plant_name == "rail_t" and pol.runs == 3
    x = np.array([[0.0, 0.0], [0.1, 0.0]])
    assert pol.act(x, pol.reset(x)).shape == (2,)

    # the original back, but edited since: the run's copy is what it was trained with, and a note says so
    (src / "elsewhere.py").rename(plant_file)
    plant_file.write_text(text.replace('(u - p["b"] * v)', '(2 * u - p["b"] * v)'))
    del PLANTS["rail_t"]
    r = run("simulate", "--policy", out, "--rollouts", 1)
    assert r.exit_code == 0, r.output
    assert f"note: {plant_file.resolve()} changed since the training; using the run's copy {copy}" in r.output
    del PLANTS["rail_t"]
    with pytest.warns(UserWarning, match="changed since the training"):
        mitlc.load_policy(out)

    # a copy changed after the training is refused, not run
    del PLANTS["rail_t"]
    copy.write_text("raise SystemExit('ran the changed copy')\n")
    r = run("simulate", "--policy", out)
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert r.output.strip() == (
        f"{out / 'params.npz'}: error: the run's copy of its plant file plants/rail_plant.py was changed after "
        "the training (its SHA-256 differs)"
    )


# ---------------------------------------------------------------- item 3: nothing overwritten


def test_the_default_out_is_numbered_and_never_lands_on_another_run(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    a = tmp_path / "pendulum" / "p2_avoid.mitl"
    b = tmp_path / "unit_weights" / "p2_avoid.mitl"
    for path, text in ((a, P2_SHORT), (b, P2_SHORT.replace("10 * G", "G"))):
        path.parent.mkdir()
        path.write_text(text)
    common = ("--runs", 2, "--trials", 2, "-q")
    r1 = run("train", "--spec", a, *common)
    assert r1.exit_code == 0 and r1.output.strip().endswith("results in runs/p2_avoid_1"), r1.output
    first = {p.name: p.read_bytes() for p in Path("runs/p2_avoid_1").iterdir()}
    assert set(first) == {"manifest.json", "metrics.json", "params.npz", "learning_curve.png", "rollout.png"} | {
        "report.html",  # not in the manifest: mitlc report writes them, after the set (mitlc docs report)
        "curves.csv",
    }
    r2 = run("train", "--spec", b, *common, "--no-plots")
    assert r2.exit_code == 0 and r2.output.strip().endswith("results in runs/p2_avoid_2"), r2.output
    assert run("train", "--spec", a, *common).output.strip().endswith("results in runs/p2_avoid_3")
    assert {p.name: p.read_bytes() for p in Path("runs/p2_avoid_1").iterdir()} == first  # untouched
    assert json.loads(Path("runs/p2_avoid_2/metrics.json").read_text())["formula"] == "F G kappa & G !psi"
    assert read_manifest(Path("runs/p2_avoid_2"))["spec_sha256"] == sha(b.read_bytes())

    # an explicit --out that holds a training of another spec is refused, and left as it was
    r = run("train", "--spec", b, *common, "--out", "runs/p2_avoid_1")
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert r.output.strip() == (
        f"--out: error: runs/p2_avoid_1 holds a training of {a}; give another --out, or continue it with "
        "mitlc train --resume runs/p2_avoid_1"
    )
    assert {p.name: p.read_bytes() for p in Path("runs/p2_avoid_1").iterdir()} == first

    # the same spec again is a re-run: its set replaces the earlier one, nothing of that one is left
    assert run("simulate", "--policy", "runs/p2_avoid_1").exit_code == 0  # writes nothing into the folder
    r = run("train", "--spec", a, "--runs", 3, "--trials", 1, "-q", "--no-plots", "--out", "runs/p2_avoid_1")
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in Path("runs/p2_avoid_1").iterdir()) == ["manifest.json", "metrics.json", "params.npz"]
    assert read_manifest(Path("runs/p2_avoid_1"))["runs"] == 3


def test_a_training_from_before_the_format_key_is_continued_not_overwritten(tmp_path, short_spec) -> None:
    out = tmp_path / "old"
    assert (
        run("train", "--spec", short_spec, "--runs", 2, "--trials", 2, "-q", "--no-plots", "--out", out).exit_code == 0
    )
    manifest = json.loads((out / "manifest.json").read_text())
    del manifest["format"], manifest["version"]  # as mitlc wrote it before the key
    (out / "manifest.json").write_text(json.dumps(manifest))
    r = run("train", "--spec", short_spec, "--runs", 2, "--trials", 2, "-q", "--no-plots", "--out", out)
    assert r.exit_code == 2 and "holds files that are not a mitlc training" in r.output
    r = run("train", "--resume", out, "--trials", 5, "-q", "--no-plots")  # its own checkpoint, continued
    assert r.exit_code == 0, r.output
    assert json.loads((out / "metrics.json").read_text())["trials"] == 5
    assert read_manifest(out)["format"] == "mitlc-run"


def test_an_unwritable_runs_folder_is_one_line(tmp_path, monkeypatch, short_spec) -> None:
    monkeypatch.chdir(tmp_path)
    Path("runs").write_text("a file, not a folder")
    r = run("train", "--spec", short_spec, "--runs", 1, "--trials", 1, "-q")
    assert r.exit_code == 2 and r.output.strip() == (
        "--out: error: cannot create the output folder runs: runs is a file"
    )


# ---------------------------------------------------------------- item 8: which starts


def test_train_and_simulate_say_which_starts_they_judged(short_spec, tmp_path) -> None:
    out = tmp_path / "pol"
    r = run("train", "--spec", short_spec, "--runs", 4, "--trials", 200, "--out", out, "-q", "--no-plots")
    assert r.exit_code == 0, r.output
    m = json.loads((out / "metrics.json").read_text())
    rate, satisfied = m["success_rate"], m["satisfied"]
    assert f"success rate {rate:.2f} (one evaluation start per run; monitor: F G kappa & 10 * G !psi)" in r.output
    assert np.array(m["evaluation_starts"]).shape == (4, 2)

    # --starts train: the very starts and verdicts of the training, hence its number
    r = run("simulate", "--policy", out, "--starts", "train")
    assert r.exit_code == 0, r.output
    *lines, last = r.output.splitlines()
    assert len(lines) == 4
    for i, line in enumerate(lines):
        q, qdot = m["evaluation_starts"][i]
        assert line.startswith(f"rollout   {i} (run   {i}, q={q:.3f}, qdot={qdot:.3f}): ")
        assert ("satisfied" in line) == satisfied[i]
    assert last == (
        f"{sum(satisfied)}/4 rollouts satisfy F G kappa & 10 * G !psi (each run's evaluation start, as mitlc train "
        "judged)"
    )

    # fresh starts (the default) say so, and where their share differs from the training's, both are printed
    r = run("simulate", "--policy", out, "--rollouts", 5)
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    k = sum("satisfied" in line for line in lines if line.startswith("rollout "))
    assert k / 5 != rate  # these seeds: 4/5 fresh against 3/4 in training
    assert lines[-2:] == [
        f"{k}/5 rollouts satisfy F G kappa & 10 * G !psi (fresh starts drawn from the initial set, seed 0)",
        f"from each run's evaluation start, as mitlc train judged: {sum(satisfied)}/4 (success rate {rate:.2f}; "
        "--starts train shows them)",
    ]

    r = run("simulate", "--policy", out, "--starts", "train", "--rollouts", 3)
    assert r.exit_code == 2 and r.output.strip() == (
        "--rollouts: error: --starts train judges each of the 4 runs from its own evaluation start: "
        "--rollouts must be 4 (or left out)"
    )


def test_the_same_share_prints_one_line(short_spec, tmp_path) -> None:
    out = tmp_path / "pol"
    r = run("train", "--spec", short_spec, "--runs", 2, "--trials", 2, "--out", out, "-q", "--no-plots")
    assert r.exit_code == 0, r.output
    assert json.loads((out / "metrics.json").read_text())["success_rate"] == 0.0
    r = run("simulate", "--policy", out, "--rollouts", 3)
    assert r.exit_code == 0 and r.output.splitlines()[-1].startswith("0/3 rollouts satisfy")
    assert not re.search("as mitlc train judged", r.output)
