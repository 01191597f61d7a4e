"""Recorded traces from files: ``.csv`` (a header row naming a column ``t`` and the state
variables; other columns are ignored) or ``.npz`` (arrays ``t`` and one per state
variable, or ``t`` and ``x`` of shape ``(N+1, n)`` in the plant's state order).

The time step must be uniform; every problem is an :class:`~mitlc.errors.InputError`
naming the file and, for a CSV, the line.
"""

from __future__ import annotations

import bisect
import codecs
import csv
import functools
import io
import math
import os
import sys
import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from types import ModuleType
from typing import BinaryIO

import numpy as np

from mitlc.errors import InputError
from mitlc.limits import MAX_COLUMNS, MAX_STEPS, MAX_TIME, MIN_DT, check_samples
from mitlc.npzfile import NpzArchive, regular_file

__all__ = ["Trace", "SourceLines", "read_trace", "write_trace", "UNIFORM_TOL", "CHUNK_BYTES"]

UNIFORM_TOL = 1e-3
"""How far (as a fraction of the time step) a sample time may stray from the uniform grid."""


class Trace:
    """A loaded trace: sample times and one array per column."""

    def __init__(
        self, path: str, t: np.ndarray, columns: dict[str, np.ndarray], lines: SourceLines | None = None
    ) -> None:
        self.path = path
        self.t = t
        self.columns = columns
        self.lines = lines  # source line of each sample (CSV only)

    def line(self, k: int) -> int | None:
        return self.lines[k] if self.lines is not None else None


class SourceLines:
    """The source line of each sample of a CSV, by runs: a run of samples on consecutive lines is
    its first line; a run with blank lines among its rows keeps an array of its lines."""

    def __init__(self) -> None:
        self._starts: list[int] = []  # the first sample of each run
        self._runs: list[int | np.ndarray] = []
        self._n = 0

    def add(self, count: int, lines: int | np.ndarray) -> None:
        """The next ``count`` samples: on the lines from ``lines`` on, or on the lines ``lines`` lists."""
        if count:
            self._starts.append(self._n)
            self._runs.append(lines)
            self._n += count

    def __len__(self) -> int:
        return self._n

    def __getitem__(self, k: int) -> int:
        if not 0 <= k < self._n:
            raise IndexError(k)
        i = bisect.bisect_right(self._starts, k) - 1
        run = self._runs[i]
        return run + k - self._starts[i] if isinstance(run, int) else int(run[k - self._starts[i]])


CHUNK_BYTES = 1 << 24
"""Text read and parsed at a time (16 MiB, about 300 000 rows of three 17-digit numbers)."""

_NUMERIC = b"0123456789.eE+-, \t\n"
"""The bytes of a chunk numpy parses as Python's ``float`` would; a chunk with any other byte
(a quote, a letter, a non-ASCII character, a line break other than LF or CRLF) is read row by row."""

_NOT_UTF8 = "cannot read trace: not UTF-8 text"


class _LimitError(InputError):
    """A CSV trace past a limit: said at once, the rest of the file not read (nor checked for UTF-8)."""


def _limit_message() -> str:
    return f"the trace has more than {MAX_STEPS + 1:,} samples (rows), the most supported ({MAX_STEPS:,} time steps)"


def _shown(name: str, width: int = 40) -> str:
    """A column's name as a message shows it: at most ``width`` characters."""
    return name if len(name) <= width else name[:width] + "..."


READER_ENV = "MITLC_CSV_READER"
"""``MITLC_CSV_READER=numpy`` reads CSV traces with the numpy reader even where pyarrow is installed."""


ARROW_MIN_BYTES = 2 << 20
"""The smallest CSV file pyarrow reads while it is not yet imported: importing it costs about 27 ms, what
the numpy reader spends on some 40,000 rows of three columns (2 MB; measured on this 2-core machine:
30,000 rows numpy 21 ms, pyarrow 28 + 8 ms; 100,000 rows numpy 70 ms, pyarrow 26 + 20 ms)."""


