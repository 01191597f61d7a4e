"""Filesystem faults for the tests of what mitlc writes (tests/test_writing.py, tests/test_fuzz_writing.py).

* :class:`Faults` counts the system calls that write a file under one folder (creating a file,
  ``write``, ``fsync``, renaming over a name, hard-linking) and fails the n-th of one kind with an
  ``OSError``, as a full disk, a failing disk or a read-only remount would: in-process, through
  ``monkeypatch``, so it works for any user.
* :func:`mount_tmpfs` mounts a small tmpfs (a real full disk, a real read-only filesystem) where the
  tests run as root and may mount; :func:`can_chattr` says whether ``chattr +i`` works here.
  Tests that need them skip, saying why, where they do not.
"""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

OPS = ("create", "write", "fsync", "rename", "link")
"""The kinds of call :class:`Faults` counts."""


def _fd_path(fd: int) -> str:
    try:
        return os.readlink(f"/proc/self/fd/{fd}")
    except OSError:
        return ""


class Faults:
    """Fail the ``n``-th call of kind ``op`` (see :data:`OPS`) on a file under ``root`` with ``OSError(err)``;
    ``n = 0``: count only. :attr:`counts` says how many calls of each kind were seen, :attr:`fired`
    whether the fault was raised."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, root: Path, op: str = "write", n: int = 0, err: int = 0):
        assert op in OPS
        self.root = os.path.realpath(root)
        self.op, self.n, self.err = op, n, err or errno.ENOSPC
        self.counts = dict.fromkeys(OPS, 0)
        self.fired = False
        real = {name: getattr(os, name) for name in ("open", "write", "fsync", "replace", "rename", "link")}
        self._real = real

        def under(path: object) -> bool:
            if not isinstance(path, (str, bytes, os.PathLike)):
                return False
            name = os.fsdecode(
                path
            )  # its folder resolved, not the name itself (a symlink is renamed over, not followed)
            p = os.path.join(os.path.realpath(os.path.dirname(name) or "."), os.path.basename(name))
            return p == self.root or p.startswith(self.root + os.sep)

        def hit(kind: str) -> None:
            self.counts[kind] += 1
            if kind == self.op and self.counts[kind] == self.n:
                self.fired = True
                raise OSError(self.err, os.strerror(self.err))

        def open_(path, flags, mode=0o777, *, dir_fd=None):
            if flags & os.O_CREAT and dir_fd is None and under(path):
                hit("create")
            return real["open"](path, flags, mode, dir_fd=dir_fd)

        def write(fd, data):
            if under(_fd_path(fd)):
                hit("write")
            return real["write"](fd, data)

        def fsync(fd):
            if under(_fd_path(fd if isinstance(fd, int) else fd.fileno())):
                hit("fsync")
            return real["fsync"](fd)

        def replace(src, dst, **kw):
            if under(dst):
                hit("rename")
            return real["replace"](src, dst, **kw)

        def rename(src, dst, **kw):
            if under(dst):
                hit("rename")
            return real["rename"](src, dst, **kw)

        def link(src, dst, **kw):
            if under(dst):
                hit("link")
            return real["link"](src, dst, **kw)

        for name, fn in (
            ("open", open_),
            ("write", write),
            ("fsync", fsync),
            ("replace", replace),
            ("rename", rename),
            ("link", link),
        ):
            monkeypatch.setattr(os, name, fn)


def temp_files(folder: Path) -> list[str]:
    """Temporary files of mitlc's under ``folder`` (any depth)."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.name.endswith(".mitlc-tmp"))


def _mount_works(point: Path, options: str) -> bool:
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(point)], capture_output=True, timeout=10)
    return r.returncode == 0


@contextmanager
def mount_tmpfs(point: Path, size_kib: int = 64, read_only: bool = False, fill: bool = False) -> Iterator[Path]:
    """A tmpfs of ``size_kib`` KiB at ``point`` (created), read-only or filled to the last byte, unmounted
    afterwards; skips the test, saying why, when mounting is not allowed here."""
    point.mkdir(parents=True, exist_ok=True)
    if not _mount_works(point, f"size={size_kib}k"):
        pytest.skip("mounting a tmpfs needs root and a mount the sandbox allows (the in-process Faults test covers it)")
    try:
        if fill:
            fd = os.open(point / "fill", os.O_WRONLY | os.O_CREAT)
            try:
                while True:
                    os.write(fd, b"\0" * 4096)
            except OSError as exc:
                assert exc.errno == errno.ENOSPC
            finally:
                os.close(fd)
        if read_only:
            subprocess.run(["mount", "-o", "remount,ro", str(point)], check=True, timeout=10)
        yield point
    finally:
        subprocess.run(["umount", "-l", str(point)], capture_output=True, timeout=10)


def can_chattr(folder: Path) -> bool:
    """Whether ``chattr +i`` works on a file in ``folder`` (root, and a filesystem that has the flag)."""
    if shutil.which("chattr") is None:
        return False
    probe = folder / ".chattr-probe"
    probe.write_text("")
    ok = subprocess.run(["chattr", "+i", str(probe)], capture_output=True, timeout=10).returncode == 0
    subprocess.run(["chattr", "-i", str(probe)], capture_output=True, timeout=10)
    probe.unlink()
    return ok


def chattr(path: Path, flag: str) -> None:
    subprocess.run(["chattr", flag, str(path)], check=True, capture_output=True, timeout=10)
