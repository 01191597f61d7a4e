"""Writing files so that nobody ever sees half of one.

Every file mitlc writes goes through :func:`atomic_write`: the data goes to a
temporary file in the same directory, which is then renamed over the target
(a symlink's target, keeping its mode); devices and pipes are written directly.
A temporary file is named for its writer (``.NAME.PID-XXXXXXXX.mitlc-tmp``), so that
one a kill -9 left behind is recognisably stale (:func:`clean_stale_temps`). A write
that cannot happen (a full disk, a read-only folder, an immutable file) is a
:class:`WriteError`: one line naming the file, exit 2; :func:`check_writable` finds
most of them before the work. :class:`FolderLock` locks an output folder.

>>> import tempfile, pathlib, numpy as np
>>> tmp = tempfile.TemporaryDirectory(); d = pathlib.Path(tmp.name)
>>> save_npz(d / "a.npz", {"x": np.arange(3)})
>>> np.load(d / "a.npz")["x"].tolist()
[0, 1, 2]
>>> tmp.cleanup()
"""

from __future__ import annotations

import errno
import io
import json
import os
import re
import stat
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import InputError

__all__ = [
    "atomic_write",
    "check_writable",
    "clean_stale_temps",
    "stage",
    "WriteError",
    "FolderLock",
    "LockBusy",
    "save_npz",
    "write_block",
    "json_text",
    "finite_or_none",
    "npz_bytes",
    "cache_root",
    "missing_folders",
    "remove_folders",
]


def cache_root() -> Path | None:
    """Where mitlc keeps files it can rebuild (compiled kernels, the spec parser's tables), or None
    when the disk cache is off: ``$MITLC_CACHE_DIR`` if set (empty: off), else
    ``$XDG_CACHE_HOME/mitlc`` or ``~/.cache/mitlc``. Everything there is mitlc's own and safe to delete."""
    env = os.environ.get("MITLC_CACHE_DIR")
    if env is not None:
        return Path(env) if env else None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "mitlc"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


class WriteError(InputError, OSError):
    """A file that could not be written (a full disk, a read-only folder, an immutable file): one
    line naming the file, exit 2. It is an :class:`OSError` too, with the system's ``errno`` and
    ``strerror``, so that code keeping a set of files whole (:class:`mitlc.cli.outputs.OutputSet`)
    catches it as the failed write it is."""

    def __init__(self, message: str, *, errno: int | None = None, strerror: str | None = None, **kw: Any) -> None:
        super().__init__(message, **kw)
        self.errno = errno
        self.strerror = strerror


def _write_error(what: str, exc: OSError, label: str) -> WriteError:
    reason = exc.strerror or str(exc)
    return WriteError(f"{what}: {reason}", file=label, errno=exc.errno, strerror=reason)


TEMP_SUFFIX = ".mitlc-tmp"
"""How every temporary file mitlc writes ends: ``.NAME.PID-XXXXXXXX.mitlc-tmp``, the pid of its writer."""

_TEMP = re.compile(r"\.(?P<name>.+)\.(?P<pid>\d+)-[0-9a-f]{8}" + re.escape(TEMP_SUFFIX))
_LEGACY_TEMP = re.compile(r"\.(?P<name>.+)\.[a-z0-9_]{8}")
"""What :func:`tempfile.mkstemp` named a temporary file before they carried a pid (``.params.npz.k2j_a9x1``)."""


def temp_path(target: Path) -> Path:
    """A new temporary file's name beside ``target``, recognisably mitlc's and its writer's (the pid)."""
    name = target.name[:120]  # the whole name stays well under NAME_MAX
    return target.parent / f".{name}.{os.getpid()}-{os.urandom(4).hex()}{TEMP_SUFFIX}"


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return pid > 0
    return True


def clean_stale_temps(folder: Path, before: float | None = None, legacy: Iterable[str] = ()) -> list[str]:
    """Remove the temporary files a killed mitlc left in ``folder``: those whose writer (the pid in
    the name) is gone, or that were last written before ``before`` (a time: the lock was taken then,
    so no writer of this folder is still at them); and, for the names in ``legacy`` (files mitlc
    writes there), the unnamed ``.NAME.XXXXXXXX`` of older versions last written before ``before``.
    Nothing else is touched. The names removed."""
    removed: list[str] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    legacy = set(legacy)
    for entry in entries:
        name = entry.name
        if not name.startswith("."):
            continue
        m = _TEMP.fullmatch(name)
        old = _LEGACY_TEMP.fullmatch(name)
        if m is None and not (old is not None and old.group("name") in legacy and before is not None):
            continue
        try:
            st = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if not stat.S_ISREG(st.st_mode):
            continue
        stale = before is not None and st.st_mtime < before
        if m is not None and not stale:
            stale = not _alive(int(m.group("pid")))
        if stale:
            try:
                os.unlink(entry.path)
            except OSError:
                continue
            removed.append(name)
    return sorted(removed)


