"""Files mitlc writes (issue 29): the folder lock, the user's files, a sweep's folder, write failures.

Every reproducer of the audit is here: a write that cannot happen (a read-only or full filesystem, an
immutable file or folder, ``/proc/self/status``, a folder given as a file) is one line naming the option
or file and exit 2, never a traceback, and leaves nothing behind; no manifest makes a user's file
mitlc's to remove; a sweep refuses a folder of the user's files; two processes never hold a folder's
lock at once (a stress test that fails on the lock before issue 29); a temporary file a kill -9 left is
removed when the folder is next opened; a set that fails while being written leaves the earlier set
whole.
"""

from __future__ import annotations

import errno
import hashlib
import json
import multiprocessing
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from mitlc.cli import main
from mitlc.cli.outputs import LOCK, MANIFEST, OWNED, OutputSet, owned, read_manifest
from mitlc.errors import InputError
from mitlc.fileio import FolderLock, LockBusy, WriteError, atomic_write, check_writable, stage
from tests.conftest import P2_SHORT
from tests.faults import Faults, can_chattr, chattr, mount_tmpfs, temp_files

ROOT = Path(__file__).resolve().parents[1]
P2 = str(ROOT / "specs/pendulum/p2_avoid.mitl")


def run(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args], prog_name="mitlc")


