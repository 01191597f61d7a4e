"""Reading ``.npz`` archives without trusting them (recorded traces, learners' checkpoints).

:func:`numpy.load` believes an archive: a header that claims 10^12 entries allocates them,
a zip member that unpacks to 6 GB is unpacked, a flipped byte can surface as any exception
zipfile or numpy has. Here an archive is read member by member, and what a member declares
is checked before its data is read: its ``.npy`` header (dtype and shape, which the caller
checks against its limits, see :meth:`NpzArchive.header`) and the zip entry's unpacked size
(``file_size``, at most the data its header declares: :meth:`NpzArchive.read`). Only the
members asked for are read. Every failure is one :class:`~mitlc.errors.InputError` naming the
file (and the array).

>>> import tempfile, pathlib
>>> tmp = tempfile.TemporaryDirectory(); p = pathlib.Path(tmp.name) / "a.npz"
>>> np.savez(p, t=np.arange(3.0))
>>> with NpzArchive(p, "trace") as z:
...     z.names, z.header("t").shape, z.read("t", max_bytes=1000).tolist()
(['t'], (3,), [0.0, 1.0, 2.0])
>>> tmp.cleanup()
"""

from __future__ import annotations

import math
import os
import stat
import tokenize
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO

import numpy as np
from numpy.lib import format as npy

from mitlc.errors import InputError

__all__ = ["NpzArchive", "Member", "regular_file", "HEADER_MAX"]

HEADER_MAX = 10_000
"""The longest ``.npy`` header read (numpy's own default ``max_header_size``)."""

_METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflated"}
"""The zip methods numpy writes (``savez``, ``savez_compressed``): the only ones read."""

_NPY_MAGIC = b"\x93NUMPY"

_BROKEN = (
    zipfile.BadZipFile,
    zlib.error,
    EOFError,
    OSError,
    ValueError,
    TypeError,
    KeyError,
    IndexError,
    OverflowError,
    NotImplementedError,
    RuntimeError,  # also RecursionError
    SyntaxError,
    tokenize.TokenError,  # numpy tokenizes a header before it reads it as a literal
    UnicodeDecodeError,
    MemoryError,
)
"""What zipfile and numpy's header reader raise on damaged data (a CRC, a header, a method)."""


def regular_file(path: str | Path, what: str) -> None:
    """Refuse ``path`` unless it is a regular file: a FIFO would block the read forever, a
    device (``/dev/zero``) never end; a directory is no file to read either."""
    try:
        st = os.stat(path)
    except OSError as exc:
        raise InputError(f"cannot read {what}: {exc.strerror or exc}", file=str(path)) from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise InputError(f"cannot read {what}: {kind}", file=str(path))


