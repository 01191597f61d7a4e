"""Fuzzing what mitlc writes with filesystem faults (issue 29).

A fault (``ENOSPC``, ``EIO``, ``EROFS``, ``EDQUOT``, ``EPERM``) is injected at the n-th call of one
kind (creating a file, ``write``, ``fsync``, a rename, a hard link; :class:`tests.faults.Faults`)
under the output folder of a small ``mitlc train --runs 1 --trials 2`` or the folder of
``mitlc compile -o``. Whatever the fault, the command ends with exit 0 or one error line and exit 2,
never a traceback, and afterwards the folder holds either the old complete set (file) or the new
complete set (file), never a mix, never a temporary file or a lock. A training whose set could not
be written says where it went instead, and that folder holds the new set, complete.

The real thing, a full or read-only tmpfs, is in tests/test_writing.py (where the tests may mount one).
"""

from __future__ import annotations

import errno
import hashlib
import json
import re
import shutil
import tempfile
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.cli import main
from mitlc.cli.outputs import LOCK, MANIFEST, read_manifest
from tests.conftest import P2_SHORT
from tests.faults import OPS, Faults, temp_files

ROOT = Path(__file__).resolve().parents[1]
P2 = str(ROOT / "specs/pendulum/p2_avoid.mitl")
ERRORS = (errno.ENOSPC, errno.EIO, errno.EROFS, errno.EDQUOT, errno.EPERM)


def run(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args], prog_name="mitlc")


def assert_clean(result) -> None:
    """Exit 0, or exit 2 with one error line; never a traceback."""
    exc = result.exception
    assert exc is None or isinstance(exc, SystemExit), f"{type(exc).__name__}: {exc}\n{result.output}"
    assert "Traceback" not in result.output
    assert result.exit_code in (0, 2), result.output
    if result.exit_code == 2:
        lines = result.output.strip().splitlines()
        assert len(lines) == 1 and ": error: " in lines[0], result.output


VIEWS = {"report.html", "curves.csv"}
"""mitlc report's views of a training (docs/report.md), written outside its set: left out of the snapshots,
and checked apart (:func:`report_seed`)."""


def snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in folder.rglob("*")
        if p.is_file() and p.name not in VIEWS
    }


def report_seed(folder: Path) -> object:
    """The seed of the training the folder's report.html shows ("none" without one): a report is of
    the set the folder holds, or there is none."""
    path = folder / "report.html"
    if not path.exists():
        return "none"
    data = re.search(r'id="report-data">(.*?)</script>', path.read_text(encoding="utf-8"), re.S)
    return json.loads(data.group(1))["summary"]["seed"] if data else "not a report"


def complete_set(folder: Path, seed: int, state: str = "complete") -> bool:
    """``folder`` holds one training's complete set of ``seed``: a manifest saying so, every file it lists
    matching its hash, and nothing else. ``state="checkpoint"``: a checkpoint of that training written
    over an earlier set, whose other files the manifest lists as ``earlier`` (to be replaced by the
    training's set, or continued with ``--resume``)."""
    manifest = read_manifest(folder)
    if manifest is None or manifest["state"] != state or manifest["seed"] != seed:
        return False
    files = snapshot(folder)
    listed = {**manifest["files"], MANIFEST: files[MANIFEST]}
    if state == "checkpoint":
        return {k: files[k] for k in listed if k in files} == listed and set(files) <= {*listed, *manifest["earlier"]}
    return files == listed


@pytest.fixture(scope="module")
def earlier(tmp_path_factory) -> tuple[Path, Path]:
    """The spec, and a folder holding a training of it with seed 1 (pictures and all)."""
    root = tmp_path_factory.mktemp("earlier")
    spec = root / "p2_short.mitl"
    spec.write_text(P2_SHORT)
    r = run("train", "--spec", spec, "--runs", 1, "--trials", 2, "-q", "--seed", 1, "--out", root / "d")
    assert r.exit_code == 0, r.output
    return spec, root / "d"


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    op=st.sampled_from(OPS),
    n=st.integers(1, 12),
    err=st.sampled_from(ERRORS),
    plots=st.booleans(),
    checkpoints=st.booleans(),
)
def test_a_training_set_is_old_or_new_whatever_write_fails(tmp_path_factory, earlier, op, n, err, plots, checkpoints):
    spec, template = earlier
    work = Path(tempfile.mkdtemp(dir=tmp_path_factory.getbasetemp()))
    d, rescue = work / "d", work / "rescue"
    shutil.copytree(template, d)
    rescue.mkdir()
    old = snapshot(d)
    args = ["train", "--spec", spec, "--runs", 1, "--trials", 2, "-q", "--seed", 2, "--out", d]
    args += [] if plots else ["--no-plots"]
    args += ["--checkpoint-every", "1e-9"] if checkpoints else []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("tempfile.tempdir", str(rescue))
        faults = Faults(mp, d, op, n, err)
        r = run(*args)
    assert_clean(r)
    assert temp_files(d) == [] and not (d / LOCK).exists()
    if r.exit_code == 0:
        assert complete_set(d, 2), (faults.counts, r.output)
        assert report_seed(d) in ("none", 2) and (report_seed(d) == 2 or not plots or faults.fired)
    else:
        assert faults.fired
        saved = re.search(r"they are saved in (\S+)", r.output)
        if saved is not None:  # the set could not go into d: d keeps the old one (or a checkpoint of the new)
            assert snapshot(d) == old or (checkpoints and complete_set(d, 2, "checkpoint")), faults.counts
            assert report_seed(d) in ("none", 1)  # the earlier training's, which the folder holds
            assert complete_set(Path(saved.group(1)), 2)  # and the rescue folder the new one
        else:  # the lock could not be written: refused before training
            assert snapshot(d) == old and r.output.startswith(f"--out: error: cannot write into {d}: ")
    shutil.rmtree(work)


@pytest.fixture(scope="module")
def compiled(tmp_path_factory) -> dict[str, bytes]:
    """What ``compile --format F`` writes, by format."""
    root = tmp_path_factory.mktemp("compiled")
    out = {}
    for fmt in ("text", "json", "dot"):
        assert run("compile", P2, "--format", fmt, "-o", root / fmt).exit_code == 0
        out[fmt] = (root / fmt).read_bytes()
    return out


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    op=st.sampled_from(OPS),
    n=st.integers(1, 5),
    err=st.sampled_from(ERRORS),
    fmt=st.sampled_from(["text", "json", "dot"]),
    exists=st.booleans(),
)
def test_compile_o_leaves_the_old_file_or_the_new_whatever_write_fails(
    tmp_path_factory, compiled, op, n, err, fmt, exists
):
    work = Path(tempfile.mkdtemp(dir=tmp_path_factory.getbasetemp()))
    target = work / "net.out"
    if exists:
        target.write_bytes(b"old")
    with pytest.MonkeyPatch.context() as mp:
        faults = Faults(mp, work, op, n, err)
        r = run("compile", P2, "--format", fmt, "-o", target)
    assert_clean(r)
    assert temp_files(work) == []
    if r.exit_code == 0:
        assert target.read_bytes() == compiled[fmt]
    else:
        assert faults.fired and r.output.startswith(f"-o {target}: error: ")
        assert (target.read_bytes() == b"old") if exists else not target.exists()
        assert sorted(p.name for p in work.iterdir()) == (["net.out"] if exists else [])
    shutil.rmtree(work)