def one_line(result, expected: str) -> None:
    """Exit 2, and the whole output is the one line ``expected``."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert result.output.strip() == expected, result.output


def listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def spec(tmp_path: Path) -> Path:
    p = tmp_path / "p2_short.mitl"
    p.write_text(P2_SHORT)
    return p


@pytest.fixture(scope="module")
def policy(tmp_path_factory) -> Path:
    """A trained SACPN policy folder (2 runs, 2 trials of the short problem 2)."""
    folder = tmp_path_factory.mktemp("policy")
    spec = folder / "p2_short.mitl"
    spec.write_text(P2_SHORT)
    r = run("train", "--spec", spec, "--runs", 2, "--trials", 2, "-q", "--no-plots", "--out", folder / "pol")
    assert r.exit_code == 0, r.output
    return folder / "pol"


# ---------------------------------------------------------------- where a write cannot happen

KINDS = ("read-only", "full", "immutable folder", "immutable file", "/proc/self/status", "a folder")


def _place(kind: str, tmp_path: Path, stack, name: str) -> tuple[Path, str]:
    """A path of ``kind`` that cannot be written, and the error the write gives."""
    if kind == "read-only":
        ro = stack.enter_context(mount_tmpfs(tmp_path / "ro", read_only=True))
        return ro / name, f"cannot write into {ro}: Read-only file system"
    if kind == "full":
        full = stack.enter_context(mount_tmpfs(tmp_path / "full", fill=True))
        return full / name, f"cannot write into {full}: No space left on device"
    if kind == "/proc/self/status":
        return Path("/proc/self/status"), "cannot write into /proc/self: No such file or directory"
    if kind == "a folder":
        (tmp_path / name).mkdir()  # a folder named like the file
        return tmp_path / name, "cannot write over a directory"
    if not can_chattr(tmp_path):
        pytest.skip("chattr +i does not work here (needs root and a filesystem with the immutable flag)")
    folder = tmp_path / "imm"
    folder.mkdir()
    if kind == "immutable folder":
        chattr(folder, "+i")
        stack.callback(chattr, folder, "-i")
        return folder / name, f"cannot write into {folder}: Operation not permitted"
    target = folder / name
    target.write_bytes(b"old")
    chattr(target, "+i")
    stack.callback(chattr, target, "-i")
    return target, "cannot replace it: the file is immutable (chattr)"


def _state(path: Path) -> list[str]:
    folder = path.parent
    if str(folder).startswith("/proc"):
        return []
    return listing(folder) + ([sha(path)] if path.is_file() else [])


@pytest.mark.parametrize("kind", KINDS)
def test_compile_o_where_it_cannot_write_is_one_line(tmp_path, kind):
    from contextlib import ExitStack

    with ExitStack() as stack:
        target, message = _place(kind, tmp_path, stack, "net.txt")
        before = _state(target)
        r = run("compile", P2, "-o", target)
        one_line(r, f"-o {target}: error: {message}")
        assert _state(target) == before  # nothing written, nothing left behind


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("option", ["--plot", "--trace"])
def test_simulate_plot_and_trace_where_they_cannot_write_are_one_line(tmp_path, policy, kind, option):
    from contextlib import ExitStack

    name = "sim.png" if option == "--plot" else "sim.csv"
    with ExitStack() as stack:
        target, message = _place(kind, tmp_path, stack, name)
        if option == "--trace" and kind == "/proc/self/status":
            target = Path("/proc/self/status.csv")
        before = _state(target)
        r = run("simulate", "--policy", policy, "--rollouts", 1, option, target)
        one_line(r, f"{option} {target}: error: {message}")  # before any rollout: no verdict line printed
        assert _state(target) == before


def test_a_full_disk_found_only_by_the_write_is_one_line_and_leaves_no_temporary_file(tmp_path, monkeypatch):
    """The probe passes (a byte fits) but the file does not: the temporary file goes, the old file stays."""
    target = tmp_path / "net.json"
    target.write_text("old")
    faults = Faults(monkeypatch, tmp_path, "write", 2)  # the probe's byte is write 1
    r = run("compile", P2, "--format", "json", "-o", target)
    assert faults.fired
    one_line(r, f"-o {target}: error: cannot write: No space left on device")
    assert listing(tmp_path) == ["net.json"] and target.read_text() == "old"


def test_a_failed_rename_leaves_the_old_file_and_no_temporary_file(tmp_path, monkeypatch):
    target = tmp_path / "net.txt"
    target.write_text("old")
    Faults(monkeypatch, tmp_path, "rename", 1, errno.EPERM)
    with pytest.raises(WriteError) as err:
        atomic_write(target, "new")
    assert err.value.errno == errno.EPERM and isinstance(err.value, OSError)
    assert str(err.value) == f"{target}: error: cannot replace it: Operation not permitted"
    assert listing(tmp_path) == ["net.txt"] and target.read_text() == "old"


def test_check_writable_accepts_what_atomic_write_writes(tmp_path):
    check_writable(tmp_path / "new.txt")
    check_writable("/dev/null")  # written directly, like a redirection
    (tmp_path / "old.txt").write_text("x")
    check_writable(tmp_path / "old.txt")
    assert listing(tmp_path) == ["old.txt"]  # the probe is gone
    with pytest.raises(WriteError, match="output directory does not exist"):
        check_writable(tmp_path / "nosuch" / "x.txt")
    with pytest.raises(WriteError, match="is not a folder"):
        check_writable(tmp_path / "old.txt" / "x.txt")


def test_compile_o_a_folder_names_the_option_and_the_file(tmp_path):
    """Issue 29: ``compile -o adir`` printed ``-o': error``."""
    (tmp_path / "adir").mkdir()
    one_line(
        run("compile", P2, "-o", tmp_path / "adir"), f"-o {tmp_path / 'adir'}: error: cannot write over a directory"
    )


def test_click_labels_an_option_by_its_first_name_without_quotes():
    from mitlc.cli.main import _one_line

    opt = click.Option(["-o", "--output"], type=int)
    ctx = click.Context(click.Command("c", params=[opt]), info_name="c")
    exc = click.BadParameter("'x' is not a valid integer.", ctx=ctx, param=opt)
    assert _one_line(exc) == "-o: error: 'x' is not a valid integer. (c --help)"


# ---------------------------------------------------------------- train --out


