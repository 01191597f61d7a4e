"""Writing files so that nobody ever sees half of one.

Every file mitlc writes goes through :func:`atomic_write`: the data goes to a
temporary file in the same directory, which is then renamed over the target
(a symlink's target, keeping its mode); devices and pipes are written directly.

>>> import tempfile, pathlib, numpy as np
>>> tmp = tempfile.TemporaryDirectory(); d = pathlib.Path(tmp.name)
>>> save_npz(d / "a.npz", {"x": np.arange(3)})
>>> np.load(d / "a.npz")["x"].tolist()
[0, 1, 2]
>>> tmp.cleanup()
"""

from __future__ import annotations

import io
import json
import os
import stat
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import InputError

__all__ = ["atomic_write", "save_npz", "write_block", "json_text", "finite_or_none", "npz_bytes", "cache_root"]


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


def atomic_write(path: str | Path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` as a shell redirection would, but never half a file.

    A regular file (or none yet) is written through a temporary file in the same
    directory that is then renamed over it: readers never see half of it, a failed
    write leaves the old file (or none), and a replaced file keeps its permission
    bits (a new one gets 0666 less the umask). A symlink is followed and its target
    replaced, so the link stays a link. A character device or a FIFO (``/dev/null``,
    ``/dev/stdout``, a named pipe) is written directly, as ``> path`` would; any other
    kind of file (a directory, a block device, a socket) is refused.
    """
    path = Path(path)
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror or exc}", file=str(path)) from None
    payload = data.encode("utf-8") if isinstance(data, str) else data
    if st is not None and not stat.S_ISREG(st.st_mode):
        if stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode):
            try:
                with open(target, "wb") as fh:  # noqa: PTH123  (a device or a pipe: no rename)
                    fh.write(payload)
            except OSError as exc:
                raise InputError(f"cannot write: {exc.strerror or exc}", file=str(path)) from None
            return
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise InputError(f"cannot write over {kind}", file=str(path))
    directory = target.parent if str(target.parent) else Path(".")
    if not directory.is_dir():
        raise InputError(f"output directory does not exist: {directory}", file=str(path))
    mode = stat.S_IMODE(st.st_mode) if st is not None else 0o666 & ~_umask()
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=directory)
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
            fh.flush()
            os.fsync(fh.fileno())  # the data is on disk before the name points at it
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


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
    return json.dumps(finite_or_none(obj), indent=indent, allow_nan=False, **kw) + "\n"


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
