"""Whether a file of the disk cache may be used: the cache is never trusted more than its folder.

mitlc keeps files it can rebuild under :func:`mitlc.fileio.cache_root` (the spec parser's tables
in ``parser/``, compiled kernels in ``kernels/``). Reading some of them runs code: a kernel is a
generated module, and numba's cache files next to it are pickles. So, as ssh does with
``~/.ssh``, a folder of the cache is used only if it is owned by the current user (or root) and
writable by nobody else, and a file in it only if it is owned by the same and writable by nobody
else, or sits in a folder nobody else may enter (numba writes its files with the umask's mode,
``0664`` under a ``002`` umask; the folder mitlc makes for them is ``0700``). Anything else is
not read and not written: the work is done in memory, as with ``MITLC_CACHE_DIR=``, and nothing
is lost but time.

Where the platform has no user ids (Windows), the checks pass: file permissions there are ACLs.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from mitlc.fileio import cache_root

__all__ = ["cache_folder", "untrusted", "untrusted_folder"]


def _uid() -> int | None:
    getuid = getattr(os, "getuid", None)
    return getuid() if getuid is not None else None


def _owner_problem(st: os.stat_result, uid: int) -> str | None:
    if st.st_uid not in (uid, 0):
        return f"owned by user {st.st_uid}, not by you ({uid})"
    return None


def untrusted_folder(path: Path) -> str | None:
    """Why the folder ``path`` may not hold cache files mitlc reads (None: it may), as words that
    follow "it is": ``owned by user 1001, not by you (0)``, ``writable by others (mode 0777; ...)``."""
    uid = _uid()
    if uid is None:
        return None
    try:
        st = os.stat(path)
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    if not stat.S_ISDIR(st.st_mode):
        return "not a folder"
    problem = _owner_problem(st, uid)
    if problem is not None:
        return problem
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"writable by others (mode {stat.S_IMODE(st.st_mode):04o}; chmod go-w {path})"
    return None


def untrusted(path: Path) -> str | None:
    """Why the cache file ``path`` may not be read (None: it may). A missing file is untrusted too."""
    uid = _uid()
    if uid is None:
        return None
    try:
        st = os.stat(path)
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    if not stat.S_ISREG(st.st_mode):
        return "not a regular file"
    problem = _owner_problem(st, uid)
    if problem is not None:
        return problem
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        try:
            folder = os.stat(path.parent)
        except OSError as exc:
            return f"in an unreadable folder ({exc.strerror or exc})"
        if folder.st_mode & (stat.S_IXGRP | stat.S_IXOTH):  # others can reach it, and write it
            return f"writable by others (mode {stat.S_IMODE(st.st_mode):04o}; chmod go-w {path})"
    return None


def cache_folder(*parts: str) -> tuple[Path | None, str | None]:
    """``(folder, None)``: the cache's folder ``parts`` (``"parser"``, ``"kernels"``), made (mode
    ``0700``) where missing, and it and every folder from the cache root down to it checked by
    :func:`untrusted_folder`; ``(None, why not)`` when the disk cache is off, cannot be made, or is
    not to be trusted."""
    root = cache_root()
    if root is None:
        return None, "the disk cache is off (MITLC_CACHE_DIR is empty)"
    folder = root
    for i, part in enumerate(("", *parts)):
        folder = folder / part if part else folder
        try:
            if i == 0:
                folder.mkdir(mode=0o700, parents=True, exist_ok=True)
            else:
                folder.mkdir(mode=0o700, exist_ok=True)
        except OSError as exc:
            return None, f"cannot make {folder}: {exc.strerror or exc}"
        problem = untrusted_folder(folder)
        if problem is not None:
            return None, f"{folder} is {problem}"
    return folder, None