def test_train_out_on_a_full_disk_is_one_line_before_the_work(tmp_path, spec):
    with mount_tmpfs(tmp_path / "full", fill=True) as full:
        r = run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--out", full / "d")
        one_line(r, f"--out: error: cannot write into {full / 'd'}: No space left on device")
        assert listing(full) == ["fill"]  # no folder, no empty .mitlc.lock


def test_train_out_when_the_lock_cannot_be_written_is_one_line_before_the_work(tmp_path, spec, monkeypatch):
    """The in-process twin of the full-disk test: the lock's pid is the first write into the folder."""
    out = tmp_path / "d"
    out.mkdir()
    trained = []
    monkeypatch.setattr("mitlc.learn.sacpn.Sacpn.train", lambda self, *a, **k: trained.append(1))
    faults = Faults(monkeypatch, out, "write", 1)
    r = run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--out", out)
    assert faults.fired and not trained
    one_line(r, f"--out: error: cannot write into {out}: No space left on device")
    assert listing(out) == []  # no empty .mitlc.lock


def test_train_out_read_only_is_one_line(tmp_path, spec):
    with mount_tmpfs(tmp_path / "ro", read_only=True) as ro:
        r = run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--out", ro / "d")
        one_line(r, f"--out: error: cannot write into {ro / 'd'}: Read-only file system")
        r = run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--out", ro)
        one_line(r, f"--out: error: cannot write into {ro}: Read-only file system")
        assert listing(ro) == []