def write_all(fd: int, data: bytes) -> None:
    """Every byte of ``data`` to the file descriptor ``fd`` (``os.write`` may write fewer)."""
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def stage(target: Path, data: bytes, mode: int | None = None) -> Path:
    """``data`` in a new temporary file beside ``target``, on disk (``fsync``), with ``mode`` (default
    0666 less the umask); its path. It is removed again when anything fails; an :class:`OSError`
    says what."""
    tmp = temp_path(target)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o600)
    try:
        try:
            os.fchmod(fd, 0o666 & ~_umask() if mode is None else mode)
            write_all(fd, data)
            os.fsync(fd)  # the data is on disk before a name points at it
        finally:
            os.close(fd)
    except BaseException:
        _unlink_quietly(tmp)
        raise
    return tmp


def _unlink_quietly(path: Path) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def _target_of(path: Path, label: str) -> tuple[Path, os.stat_result | None]:
    """The file a write to ``path`` replaces (a symlink's target) and its status (None: none yet)."""
    try:
        target = Path(os.path.realpath(path)) if path.is_symlink() else path
        return target, os.stat(target)
    except (FileNotFoundError, NotADirectoryError):  # none yet (or its folder is a file: said next)
        return target, None
    except OSError as exc:
        raise _write_error("cannot write", exc, label) from None


def _folder_of(target: Path, label: str) -> Path:
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        if directory.exists():
            raise WriteError(f"cannot write: {directory} is not a folder", file=label)
        raise WriteError(f"output directory does not exist: {directory}", file=label)
    return directory


_FS_IOC_GETFLAGS = 0x80086601
_IMMUTABLE, _APPEND_ONLY = 0x10, 0x20


def _locked_flags(path: Path) -> str | None:
    """``'immutable'`` or ``'append-only'`` when ``chattr`` marked the file so (Linux), else None."""
    try:
        import array
        import fcntl

        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except (ImportError, OSError):
        return None
    try:
        buf = array.array("l", [0])
        fcntl.ioctl(fd, _FS_IOC_GETFLAGS, buf, True)
    except OSError:
        return None
    finally:
        os.close(fd)
    flags = buf[0]
    return "immutable" if flags & _IMMUTABLE else "append-only" if flags & _APPEND_ONLY else None


def check_writable(path: str | Path, label: str | None = None) -> None:
    """Refuse, before any work, a ``path`` that :func:`atomic_write` could not write: a directory, a
    missing folder, a folder that cannot be written (read-only, full, immutable: a probe file is
    written there and removed), or an immutable file. A :class:`WriteError` labelled ``label``."""
    path = Path(path)
    label = label or str(path)
    target, st = _target_of(path, label)
    if st is not None and not stat.S_ISREG(st.st_mode):
        if stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode):
            return  # written directly, as a redirection: opening a FIFO here would wait for a reader
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise WriteError(f"cannot write over {kind}", file=label)
    directory = _folder_of(target, label)
    try:
        os.unlink(stage(target, b"\0"))
    except OSError as exc:
        raise _write_error(f"cannot write into {directory}", exc, label) from None
    flags = _locked_flags(target) if st is not None else None
    if flags is not None:
        raise WriteError(f"cannot replace it: the file is {flags} (chattr)", file=label)


def atomic_write(path: str | Path, data: bytes | str, label: str | None = None) -> None:
    """Write ``data`` to ``path`` as a shell redirection would, but never half a file.

    A regular file (or none yet) is written through a temporary file in the same
    directory that is then renamed over it: readers never see half of it, a failed
    write leaves the old file (or none) and no temporary file, and a replaced file
    keeps its permission bits (a new one gets 0666 less the umask). A symlink is
    followed and its target replaced, so the link stays a link. A character device or a
    FIFO (``/dev/null``, ``/dev/stdout``, a named pipe) is written directly, as ``> path``
    would; any other kind of file (a directory, a block device, a socket) is refused.
    Every failure is a :class:`WriteError` naming ``label`` (default: the path).
    """
    path = Path(path)
    label = label or str(path)
    target, st = _target_of(path, label)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    if st is not None and not stat.S_ISREG(st.st_mode):
        if stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode):
            try:
                with open(target, "wb") as fh:  # noqa: PTH123  (a device or a pipe: no rename)
                    fh.write(payload)
            except OSError as exc:
                raise _write_error("cannot write", exc, label) from None
            return
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise WriteError(f"cannot write over {kind}", file=label)
    directory = _folder_of(target, label)
    mode = stat.S_IMODE(st.st_mode) if st is not None else None
    try:
        tmp = stage(target, payload, mode)
    except OSError as exc:
        what = (
            "cannot write" if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EIO) else f"cannot write into {directory}"
        )
        raise _write_error(what, exc, label) from None
    try:
        os.replace(tmp, target)
    except BaseException as exc:
        _unlink_quietly(tmp)
        if isinstance(exc, OSError):
            raise _write_error("cannot replace it", exc, label) from None
        raise