def _read_csv(path: str, needed: tuple[str, ...]) -> Trace:
    """Read a CSV trace: with pyarrow (the ``fast`` extra) when it reads the file exactly as the
    numpy reader would and the file is big enough to pay for importing it (:data:`ARROW_MIN_BYTES`),
    else (and for every error's message) with :func:`_read_csv_numpy`; the same numbers either way."""
    if os.environ.get(READER_ENV, "") != "numpy" and _arrow_pays(path):
        trace = _read_csv_arrow(path, needed)
        if trace is not None:
            return trace
    return _read_csv_numpy(path, needed)


def _arrow_pays(path: str) -> bool:
    """Whether pyarrow should read ``path``: it is imported already, or the file is big (or cannot be
    sized: the reader says why)."""
    if "pyarrow.csv" in sys.modules:
        return True
    try:
        return os.path.getsize(path) >= ARROW_MIN_BYTES
    except OSError:
        return True


@functools.cache
def _pyarrow() -> tuple[ModuleType, ModuleType] | None:
    """pyarrow and pyarrow.csv, or None where pyarrow is not installed (or does not load)."""
    try:
        import pyarrow
        import pyarrow.csv
    except Exception:  # not installed, or an install that does not load: the numpy reader reads
        return None
    return pyarrow, pyarrow.csv


def _read_csv_arrow(path: str, needed: tuple[str, ...]) -> Trace | None:
    """pyarrow's streaming CSV reader (correctly rounded floats, as Python's ``float``), or None.

    It is used only where it cannot differ from the numpy reader: the header (found and checked
    as the numpy reader does) is one plain line ending in LF or CRLF, and pyarrow is told to read
    every cell of every later line as a float64, with no quoting, no nulls and no blank lines. A
    file it reads so holds only float literals and LF, CR or CRLF line ends, so sample k is on
    the k-th line after the header and every value is the one ``float`` gives. Anything else
    (a cell that is not a float literal, ``1_0``, a quote, a blank or ragged line, a value that
    is not finite, a missing column, no data, more samples than the limit: any doubt) returns
    None, and the numpy reader reads the file or says, as ever, what is wrong and on which line.
    Only the columns needed are kept, block by block.
    """
    mods = _pyarrow()
    if mods is None:
        return None
    pa, pcsv = mods
    try:
        with open(path, "rb") as fh:
            head = fh.read(_HEAD_BYTES)
    except OSError:
        return None
    found = _header(path, head, needed)
    if found is None:
        return None
    reader, line, offset = found
    if head[offset : offset + len(codecs.BOM_UTF8)] == codecs.BOM_UTF8:  # pyarrow would drop a BOM here
        return None
    temp = [f"c{i}" for i in range(len(reader.names))]  # the names are unique, but not every string is a name
    parts: dict[str, list[np.ndarray]] = {name: [] for name in reader.idx}
    n = 0
    try:
        with pa.OSFile(path) as source:
            source.seek(offset)
            batches = pcsv.open_csv(  # streamed: a trace past the sample limit is not read to its end
                source,
                read_options=pcsv.ReadOptions(column_names=temp, block_size=_ARROW_BLOCK),
                parse_options=pcsv.ParseOptions(
                    quote_char=False, escape_char=False, double_quote=False, ignore_empty_lines=False
                ),
                convert_options=pcsv.ConvertOptions(
                    column_types={c: pa.float64() for c in temp},
                    null_values=[],
                    true_values=[],
                    false_values=[],
                    strings_can_be_null=False,
                    quoted_strings_can_be_null=False,
                ),
            )
            for batch in batches:
                rows = min(batch.num_rows, MAX_STEPS + 1 - n)  # the rows within the sample limit
                for name, i in reader.idx.items():
                    chunk = batch.column(i)  # a float64 buffer, read in place (to_numpy would load pandas)
                    if chunk.null_count or chunk.type != pa.float64():
                        return None
                    values = np.frombuffer(chunk.buffers()[1], dtype=np.float64, count=rows, offset=8 * chunk.offset)
                    if not np.isfinite(values).all():
                        return None
                    parts[name].append(values.copy())
                n += rows
                if rows < batch.num_rows:  # a sample past the limit, every one before it good: on its own line
                    break
            else:
                batch = None
    except (pa.ArrowException, ValueError, OSError):
        return None
    if batch is not None:  # as the numpy reader says it, the rest of the file unread
        raise _LimitError(_limit_message(), file=path, line=line + 1 + n)
    columns = {name: np.concatenate(p) if p else np.empty(0) for name, p in parts.items()}
    del parts
    lines = SourceLines()
    lines.add(n, line + 1)
    t = columns.pop("t")
    return Trace(path, t, columns, lines)


