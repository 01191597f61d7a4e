"""What every command shares: clean error reporting and atomic file writes.

Command modules import these from here; :mod:`mitlc.cli` imports the command
modules to register them, so nothing here may import :mod:`mitlc.cli`.
"""

from __future__ import annotations

import functools
import os
import sys
import tempfile
from pathlib import Path
from typing import Any, Callable

import click

from mitlc.errors import InputError, MitlError

__all__ = ["handle_errors", "atomic_write"]


def handle_errors(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Turn :class:`MitlError` into a clean message on stderr and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except MitlError as exc:
            click.echo(exc.render(), err=True)
            sys.exit(2)

    return wrapper


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename.

    Readers never see a half-written file, and a failed write leaves no file
    behind. The file gets the usual permissions (0666 less the umask).
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise InputError(f"output directory does not exist: {directory}", file=str(path))
    payload = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=directory)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