try:
    import fcntl as _fcntl
except ImportError:  # pragma: no cover - not POSIX (Windows is not a target): the lock below is a created file
    _fcntl = None  # type: ignore[assignment]


class LockBusy(Exception):
    """The folder lock is held by another process; ``owner`` is what its lock file says (``PID HOST``),
    or '' when it has not said yet."""

    def __init__(self, owner: str) -> None:
        super().__init__(owner)
        self.owner = owner


def _hostname() -> str:
    import socket  # only a lock's owner is named by it: not paid by every start-up

    return socket.gethostname()


class FolderLock:
    """An exclusive lock on a folder: ``fcntl.flock`` on its lock file ``path``, held from
    :meth:`acquire` until :meth:`release` (or the process's end: the system drops a dead
    process's lock, so there is no stale lock to take over). The lock file says who holds it
    (``PID HOST``), only for the message of whoever finds it taken. :meth:`release` removes the
    file while still holding it; one who opened it before and locks it after finds that its
    name now points elsewhere (or nowhere) and starts again, so two never hold the lock at once.
    Without ``fcntl`` (not POSIX) the file is created with its owner already in it (a hard link
    of a written file), so that nobody ever sees it empty."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._fd: int | None = None
        self._linked = False

    @property
    def held(self) -> bool:
        return self._fd is not None or self._linked

    def owner_text(self) -> str:
        return f"{os.getpid()} {_hostname()}\n"

    def acquire(self) -> None:
        """Take the lock, or raise :class:`LockBusy`; an :class:`OSError` when the file cannot be
        created or written (a read-only or full folder), with nothing left behind."""
        if _fcntl is None:  # pragma: no cover - exercised by monkeypatching in the tests
            self._acquire_by_link()
            return
        for _ in range(1000):
            flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NOFOLLOW", 0)
            fd = os.open(self.path, flags, 0o644)  # a symlink planted there is refused, not followed
            try:
                _fcntl.flock(fd, _fcntl.LOCK_EX | _fcntl.LOCK_NB)
            except BlockingIOError:
                owner = _read_fd(fd)
                os.close(fd)
                raise LockBusy(owner) from None
            except BaseException:
                os.close(fd)
                raise
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            except BaseException:
                os.close(fd)
                raise
            if not same:  # released and removed between our open and our flock: try the new file
                os.close(fd)
                continue
            try:
                os.ftruncate(fd, 0)
                write_all(fd, self.owner_text().encode())
                os.fsync(fd)
            except BaseException:
                _unlink_quietly(self.path)
                os.close(fd)
                raise
            self._fd = fd
            return
        raise LockBusy("")  # pragma: no cover - a thousand releases in a row

    def _acquire_by_link(self) -> None:
        for _ in range(2):
            tmp = stage(self.path, self.owner_text().encode(), 0o644)
            try:
                os.link(tmp, self.path)  # fails if it exists: the file appears with its owner in it
            except FileExistsError:
                owner = _read_path(self.path)
                pid_text, host = (owner.split() + ["", ""])[:2]
                pid = int(pid_text) if pid_text.isdigit() else -1
                if pid > 0 and host == _hostname() and not _alive(pid):
                    _unlink_quietly(self.path)  # its process is gone
                    continue
                raise LockBusy(owner) from None
            finally:
                _unlink_quietly(tmp)
            self._linked = True
            return
        raise LockBusy("")

    def release(self) -> None:
        """Let go of the lock and remove its file."""
        if self._fd is not None:
            fd, self._fd = self._fd, None
            try:
                if os.path.samestat(os.fstat(fd), os.stat(self.path)):
                    os.unlink(self.path)
            except OSError:
                pass
            finally:
                os.close(fd)
        elif self._linked:
            self._linked = False
            _unlink_quietly(self.path)


def _read_fd(fd: int) -> str:
    try:
        return os.pread(fd, 200, 0).decode("utf-8", "replace")
    except OSError:
        return ""


def _read_path(path: Path) -> str:
    try:
        with open(path, "rb") as fh:  # noqa: PTH123
            return fh.read(200).decode("utf-8", "replace")
    except OSError:
        return ""


def missing_folders(folder: Path) -> list[Path]:
    """The folders of ``folder``'s path that do not exist yet, innermost first: what a
    ``mkdir(parents=True)`` would create, and what :func:`remove_folders` takes back."""
    missing = []
    for f in [folder, *folder.parents]:
        if f.exists():
            break
        missing.append(f)
    return missing


def remove_folders(folders: Sequence[Path]) -> None:
    """Remove the folders a failed start created (innermost first), each only if it is empty."""
    for f in folders:
        try:
            f.rmdir()
        except OSError:
            return


def lock_owner_pid(owner: str) -> int | None:
    """The pid a lock file's text names (``PID HOST``), or None."""
    first = (owner.split() or [""])[0]
    return int(first) if first.isdigit() else None