_HEAD_BYTES = 1 << 16
"""How far into the file the pyarrow path looks for the header (a longer one: the numpy reader)."""

_ARROW_BLOCK = 1 << 22
"""pyarrow's block, parsed by one thread: 4 MiB (its default, 1 MiB, was slower here on 10M rows;
4 MiB splits a 100k-row file in two)."""


def _header(path: str, head: bytes, needed: tuple[str, ...]) -> tuple[_CsvReader, int, int] | None:
    """The header the numpy reader would find in ``head`` (its reader, the header's line, the offset
    of the first byte after it), or None: not found in plain lines that end in LF, or not valid."""
    start = len(codecs.BOM_UTF8) if head.startswith(codecs.BOM_UTF8) else 0
    line = 1
    reader = _CsvReader(path, io.BytesIO(), needed)
    while True:
        end = head.find(b"\n", start) + 1
        if not end:
            return None
        try:
            text = head[start:end].decode("utf-8")
        except UnicodeDecodeError:
            return None
        parts = text.splitlines()
        if len(parts) != 1 or '"' in text:  # another line break (CR, FF, U+2028, ...), or csv quoting
            return None
        row = next(csv.reader(parts), [])
        if any(c.strip() for c in row):
            try:
                reader.header(row, line)
            except InputError:
                return None
            return reader, line, end
        line += 1
        start = end


def _read_csv_numpy(path: str, needed: tuple[str, ...]) -> Trace:
    """Read a CSV trace in chunks: numpy parses a chunk of plain numbers at once; a chunk it
    refuses (or any other) is read row by row, which finds the first bad row and says where."""
    try:
        with open(path, "rb") as fh:
            try:
                return _CsvReader(path, fh, needed).read()
            except _LimitError:
                raise
            except InputError:
                if not _utf8(fh):  # the whole file is decoded first, as text: not UTF-8 comes before a bad row
                    raise InputError(_NOT_UTF8, file=path) from None
                raise
    except OSError as exc:
        raise InputError(f"cannot read trace: {exc.strerror}", file=path) from None


def _utf8(fh: BinaryIO) -> bool:
    fh.seek(0)
    decoder = codecs.getincrementaldecoder("utf-8")()
    try:
        while block := fh.read(CHUNK_BYTES):
            decoder.decode(block)
        decoder.decode(b"", final=True)
    except UnicodeDecodeError:
        return False
    return True


