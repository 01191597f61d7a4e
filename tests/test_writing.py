"""Files mitlc writes (issue 29): a write that cannot happen (a read-only or full filesystem, an
immutable file or folder, ``/proc/self/status``, a folder given as a file) is one line naming the option
or file and exit 2, never a traceback, and leaves nothing behind."""

from __future__ import annotations

import errno
import hashlib
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from mitlc.cli import main
from mitlc.fileio import WriteError, atomic_write, check_writable
from tests.conftest import P2_SHORT
from tests.faults import Faults, can_chattr, chattr, mount_tmpfs

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