def finite_or_none(obj: Any) -> Any:
    """``obj`` with every non-finite float (``inf``, ``-inf``, ``nan``) as None, numpy scalars
    and arrays as Python numbers and lists: what strict JSON can hold.

    >>> finite_or_none({"a": [1.0, float("inf")], "b": np.float64("nan"), "c": np.arange(2)})
    {'a': [1.0, None], 'b': None, 'c': [0, 1]}
    """
    if isinstance(obj, float | np.floating):
        v = float(obj)
        return v if np.isfinite(v) else None
    if isinstance(obj, bool | np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return finite_or_none(obj.tolist())
    if isinstance(obj, Mapping):
        return {k: finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [finite_or_none(v) for v in obj]
    return obj


def json_text(obj: Any, indent: int | None = None, **kw: Any) -> str:
    """Strict JSON of ``obj``: never ``Infinity`` or ``NaN`` (written ``null``, see
    :func:`finite_or_none`); a trailing newline.

    >>> json_text({"hi": float("inf")})
    '{"hi": null}\\n'
    """
    try:  # numpy values through the encoder's default; one pass where every float is finite (most data)
        return json.dumps(obj, indent=indent, allow_nan=False, default=_plain, **kw) + "\n"
    except ValueError:  # a non-finite float somewhere: the whole object made plain first
        return json.dumps(finite_or_none(obj), indent=indent, allow_nan=False, **kw) + "\n"


def _plain(obj: Any) -> Any:
    """What :func:`json_text`'s encoder cannot write itself, as :func:`finite_or_none` makes it (a numpy
    scalar or array, a mapping other than a dict); anything else the encoder's own ``TypeError``."""
    if isinstance(obj, np.ndarray | np.generic | Mapping):
        return finite_or_none(obj)
    raise TypeError(f"Object of type {type(obj).__name__} is not JSON serializable")


def npz_bytes(arrays: Mapping[str, np.ndarray]) -> bytes:
    """What :func:`numpy.savez` writes for ``arrays``, in memory."""
    buf = io.BytesIO()
    named: dict[str, Any] = dict(arrays)  # numpy's stub reads **kwargs as if they could be allow_pickle
    np.savez(buf, **named)
    return buf.getvalue()


def save_npz(path: str | Path, arrays: Mapping[str, np.ndarray]) -> None:
    """:func:`numpy.savez` to ``path``, atomically."""
    atomic_write(path, npz_bytes(arrays))


def write_block(path: str | Path, begin: str, end: str, block: str) -> None:
    r"""Replace the text from the line ``begin`` to the line ``end`` of a text file by ``block``
    (which carries both markers), or append ``block`` when the file has none; atomically.

    >>> import tempfile, pathlib
    >>> tmp = tempfile.TemporaryDirectory(); p = pathlib.Path(tmp.name) / "page.md"
    >>> _ = p.write_text("# page\n\n<!-- a -->\nold\n<!-- /a -->\nrest\n")
    >>> write_block(p, "<!-- a -->", "<!-- /a -->", "<!-- a -->\nnew\n<!-- /a -->\n")
    >>> p.read_text()
    '# page\n\n<!-- a -->\nnew\n<!-- /a -->\nrest\n'
    >>> tmp.cleanup()
    """
    text = Path(path).read_text(encoding="utf-8")
    if begin in text:
        text = text[: text.index(begin)] + block + text[text.index(end) + len(end) + 1 :]
    else:
        text = text.rstrip("\n") + "\n\n" + block
    atomic_write(path, text)
