"""Outputs (#16): mitlc writes what it was asked to and touches nothing else."""

from __future__ import annotations

import os
import stat
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from mitlc.cli import main
from mitlc.errors import InputError
from mitlc.fileio import atomic_write

SPEC = "specs/pendulum/p1_swing_up.mitl"
ROOT = Path(__file__).resolve().parents[1]


def _char_device(path: Path) -> bool:
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))  # a /dev/null of our own
    except (PermissionError, OSError):
        return False
    return True


def test_a_character_device_is_written_not_replaced(tmp_path):
    dev = tmp_path / "null"
    if not _char_device(dev):
        pytest.skip("mknod needs CAP_MKNOD")
    r = CliRunner().invoke(main, ["compile", str(ROOT / SPEC), "-o", str(dev)])
    assert r.exit_code == 0, r.output
    assert stat.S_ISCHR(dev.stat().st_mode)  # still a device
    assert sorted(p.name for p in tmp_path.iterdir()) == ["null"]  # no temporary file left


def test_a_fifo_is_written_like_a_redirection(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    atomic_write(fifo, "hello\n")
    reader.join(10)
    assert got == [b"hello\n"] and stat.S_ISFIFO(fifo.stat().st_mode)


def test_a_symlink_stays_a_link_and_its_target_is_replaced_keeping_its_mode(tmp_path):
    target = tmp_path / "real.txt"
    target.write_text("old")
    target.chmod(0o640)
    link = tmp_path / "link.txt"
    link.symlink_to(target)
    atomic_write(link, "new")
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text() == "new" and stat.S_IMODE(target.stat().st_mode) == 0o640


def test_a_replaced_regular_file_keeps_its_mode(tmp_path):
    f = tmp_path / "out.json"
    f.write_text("{}")
    f.chmod(0o600)
    atomic_write(f, "[]")
    assert f.read_text() == "[]" and stat.S_IMODE(f.stat().st_mode) == 0o600


def test_a_directory_is_refused(tmp_path):
    with pytest.raises(InputError, match="a directory"):
        atomic_write(tmp_path, "x")


# ---------------------------------------------------------------- a training's output set

import json  # noqa: E402

import numpy as np  # noqa: E402

from mitlc.cli.outputs import LOCK, MANIFEST, OutputSet, read_manifest  # noqa: E402
from mitlc.learn.sacpn import Sacpn  # noqa: E402
from mitlc.petri.compile import compile_spec  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402

P2 = str(ROOT / "specs/pendulum/p2_avoid.mitl")


def _train(args, out):
    return CliRunner().invoke(main, ["train", "--spec", P2, "--runs", "2", "-q", "--out", str(out), *args])


def test_an_unwritable_out_fails_before_training(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("mine")
    r = _train(["--trials", "5"], afile / "sub")
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert f"--out: error: cannot create the output folder {afile / 'sub'}: {afile} is a file" in r.output
    assert afile.read_text() == "mine"


def test_a_failed_write_after_training_keeps_the_results(tmp_path, monkeypatch):
    import mitlc.cli.outputs as outputs

    out = tmp_path / "out"
    real = outputs.stage

    def full_disk(target, data, mode=None):
        if Path(target).parent == out and Path(target).name != MANIFEST:
            raise OSError(28, "No space left on device")
        return real(target, data, mode)

    monkeypatch.setattr(outputs, "stage", full_disk)
    monkeypatch.setattr(outputs.tempfile, "gettempdir", lambda: str(tmp_path / "rescue"))
    r = _train(["--trials", "4"], out)
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert "No space left on device" in r.output and "they are saved in" in r.output
    (saved,) = (tmp_path / "rescue").iterdir()
    assert f"mitlc train --resume {saved}" in r.output
    assert json.loads((saved / "metrics.json").read_text())["trials"] == 4
    assert read_manifest(saved)["state"] == "complete"
    assert not out.exists()  # the folder it created for the failed set is gone: no half set, no temporary file
    monkeypatch.setattr(outputs, "stage", real)
    r = CliRunner().invoke(main, ["train", "--resume", str(saved), "--trials", "6", "-q"])  # and it resumes
    assert r.exit_code == 0, r.output
    assert json.loads((saved / "metrics.json").read_text())["trials"] == 6


def test_the_set_is_one_training_and_its_manifest_is_written_last(tmp_path):
    out = tmp_path / "out"
    assert _train(["--trials", "3", "--seed", "1"], out).exit_code == 0
    first = read_manifest(out)
    assert first["state"] == "complete" and first["seed"] == 1 and first["trial"] == 3
    assert set(first["files"]) == {"params.npz", "metrics.json", "learning_curve.png", "rollout.png"}
    assert _train(["--trials", "2", "--seed", "2", "--no-plots"], out).exit_code == 0
    second = read_manifest(out)
    assert set(second["files"]) == {"params.npz", "metrics.json"} and second["seed"] == 2
    # the first set's pictures are gone (they were ours, listed by its manifest), nothing else is
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "metrics.json", "params.npz"]
    import hashlib

    for name, digest in second["files"].items():
        assert hashlib.sha256((out / name).read_bytes()).hexdigest() == digest
    assert json.loads((out / "metrics.json").read_text())["seed"] == 2


def test_files_that_are_not_ours_are_left_alone(tmp_path):
    out = tmp_path / "out"
    assert _train(["--trials", "2"], out).exit_code == 0
    (out / "notes.txt").write_text("mine")  # the user's, put into mitlc's folder: not listed, not touched
    assert _train(["--trials", "2", "--no-plots"], out).exit_code == 0
    assert (out / "notes.txt").read_text() == "mine"
    assert set(read_manifest(out)["files"]) == {"params.npz", "metrics.json"}


def test_a_folder_of_the_users_files_is_refused_not_cleaned(tmp_path):
    """Issue 29 item 2: a manifest.json without mitlc's format key is the user's file, not a licence to clean."""
    out = tmp_path / "d"
    out.mkdir()
    (out / "notes.txt").write_text("notes")
    (out / "metrics.json").write_text("my metrics")
    fake = '{"files":{"notes.txt":"", "metrics.json":""}}'
    (out / MANIFEST).write_text(fake)
    r = _train(["--trials", "1"], out)
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert r.output.strip() == (
        f"--out: error: {out} holds files that are not a mitlc training (manifest.json, metrics.json, notes.txt); "
        "mitlc writes only into a new or empty folder or one of its own trainings: give another --out"
    )
    assert (out / "notes.txt").read_text() == "notes" and (out / "metrics.json").read_text() == "my metrics"
    assert (out / MANIFEST).read_text() == fake and sorted(p.name for p in out.iterdir()) == [
        MANIFEST,
        "metrics.json",
        "notes.txt",
    ]  # not even a lock left behind
    assert read_manifest(out) is None  # not ours
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _train(["--trials", "1", "--no-plots"], empty).exit_code == 0  # an empty folder is fine
    manifest = read_manifest(empty)
    assert manifest["format"] == "mitlc-run" and manifest["version"] == 1


def test_a_second_training_into_a_locked_folder_is_refused(tmp_path):
    out = tmp_path / "out"
    out.mkdir()  # (a folder OutputSet creates and leaves empty goes at close)
    held = OutputSet(out).open()
    try:
        r = _train(["--trials", "2"], out)
        assert r.exit_code == 2 and f"is writing into {out}" in r.output
    finally:
        held.close()
    (out / LOCK).write_text("999999999 " + __import__("socket").gethostname() + "\n")  # a dead process's lock
    assert _train(["--trials", "2"], out).exit_code == 0
    assert not (out / LOCK).exists()


def test_checkpoints_while_training(tmp_path):
    out = tmp_path / "out"
    seen = []
    real = OutputSet.checkpoint

    def spy(self, name, data, **info):
        seen.append(info["trial"])
        real(self, name, data, **info)

    import mitlc.cli.outputs as outputs

    outputs.OutputSet.checkpoint = spy  # type: ignore[method-assign]
    try:
        assert _train(["--trials", "5", "--checkpoint-every", "0.000001"], out).exit_code == 0
    finally:
        outputs.OutputSet.checkpoint = real  # type: ignore[method-assign]
    assert seen == [1, 2, 3, 4, 5]  # every trial, at this interval
    assert _train(["--trials", "3", "--checkpoint-every", "0"], tmp_path / "none").exit_code == 0


def test_a_diverged_run_is_marked_and_the_others_train_on():
    rs = compile_spec(load_spec(P2))
    healthy = Sacpn(rs, runs=3, seed=4)
    healthy.train(6)
    sick = Sacpn(rs, runs=3, seed=4)
    real = sick._trial

    def poisoned():
        ret = real()
        if sick.trial == 2:  # the third trial: run 1's critic blows up
            sick.theta[1, 0, 0] = np.inf
        return ret

    sick._trial = poisoned  # type: ignore[method-assign]
    returns = sick.train(6)
    assert sick.diverged.tolist() == [-1, 3, -1]
    assert np.isnan(returns[1, 2:]).all() and np.isfinite(returns[1, :2]).all()
    # runs are independent: the healthy runs are exactly what they are without the sick one
    np.testing.assert_array_equal(returns[[0, 2]], healthy.returns[[0, 2]])
    np.testing.assert_array_equal(sick.xi[[0, 2]], healthy.xi[[0, 2]])
    assert np.isfinite(sick.xi[1]).all() and np.isfinite(sick.theta[1]).all()  # its last finite values
    d = sick.state_dict()
    again = Sacpn(rs, runs=3, seed=4)
    again.load_state_dict(d)
    assert again.diverged.tolist() == [-1, 3, -1]


def test_when_every_run_diverges_the_set_still_says_where(tmp_path):
    out = tmp_path / "x"
    r = _train(["--trials", "300", "--set", "alpha_c=10", "--set", "gamma=1", "--set", "lam=1"], out)
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert "every run diverged" in r.output and f"{out} keeps each run's last finite parameters" in r.output
    m = json.loads((out / "metrics.json").read_text())
    assert [d["run"] for d in m["diverged"]] == [0, 1] and all(d["trial"] > 0 for d in m["diverged"])
    assert "NaN" not in (out / "metrics.json").read_text()  # strict JSON: a diverged return is null


# json_text: one encoder pass where the data is finite, the same bytes as making it plain first
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from mitlc.fileio import finite_or_none, json_text  # noqa: E402

_FLOATS = st.floats(allow_nan=True, allow_infinity=True)
_LEAVES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**20), 10**20),
    st.text(max_size=4),
    _FLOATS,
    _FLOATS.map(np.float64),
    _FLOATS.map(np.float32),
    st.integers(-(2**62), 2**62).map(np.int64),
    st.booleans().map(np.bool_),
    st.lists(_FLOATS, max_size=4).map(np.array),
    st.lists(st.integers(-5, 5), max_size=4).map(lambda v: np.array(v, dtype=np.int32)),
)
_DATA = st.recursive(
    _LEAVES,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.lists(inner, max_size=3).map(tuple),
        st.dictionaries(st.text(max_size=3), inner, max_size=4),
    ),
    max_leaves=20,
)


@settings(max_examples=300, deadline=None)
@given(_DATA, st.sampled_from([None, 1, 2]))
def test_json_text_is_strict_json_of_the_data_made_plain_first(data, indent) -> None:
    """json_text hands numpy values to the encoder's default and only where a float is not finite
    makes the whole object plain first (finite_or_none): the text is what that always gave."""
    text = json_text(data, indent=indent)
    assert text == json.dumps(finite_or_none(data), indent=indent, allow_nan=False) + "\n"
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
