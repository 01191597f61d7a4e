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