def test_a_checkpoint_that_cannot_be_written_warns_once_and_training_goes_on(tmp_path, spec, monkeypatch):
    def full(self, *a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(OutputSet, "checkpoint", full)
    out = tmp_path / "d"
    r = run(
        "train",
        "--spec",
        spec,
        "--runs",
        1,
        "--trials",
        3,
        "-q",
        "--no-plots",
        "--checkpoint-every",
        "1e-9",
        "--out",
        out,
    )
    assert r.exit_code == 0, r.output
    warnings = [line for line in r.output.splitlines() if line.startswith("warning: cannot write a checkpoint")]
    assert warnings == [
        f"warning: cannot write a checkpoint into {out} (No space left on device); training goes on, and its "
        "results go to a fallback folder if the folder stays unwritable"
    ]
    assert json.loads((out / "metrics.json").read_text())["trials"] == 3


# ---------------------------------------------------------------- item 2: the user's files


def test_the_issues_fake_manifest_deletes_nothing(tmp_path):
    """Issue 29 item 2, its exact reproducer: a manifest.json with a files key is not mitlc's."""
    d = tmp_path / "d"
    d.mkdir()
    (d / "notes.txt").write_text("notes\n")
    (d / MANIFEST).write_text('{"files":{"notes.txt":""}}\n')
    r = run("train", "--spec", "pendulum/p2_avoid", "--runs", 1, "--trials", 1, "-q", "--out", d)
    one_line(
        r,
        f"--out: error: {d} holds files that are not a mitlc training (manifest.json, notes.txt); mitlc writes only "
        "into a new or empty folder or one of its own trainings: give another --out",
    )
    assert (d / "notes.txt").read_text() == "notes\n" and listing(d) == [MANIFEST, "notes.txt"]


@pytest.mark.parametrize("listed", ["files", "earlier"])
def test_a_manifest_with_the_format_key_cannot_list_a_users_file_for_removal(tmp_path, spec, listed):
    d = tmp_path / "d"
    d.mkdir()
    (d / "notes.txt").write_text("notes\n")
    (d / "metrics.json").write_text("my metrics\n")
    doc = {"format": "mitlc-run", "version": 1, "state": "complete", "files": {}}
    doc[listed] = {"notes.txt": "0" * 64} if listed == "files" else ["notes.txt", "../outside.txt"]
    (d / MANIFEST).write_text(json.dumps(doc))
    assert read_manifest(d) is None  # it lists a file mitlc never writes: not mitlc's
    r = run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--no-plots", "--out", d)
    assert r.exit_code == 2 and "holds files that are not a mitlc training" in r.output
    assert (d / "notes.txt").read_text() == "notes\n" and (d / "metrics.json").read_text() == "my metrics\n"


def test_only_names_mitlc_writes_are_ever_removed(tmp_path, spec):
    """A real training folder whose manifest an older mitlc (or a hand) extended: its removals are
    limited to :data:`OWNED` and ``plants/NAME.py``; notes.txt and the user's plants/notes.txt stay."""
    from mitlc.cli.outputs import _earlier

    assert _earlier({"files": {"notes.txt": "", "params.npz": ""}, "earlier": ["plants/x.py", "plants/x.txt"]}) == [
        "params.npz",
        "plants/x.py",
    ]
    assert [n for n in ("params.npz", "rollout.png", "plants/cart_plant.py") if owned(n)] == [
        "params.npz",
        "rollout.png",
        "plants/cart_plant.py",
    ]
    assert not any(owned(n) for n in ("notes.txt", "plants/../x.py", "/etc/passwd", "plants/a/b.py", MANIFEST))
    d = tmp_path / "d"
    assert (
        run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--out", d, "--learner", "sacpn").exit_code == 0
    )
    # every file a SACPN training writes is in OWNED, and no other but the policy search's
    assert set(read_manifest(d)["files"]) | {"search.npz"} == OWNED
    assert owned("sac_000.zip") and owned("sac_1234.zip") and not owned("sac_1.zip") and not owned("sac_000.zip.bak")
    (d / "notes.txt").write_text("mine")
    sacpn = ("--learner", "sacpn")
    assert (
        run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--no-plots", "--out", d, *sacpn).exit_code == 0
    )
    assert listing(d) == [MANIFEST, "metrics.json", "notes.txt", "params.npz"]
    # a policy search into the same folder replaces the set (its search.npz is mitlc's, the checkpoint goes)
    search = ("--learner", "search")
    assert (
        run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--no-plots", "--out", d, *search).exit_code == 0
    )
    assert listing(d) == [MANIFEST, "metrics.json", "notes.txt", "search.npz"]
    assert (
        run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--no-plots", "--out", d, *search).exit_code == 0
    )


# ---------------------------------------------------------------- item 3: a sweep's folder

SWEEP = ("sweep", "GRID", "--grid", "sigma=1", "--seeds", 1, "--runs", 1, "--trials", 1, "-q", "--no-plot")


def sweep(spec: Path, out: Path):
    return run(*[spec if a == "GRID" else a for a in SWEEP], "--out", out)


@pytest.mark.parametrize(
    "files",
    [{"results.csv": "a,b\n1,2\n"}, {"results.json": '{"a": 1}\n'}, {"results.json": "not json"}, {"notes.txt": "x"}],
)
def test_a_sweep_refuses_a_folder_of_the_users_files(tmp_path, spec, files):
    """Issue 29 item 3: ``sweep --out d`` replaced a user's results.csv; a user's results.json gave
    "cannot read earlier results: 'header'"."""
    d = tmp_path / "d"
    d.mkdir()
    for name, text in files.items():
        (d / name).write_text(text)
    r = sweep(spec, d)
    shown = ", ".join(sorted(files))
    one_line(
        r,
        f"--out: error: {d} holds files that are not a mitlc sweep ({shown}); a sweep writes only into a new or "
        "empty folder or one of its own sweeps: give another --out",
    )
    assert {p.name: p.read_text() for p in d.iterdir()} == files  # untouched, and no lock left


def test_a_sweeps_results_say_they_are_a_sweeps_and_an_older_one_is_continued(tmp_path, spec):
    d = tmp_path / "d"
    assert sweep(spec, d).exit_code == 0
    data = json.loads((d / "results.json").read_text())
    assert (data["format"], data["version"]) == ("mitlc-sweep", 1) and len(data["results"]) == 1
    assert listing(d) == ["results.csv", "results.json"]  # the lock is gone with the sweep
    del data["format"], data["version"]  # as a sweep wrote it before the format key
    (d / "results.json").write_text(json.dumps(data))
    (d / "notes.txt").write_text("mine")  # the user's file in the sweep's own folder: left alone
    r = run(*[spec if a == "GRID" else a for a in SWEEP[:-2]], "--no-plot", "--out", d)
    assert r.exit_code == 0, r.output
    assert "0 tasks run in" in r.output and "1 done earlier" in r.output
    assert json.loads((d / "results.json").read_text())["format"] == "mitlc-sweep"
    assert (d / "notes.txt").read_text() == "mine"


def test_sweep_out_that_cannot_be_written_is_one_line(tmp_path, spec):
    afile = tmp_path / "afile"
    afile.write_text("mine")
    one_line(
        sweep(spec, afile / "sub"), f"--out: error: cannot create the output folder {afile / 'sub'}: {afile} is a file"
    )
    assert afile.read_text() == "mine"
    with mount_tmpfs(tmp_path / "ro", read_only=True) as ro:
        one_line(
            sweep(spec, ro / "sw"), f"--out: error: cannot create the output folder {ro / 'sw'}: Read-only file system"
        )
        one_line(sweep(spec, ro), f"--out: error: cannot write into {ro}: Read-only file system")
    with mount_tmpfs(tmp_path / "full", fill=True) as full:
        one_line(sweep(spec, full / "sw"), f"--out: error: cannot write into {full / 'sw'}: No space left on device")
        assert listing(full) == ["fill"]


def test_a_sweep_on_a_disk_that_fills_at_its_first_write_is_one_line(tmp_path, spec, monkeypatch):
    d = tmp_path / "sw"
    faults = Faults(monkeypatch, tmp_path, "write", 2)  # 1: the lock's pid; 2: results.json
    one_line(sweep(spec, d), f"{d / 'results.json'}: error: cannot write: No space left on device")
    assert faults.fired and not d.exists()  # the folder it made is gone again


# ---------------------------------------------------------------- item 4: the lock


def _racer(root: str, n: int, barrier, results) -> None:
    for i in range(n):
        held = OutputSet(Path(root) / str(i))
        barrier.wait()
        try:
            held._lock()
            got = True
        except InputError:
            got = False
        results.put((i, got))
        barrier.wait()  # everybody has tried while the holders still hold
        if got:
            held.close()


def test_eight_processes_taking_the_lock_at_once_get_one_holder(tmp_path):
    """Issue 29 item 4's reproducer: eight processes call ``OutputSet(d)._lock()`` at once, N times.
    The lock before issue 29 (an O_EXCL file read as stale while still empty) had two holders in
    about 1 % of 1000 iterations here (37 of 200 in the audit)."""
    n, procs = 600, 8
    for i in range(n):
        (tmp_path / str(i)).mkdir()
    ctx = multiprocessing.get_context("fork")
    barrier, results = ctx.Barrier(procs), ctx.Queue()
    workers = [ctx.Process(target=_racer, args=(str(tmp_path), n, barrier, results)) for _ in range(procs)]
    for w in workers:
        w.start()
    holders = [0] * n
    for _ in range(n * procs):
        i, got = results.get(timeout=60)
        holders[i] += got
    for w in workers:
        w.join(30)
    assert holders == [1] * n
    assert all(not (tmp_path / str(i) / LOCK).exists() for i in range(n))


def _churner(folder: str, until: float, holders, overlaps, taken) -> None:
    while time.time() < until:
        held = OutputSet(Path(folder))
        try:
            held._lock()
        except InputError:
            continue
        with holders.get_lock():
            holders.value += 1
            overlaps.value += holders.value > 1
        taken.value += 1
        time.sleep(0.0005)
        with holders.get_lock():
            holders.value -= 1
        held.close()


def test_the_lock_is_never_held_twice_while_holders_come_and_go(tmp_path):
    """Eight processes take and release one folder's lock for 1.5 s. A release removes the lock file;
    one who opened it just before must not hold the removed file while a third creates a new one.
    Before issue 29: thousands of overlaps in 1.5 s."""
    ctx = multiprocessing.get_context("fork")
    holders, overlaps, taken = ctx.Value("i", 0), ctx.Value("i", 0), ctx.Value("i", 0)
    until = time.time() + 1.5
    workers = [ctx.Process(target=_churner, args=(str(tmp_path), until, holders, overlaps, taken)) for _ in range(8)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(30)
    assert overlaps.value == 0 and taken.value > 0 and holders.value == 0
    assert not (tmp_path / LOCK).exists()


def test_a_held_lock_names_its_holder_and_a_dead_holder_holds_nothing(tmp_path):
    child = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time; from mitlc.cli.outputs import OutputSet; "
            f"s = OutputSet({str(tmp_path)!r}).open(); print('held', flush=True); time.sleep(60)",
        ],
        stdout=subprocess.PIPE,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    try:
        assert child.stdout.readline() == b"held\n"
        with pytest.raises(InputError) as err:
            OutputSet(tmp_path).open()
        assert err.value.message == (
            f"another mitlc (pid {child.pid}) is writing into {tmp_path}: wait for it, or give another folder"
        )
        child.kill()  # kill -9: the system lets go of its lock; its file stays, naming a dead pid
        child.wait(10)
        assert (tmp_path / LOCK).read_text() == f"{child.pid} {socket.gethostname()}\n"
        OutputSet(tmp_path).open().close()
        assert not (tmp_path / LOCK).exists()
    finally:
        child.kill()
        child.wait(10)


def test_without_fcntl_the_lock_file_appears_with_its_owner_in_it(tmp_path, monkeypatch):
    import mitlc.fileio as fileio

    monkeypatch.setattr(fileio, "_fcntl", None)
    first = FolderLock(tmp_path / LOCK)
    first.acquire()
    assert (tmp_path / LOCK).read_text() == f"{os.getpid()} {socket.gethostname()}\n"
    with pytest.raises(LockBusy) as busy:
        FolderLock(tmp_path / LOCK).acquire()  # this process is alive: busy
    assert busy.value.owner.split()[0] == str(os.getpid())
    first.release()
    (tmp_path / LOCK).write_text(f"999999999 {socket.gethostname()}\n")  # a dead process's
    second = FolderLock(tmp_path / LOCK)
    second.acquire()
    second.release()
    assert listing(tmp_path) == []


# ---------------------------------------------------------------- temporary files a kill -9 left


def test_a_temporary_file_a_kill_left_is_removed_when_the_folder_is_next_opened(tmp_path, spec):
    """Issue 29: a kill -9 during a checkpoint left ``.params.npz.XXXX`` for ever. A temporary file now
    names its writer (``.params.npz.PID-XXXXXXXX.mitlc-tmp``); the next training into the folder
    removes those whose writer is dead, and old unnamed ones of mitlc's files from before the lock."""
    d = tmp_path / "d"
    assert run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--no-plots", "--out", d).exit_code == 0
    code = (
        "import os; from pathlib import Path; from mitlc.fileio import stage; "
        f"stage(Path({str(d / 'params.npz')!r}), b'x' * 100); os._exit(9)"  # killed between stage and rename
    )
    subprocess.run([sys.executable, "-c", code], env={**os.environ, "PYTHONPATH": str(ROOT)}, check=False, timeout=60)
    (left,) = temp_files(d)
    assert left.startswith(".params.npz.") and left.endswith(".mitlc-tmp")
    old = d / ".params.npz.k2j_a9x1"  # an older mitlc's, from an hour ago
    old.write_bytes(b"half")
    os.utime(old, (time.time() - 3600,) * 2)
    fresh = d / ".metrics.json.abcd1234"  # might be anybody's still: left alone
    fresh.write_bytes(b"?")
    (d / ".notes").write_text("the user's")  # not a temporary file at all
    mine = stage(d / "params.npz", b"mine")  # this (live) process's own
    assert run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--no-plots", "--out", d).exit_code == 0
    assert temp_files(d) == [mine.name]
    assert sorted(p.name for p in d.iterdir() if p.name.startswith(".")) == sorted(
        [".metrics.json.abcd1234", ".notes", mine.name]
    )
    mine.unlink()


# ---------------------------------------------------------------- a set is written whole or not at all


def _snapshot(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): sha(p) for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize(
    "op, n", [("create", 3), ("write", 2), ("fsync", 4), ("rename", 1), ("rename", 3), ("rename", 4), ("link", 2)]
)
def test_a_failure_while_writing_a_set_keeps_the_earlier_set_whole(tmp_path, spec, monkeypatch, op, n):
    """The set (params, metrics and the manifest twice, as ``writing`` then ``complete``, replacing one
    with pictures) fails at the n-th call of a kind: the folder holds the earlier set exactly, and the
    new one is in the rescue folder. A failed hard link (the earlier file kept for putting back) is
    a copy instead: the new set is written."""
    d = tmp_path / "d"
    assert run("train", "--spec", spec, "--runs", 1, "--trials", 2, "-q", "--seed", 1, "--out", d).exit_code == 0
    before = _snapshot(d)
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "rescue"))
    (tmp_path / "rescue").mkdir()
    faults = Faults(monkeypatch, d, op, n + 1 if op in ("write", "fsync") else n)  # the lock's write and fsync first
    r = run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--seed", 2, "--no-plots", "--out", d)
    assert faults.fired, faults.counts
    if op == "link":
        assert r.exit_code == 0, r.output
        saved = d
    else:
        assert r.exit_code == 2 and "they are saved in" in r.output and len(r.output.strip().splitlines()) == 1
        assert _snapshot(d) == before  # the earlier set, whole: every file as it was, no temporary file, no lock
        (saved,) = (tmp_path / "rescue").iterdir()
    manifest = read_manifest(saved)
    assert manifest["state"] == "complete" and manifest["seed"] == 2
    assert _snapshot(saved) == {**manifest["files"], MANIFEST: sha(saved / MANIFEST)}