class _CsvReader:
    def __init__(self, path: str, fh: BinaryIO, needed: tuple[str, ...]) -> None:
        self.path = path
        self.fh = fh
        self.needed = needed
        self.names: list[str] = []
        self.idx: dict[str, int] = {}
        self.parts: list[np.ndarray] = []  # (rows, columns of idx) per chunk
        self.lines = SourceLines()

    def chunks(self) -> Iterator[bytes]:
        """The file's bytes in pieces that end at a line feed (the last one may not), a BOM dropped."""
        rest = b""
        first = True
        while block := self.fh.read(CHUNK_BYTES):
            if first:
                block = block.removeprefix(codecs.BOM_UTF8)
                first = False
            rest += block
            cut = rest.rfind(b"\n") + 1
            if cut:
                yield rest[:cut]
                rest = rest[cut:]
        if rest:
            yield rest

    def read(self) -> Trace:
        line = 1  # the number of the chunk's first line
        for chunk in self.chunks():
            while not self.names and chunk:  # the header is the first row that is not blank
                cut = chunk.find(b"\n") + 1 or len(chunk)
                line = self.slow(chunk[:cut], line)
                chunk = chunk[cut:]
            if chunk:
                line = self.fast(chunk, line)
        if not self.names:
            raise InputError(
                "trace file is empty (expected a header row with 't' and the state variables)", file=self.path
            )
        data = np.concatenate(self.parts) if self.parts else np.empty((0, len(self.idx)))
        columns = {name: np.ascontiguousarray(data[:, j]) for j, name in enumerate(self.idx)}
        t = columns.pop("t")
        return Trace(self.path, t, columns, self.lines)

    def fast(self, chunk: bytes, line: int) -> int:
        """Parse a chunk of plain numbers with numpy; anything else (or any doubt) goes row by row.
        Returns the number of the next chunk's first line."""
        text = chunk.replace(b"\r\n", b"\n") if b"\r" in chunk else chunk
        if b"\r" in text or text.translate(None, _NUMERIC) or len(self.names) < 2:
            return self.slow(chunk, line)
        count = text.count(b"\n") + (not text.endswith(b"\n"))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "input contained no data": a shape check below
                a = np.loadtxt(io.BytesIO(text), delimiter=",", comments=None, dtype=float, ndmin=2)
        except ValueError:
            return self.slow(chunk, line)
        if a.shape != (count, len(self.names)):  # a blank line numpy skipped, a row's wrong length
            return self.slow(chunk, line)
        a = a[:, list(self.idx.values())]
        if not np.isfinite(a).all():
            return self.slow(chunk, line)
        before = len(self.lines)
        if before + count > MAX_STEPS + 1:
            self.limit(line + MAX_STEPS + 1 - before)  # the rows are on consecutive lines
        self.parts.append(a)
        self.lines.add(count, line)
        return line + count

    def slow(self, chunk: bytes, line: int) -> int:
        """The chunk row by row, as Python's csv and float read it: the first bad row is an error
        with its line. Returns the number of the next chunk's first line."""
        try:
            text = chunk.decode("utf-8")
        except UnicodeDecodeError:
            raise InputError(_NOT_UTF8, file=self.path) from None
        values: list[list[float]] = []
        where: list[int] = []
        n = line - 1
        try:
            for n, row in enumerate(csv.reader(text.splitlines()), start=line):
                if not any(c.strip() for c in row):
                    continue
                if not self.names:
                    self.header(row, n)
                    continue
                if len(row) != len(self.names):
                    raise InputError(
                        f"row has {len(row)} fields, the header has {len(self.names)}", file=self.path, line=n
                    )
                values.append([self.number(row[i], name, n) for name, i in self.idx.items()])
                where.append(n)
                if len(self.lines) + len(where) > MAX_STEPS + 1:
                    self.limit(n)
        except csv.Error as exc:
            raise InputError(f"cannot read trace: {exc}", file=self.path, line=n + 1) from None
        if values:
            self.parts.append(np.array(values, dtype=float))
            self.lines.add(len(where), np.array(where, dtype=np.int64))
        return n + 1

    def limit(self, line: int) -> None:
        """Refuse the trace, its row on ``line`` one sample more than :data:`~mitlc.limits.MAX_STEPS`
        allows: the rest of the file is not read."""
        raise _LimitError(_limit_message(), file=self.path, line=line)

    def header(self, row: list[str], line: int) -> None:
        if len(row) > MAX_COLUMNS:
            raise _LimitError(
                f"the header has {len(row):,} columns, more than the {MAX_COLUMNS:,} supported",
                file=self.path,
                line=line,
            )
        names = [h.strip() for h in row]
        index: dict[str, int] = {}
        for i, name in enumerate(names):
            if index.setdefault(name, i) != i:
                raise InputError(f"duplicate column '{_shown(name)}'", file=self.path, line=line)
        for want in ("t",) + self.needed:
            if want not in index:
                shown = ", ".join(_shown(n) for n in names[:20]) + (
                    f", ... ({len(names):,} in all)" if len(names) > 20 else ""
                )
                raise InputError(f"missing column '{want}'", file=self.path, line=line, hint=f"columns: {shown}")
        self.names = names
        self.idx = {name: index[name] for name in ("t",) + self.needed}

    def number(self, cell: str, name: str, line: int) -> float:
        cell = cell.strip()
        try:
            value = float(cell)
        except ValueError:
            raise InputError(f"not a number: '{cell}' (column {name})", file=self.path, line=line) from None
        if not math.isfinite(value):
            raise InputError(f"not a finite number: '{cell}' (column {name})", file=self.path, line=line)
        return value


