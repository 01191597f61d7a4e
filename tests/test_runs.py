"""A training folder is used again as it is (issue 28): a default ``--out`` never lands on
another run, and an occupied ``--out`` of another spec is refused."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from click.testing import CliRunner

from mitlc.cli.main import main
from mitlc.cli.outputs import read_manifest
from tests.conftest import P2_SHORT


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


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
    assert set(first) == {"manifest.json", "metrics.json", "params.npz", "learning_curve.png", "rollout.png"}
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
    r = run("train", "--spec", a, "--runs", 3, "--trials", 1, "-q", "--no-plots", "--out", "runs/p2_avoid_1")
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in Path("runs/p2_avoid_1").iterdir()) == ["manifest.json", "metrics.json", "params.npz"]
    assert read_manifest(Path("runs/p2_avoid_1"))["runs"] == 3


def test_an_unwritable_runs_folder_is_one_line(tmp_path, monkeypatch, short_spec) -> None:
    monkeypatch.chdir(tmp_path)
    Path("runs").write_text("a file, not a folder")
    r = run("train", "--spec", short_spec, "--runs", 1, "--trials", 1, "-q")
    assert r.exit_code == 2 and r.output.strip() == (
        "--out: error: cannot create the output folder runs: runs is a file"
    )