def test_a_lock_file_planted_as_a_symlink_is_not_followed(tmp_path, spec):
    outside = tmp_path / "outside.txt"
    outside.write_text("the user's")
    d = tmp_path / "d"
    d.mkdir()
    (d / LOCK).symlink_to(outside)
    r = run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--out", d)
    one_line(r, f"--out: error: cannot write into {d}: Too many levels of symbolic links")
    assert outside.read_text() == "the user's" and (d / LOCK).is_symlink()


def test_a_symlink_in_the_set_is_put_back_as_a_link_when_the_set_fails(tmp_path, spec, monkeypatch):
    d = tmp_path / "d"
    assert run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--no-plots", "--out", d).exit_code == 0
    elsewhere = tmp_path / "metrics-elsewhere.json"
    elsewhere.write_text("{}")
    (d / "metrics.json").unlink()
    (d / "metrics.json").symlink_to(elsewhere)
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    faults = Faults(monkeypatch, d, "rename", 4)  # the last: the complete manifest
    r = run("train", "--spec", spec, "--runs", 1, "--trials", 1, "-q", "--no-plots", "--out", d)
    assert faults.fired and r.exit_code == 2 and "they are saved in" in r.output
    assert (d / "metrics.json").is_symlink() and os.readlink(d / "metrics.json") == str(elsewhere)
    assert elsewhere.read_text() == "{}" and temp_files(d) == []