_REAL = "fiu"
"""The dtype kinds of a trace's arrays: real numbers (float, signed and unsigned integers)."""


def _read_npz(path: str, needed: tuple[str, ...], order: tuple[str, ...]) -> Trace:
    """The arrays ``t`` and ``needed`` (or ``x``) of an ``.npz`` trace, each header checked (shape,
    dtype, the sample limit) before its data is read; other arrays are not read."""
    with NpzArchive(path, "trace") as archive:
        names = archive.names
        if "t" not in archive:
            raise InputError("missing array 't'", file=path, hint=f"arrays: {', '.join(names) or 'none'}")
        t = archive.header("t")
        if len(t.shape) != 1:
            raise InputError(f"array 't' has shape {t.shape}, expected (N+1,)", file=path)
        try:
            check_samples(t.shape[0])
        except ValueError as exc:
            raise InputError(str(exc), file=path) from None
        members = {"t": t}
        if not needed:
            pass
        elif all(n in archive for n in needed):
            members.update({n: archive.header(n) for n in needed})
        elif "x" in archive:
            x = archive.header("x")
            if len(x.shape) != 2 or x.shape[1] != len(order):
                raise InputError(
                    f"array 'x' has shape {x.shape}, expected (N+1, {len(order)}) with columns {', '.join(order)}",
                    file=path,
                )
            if x.shape[0] != t.shape[0]:
                raise InputError(f"array 'x' has {x.shape[0]} samples, 't' has {t.shape[0]}", file=path)
            members["x"] = x
        else:
            missing = next(n for n in needed if n not in archive)
            raise InputError(
                f"missing array '{missing}' (or 'x' with columns {', '.join(order)})",
                file=path,
                hint=f"arrays: {', '.join(names)}",
            )
        for name, m in members.items():
            if m.dtype.kind not in _REAL:
                raise InputError(f"array '{name}' does not hold real numbers ({m.dtype})", file=path)
            if name != "x" and m.shape != t.shape:
                raise InputError(
                    f"array '{name}' has {m.shape[0] if m.shape else 0} samples, 't' has {t.shape[0]}", file=path
                )
        arrays = {name: archive.read(name, m.nbytes) for name, m in members.items()}
    t_values = arrays.pop("t")
    if "x" in arrays:
        x_values = arrays.pop("x")
        arrays = {n: x_values[:, order.index(n)] for n in needed}
    for name, a in [("t", t_values), *arrays.items()]:
        bad = ~np.isfinite(a.astype(float))
        if bad.any():
            k = int(np.argmax(bad))
            raise InputError(
                f"array '{name}' holds a value that is not a finite number at sample {k}: {a[k]}", file=path
            )
    return Trace(path, t_values.astype(float), {n: a.astype(float) for n, a in arrays.items()})


def read_trace(path: str, needed: tuple[str, ...], order: tuple[str, ...]) -> tuple[Trace, float]:
    """Load ``path`` (.csv or .npz) and check its time column; return it and the time step."""
    suffix = Path(path).suffix.lower()
    if suffix in (".csv", ".npz"):
        regular_file(path, "trace")  # a FIFO would block forever, a device never end
    if suffix == ".csv":
        trace = _read_csv(path, needed)
    elif suffix == ".npz":
        trace = _read_npz(path, needed, order)
    else:
        raise InputError(f"trace must be .csv or .npz, not '{suffix or Path(path).name}'", file=path)
    with np.errstate(over="ignore", invalid="ignore"):  # times of +-1e308: said in words, not warnings
        return trace, _time_step(trace, path)