def _why(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    line = text[0] if text else type(exc).__name__
    return line if len(line) <= 100 else line[:100] + "..."


@dataclass(frozen=True)
class Member:
    """What a member's ``.npy`` header declares."""

    name: str
    shape: tuple[int, ...]
    dtype: np.dtype
    fortran: bool
    offset: int
    """Bytes of the magic string and header, before the data."""

    @property
    def size(self) -> int:
        """Entries (the product of the shape)."""
        return math.prod(self.shape)

    @property
    def nbytes(self) -> int:
        return self.size * self.dtype.itemsize


class NpzArchive:
    """An ``.npz`` archive open for checked reading; ``what`` names it in messages (``trace``,
    ``checkpoint``). Use as a context manager."""

    def __init__(self, path: str | Path, what: str) -> None:
        self.path = str(path)
        self.what = what
        regular_file(path, what)
        try:
            with open(path, "rb") as fh:  # noqa: PTH123
                magic = fh.read(len(_NPY_MAGIC))
        except OSError as exc:
            raise self._error(exc.strerror or str(exc)) from None
        if magic == _NPY_MAGIC:
            raise self._error("a single .npy array, not a .npz archive")
        try:
            self._zip = zipfile.ZipFile(path)
            infos = self._zip.infolist()
        except _BROKEN as exc:
            raise self._error(f"not a .npz archive ({_why(exc)})") from None
        self._members: dict[str, zipfile.ZipInfo] = {}
        for info in infos:  # numpy's names: a member 'x.npy' is the array 'x'
            if info.filename.endswith(".npy"):
                self._members[info.filename[: -len(".npy")]] = info
        self._headers: dict[str, Member] = {}

    @property
    def names(self) -> list[str]:
        """The arrays the archive holds, in its order."""
        return list(self._members)

    def __contains__(self, name: str) -> bool:
        return name in self._members

    def __enter__(self) -> NpzArchive:
        return self

    def __exit__(self, typ: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    def close(self) -> None:
        self._zip.close()

    def _error(self, why: str) -> InputError:
        return InputError(f"cannot read {self.what}: {why}", file=self.path)

    def _damaged(self, name: str, why: str) -> InputError:
        return self._error(f"array '{name}' is damaged ({why})")

    def _open(self, name: str) -> IO[bytes]:
        info = self._members[name]
        if info.compress_type not in _METHODS:
            raise self._damaged(name, f"zip method {info.compress_type}, not stored or deflated")
        if info.flag_bits & 0x1:
            raise self._damaged(name, "encrypted")
        return self._zip.open(info)

    def header(self, name: str) -> Member:
        """What member ``name`` declares (its ``.npy`` header), its data not read. An array of
        Python objects (which would need unpickling) is refused."""
        if name in self._headers:
            return self._headers[name]
        try:
            with self._open(name) as fh:
                version = npy.read_magic(fh)
                if version == (1, 0):
                    shape, fortran, dtype = npy.read_array_header_1_0(fh, max_header_size=HEADER_MAX)
                elif version == (2, 0):
                    shape, fortran, dtype = npy.read_array_header_2_0(fh, max_header_size=HEADER_MAX)
                else:
                    raise ValueError(f".npy format version {version[0]}.{version[1]}, not 1.0 or 2.0")
                offset = fh.tell()
        except InputError:
            raise
        except _BROKEN as exc:
            raise self._damaged(name, _why(exc)) from None
        if any(not isinstance(n, int) or n < 0 for n in shape):
            raise self._damaged(name, f"shape {shape}")
        if dtype.hasobject:
            raise self._error(f"array '{name}' holds Python objects ({dtype}), not numbers")
        if dtype.itemsize == 0:
            raise self._error(f"array '{name}' holds entries of no size ({dtype})")
        member = Member(name, tuple(shape), dtype, bool(fortran), offset)
        self._headers[name] = member
        return member

    def read(self, name: str, max_bytes: int) -> np.ndarray:
        """The array ``name``, whose header the caller has checked: refused, before any data is
        unpacked, when its data would take more than ``max_bytes`` or the zip entry unpacks to more
        than the header declares (a zip bomb)."""
        m = self.header(name)
        info = self._members[name]
        if m.nbytes > max_bytes:
            raise self._error(
                f"array '{name}' of shape {m.shape} ({m.dtype}) takes {m.nbytes:,} bytes, more than the "
                f"{max_bytes:,} supported"
            )
        if info.file_size > m.offset + m.nbytes + HEADER_MAX:  # room for padding, never for a bomb
            raise self._error(
                f"array '{name}' unpacks to {info.file_size:,} bytes, its header declares {m.nbytes:,} bytes of data"
            )
        data = bytearray(m.nbytes)
        try:
            with self._open(name) as fh:
                fh.read(m.offset)
                view = memoryview(data)
                got = 0
                while got < m.nbytes:
                    n = fh.readinto(view[got:])  # type: ignore[attr-defined]
                    if not n:
                        break
                    got += n
                if got < m.nbytes:
                    raise self._damaged(name, f"truncated: {got:,} of {m.nbytes:,} bytes of data")
                while fh.read(1 << 16):  # the rest of the entry (bounded by file_size above): its CRC is checked
                    pass
        except InputError:
            raise
        except _BROKEN as exc:
            raise self._damaged(name, _why(exc)) from None
        a = np.frombuffer(data, dtype=m.dtype, count=m.size)
        if m.fortran:
            return a.reshape(m.shape[::-1]).transpose()
        return a.reshape(m.shape)
