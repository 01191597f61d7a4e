"""Writing files so that nobody ever sees half of one.

Every file mitlc writes goes through :func:`atomic_write`: the data goes to a
temporary file in the same directory, which is then renamed over the target.

>>> import tempfile, pathlib, numpy as np
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> save_npz(d / "a.npz", {"x": np.arange(3)})
>>> np.load(d / "a.npz")["x"].tolist()
[0, 1, 2]
"""

from __future__ import annotations

import io
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import InputError

__all__ = ["atomic_write", "save_npz", "write_block"]


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
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
            fh.flush()
            os.fsync(fh.fileno())  # the data is on disk before the name points at it
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def save_npz(path: str | Path, arrays: Mapping[str, np.ndarray]) -> None:
    """:func:`numpy.savez` to ``path``, atomically."""
    buf = io.BytesIO()
    named: dict[str, Any] = dict(arrays)  # numpy's stub reads **kwargs as if they could be allow_pickle
    np.savez(buf, **named)
    atomic_write(path, buf.getvalue())


def write_block(path: str | Path, begin: str, end: str, block: str) -> None:
    r"""Replace the text from the line ``begin`` to the line ``end`` of a text file by ``block``
    (which carries both markers), or append ``block`` when the file has none; atomically.

    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "page.md"
    >>> _ = p.write_text("# page\n\n<!-- a -->\nold\n<!-- /a -->\nrest\n")
    >>> write_block(p, "<!-- a -->", "<!-- /a -->", "<!-- a -->\nnew\n<!-- /a -->\n")
    >>> p.read_text()
    '# page\n\n<!-- a -->\nnew\n<!-- /a -->\nrest\n'
    """
    text = Path(path).read_text(encoding="utf-8")
    if begin in text:
        text = text[: text.index(begin)] + block + text[text.index(end) + len(end) + 1 :]
    else:
        text = text.rstrip("\n") + "\n\n" + block
    atomic_write(path, text)