def _time_step(trace: Trace, path: str) -> float:
    """The trace's time step, after checking that its times increase, span no more than
    :data:`~mitlc.limits.MAX_TIME` and are uniform."""
    t = trace.t
    if len(t) < 2:
        raise InputError(f"a trace needs at least 2 samples to tell the time step, got {len(t)}", file=path)
    step0 = t[1] - t[0]
    backwards = uneven = None  # the first sample after a step that is not positive, or not the first step
    for a in range(0, len(t) - 1, _BLOCK):  # in blocks: no temporary as long as the trace
        steps = np.diff(t[a : a + _BLOCK + 1])
        if backwards is None and (steps <= 0).any():
            backwards = a + int(np.argmax(steps <= 0)) + 1
        bad = np.abs(steps - step0) > UNIFORM_TOL * step0  # a step of 1e308 from -1e308 is uneven
        if uneven is None and bad.any():
            uneven = a + int(np.argmax(bad)) + 1
        if backwards is not None:
            break
    if backwards is not None:
        k = backwards
        raise InputError(f"time must increase: t = {t[k]:g} after t = {t[k - 1]:g}", file=path, line=trace.line(k))
    if not t[-1] - t[0] <= MAX_TIME:
        raise InputError(
            f"the trace spans t = {t[0]:g} to {t[-1]:g} s, longer than the longest supported, {MAX_TIME:g} s",
            file=path,
        )
    if uneven is not None:
        k = uneven
        raise InputError(
            f"time step is not uniform: t goes from {t[k - 1]:g} to {t[k]:g} (a step of {t[k] - t[k - 1]:g} s), "
            f"the first step is {step0:g} s",
            file=path,
            line=trace.line(k),
        )
    n = len(t) - 1
    dt = float((t[-1] - t[0]) / n)
    if not dt >= MIN_DT:
        raise InputError(f"the time step {dt:g} s is below the smallest supported, {MIN_DT:g} s", file=path)
    for a in range(0, n + 1, _BLOCK):  # small steps that drift away from the grid t[0] + dt * k
        off = np.abs(t[a : a + _BLOCK] - (t[0] + dt * np.arange(a, min(a + _BLOCK, n + 1)))) > UNIFORM_TOL * dt
        if off.any():
            k = a + int(np.argmax(off))
            raise InputError(
                f"time step is not uniform: t = {t[k]:g} is off the grid t0 + k * {dt:g} s",
                file=path,
                line=trace.line(k),
            )
    return dt


_BLOCK = 1 << 20
"""Samples checked at a time by :func:`read_trace`."""


def write_trace(
    path: str | Path, t: np.ndarray, columns: Mapping[str, np.ndarray], extra: Mapping[str, np.ndarray] | None = None
) -> None:
    """Write one trace in the format :func:`read_trace` (and ``mitlc check``) reads, atomically.

    ``.csv``: a header ``t,<column>,...`` and one row per sample, every float written so
    that it reads back exactly; ``.npz``: the arrays ``t``, one per column, and ``extra``
    (e.g. the inputs ``u``, one fewer than the samples), which ``check`` ignores.
    """
    from mitlc.fileio import atomic_write, save_npz

    t = np.asarray(t, dtype=float)
    cols = {n: np.asarray(v, dtype=float) for n, v in columns.items()}
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        names = list(cols)
        lines = [",".join(["t", *names])]
        for k in range(t.shape[0]):
            lines.append(",".join(repr(float(x)) for x in [t[k], *(cols[n][k] for n in names)]))
        atomic_write(path, "\n".join(lines) + "\n")
    elif suffix == ".npz":
        save_npz(path, {"t": t, **cols, **{k: np.asarray(v) for k, v in (extra or {}).items()}})
    else:
        raise InputError(f"a trace is written as .csv or .npz, not '{suffix or Path(path).name}'", file=str(path))
