"""Recorded traces from files: ``.csv`` (a header row naming a column ``t`` and the state
variables; other columns are ignored) or ``.npz`` (arrays ``t`` and one per state
variable, or ``t`` and ``x`` of shape ``(N+1, n)`` in the plant's state order).

The time step must be uniform; every problem is an :class:`~mitlc.errors.InputError`
naming the file and, for a CSV, the line.
"""

from __future__ import annotations

import csv
import math
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from mitlc.errors import InputError
from mitlc.limits import MIN_DT

__all__ = ["Trace", "read_trace", "write_trace", "UNIFORM_TOL"]

UNIFORM_TOL = 1e-3
"""How far (as a fraction of the time step) a sample time may stray from the uniform grid."""


class Trace:
    """A loaded trace: sample times and one array per column."""

    def __init__(
        self, path: str, t: np.ndarray, columns: dict[str, np.ndarray], lines: list[int] | None = None
    ) -> None:
        self.path = path
        self.t = t
        self.columns = columns
        self.lines = lines  # source line of each sample (CSV only)

    def line(self, k: int) -> int | None:
        return self.lines[k] if self.lines is not None else None


def _read_csv(path: str, needed: tuple[str, ...]) -> Trace:
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:  # a byte-order mark is allowed
            text = fh.read()
    except OSError as exc:
        raise InputError(f"cannot read trace: {exc.strerror}", file=path) from None
    except UnicodeDecodeError:
        raise InputError("cannot read trace: not UTF-8 text", file=path) from None
    rows = [(n, r) for n, r in enumerate(csv.reader(text.splitlines()), start=1) if any(c.strip() for c in r)]
    if not rows:
        raise InputError("trace file is empty (expected a header row with 't' and the state variables)", file=path)
    head_line, header = rows[0]
    names = [h.strip() for h in header]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise InputError(f"duplicate column '{name}'", file=path, line=head_line)
    for want in ("t",) + needed:
        if want not in names:
            raise InputError(f"missing column '{want}'", file=path, line=head_line, hint=f"columns: {', '.join(names)}")
    idx = {name: names.index(name) for name in ("t",) + needed}
    data = {name: np.empty(len(rows) - 1) for name in idx}
    lines = []
    for k, (n, row) in enumerate(rows[1:]):
        if len(row) != len(names):
            raise InputError(f"row has {len(row)} fields, the header has {len(names)}", file=path, line=n)
        for name, i in idx.items():
            cell = row[i].strip()
            try:
                value = float(cell)
            except ValueError:
                raise InputError(f"not a number: '{cell}' (column {name})", file=path, line=n) from None
            if not math.isfinite(value):
                raise InputError(f"not a finite number: '{cell}' (column {name})", file=path, line=n)
            data[name][k] = value
        lines.append(n)
    t = data.pop("t")
    return Trace(path, t, data, lines)


def _read_npz(path: str, needed: tuple[str, ...], order: tuple[str, ...]) -> Trace:
    try:
        archive = np.load(path, allow_pickle=False)
    except OSError as exc:
        raise InputError(f"cannot read trace: {exc.strerror or exc}", file=path) from None
    except (ValueError, zipfile.BadZipFile, EOFError):
        raise InputError("cannot read trace: not a .npz archive", file=path) from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise InputError("cannot read trace: a single .npy array, not a .npz archive", file=path)
    with archive:
        names = list(archive.files)
        if "t" not in names:
            raise InputError("missing array 't'", file=path, hint=f"arrays: {', '.join(names) or 'none'}")
        try:
            arrays = {name: np.asarray(archive[name]) for name in names}
        except (ValueError, OSError, zipfile.BadZipFile):
            raise InputError("cannot read trace: damaged .npz archive", file=path) from None
    t = arrays["t"]
    if t.ndim != 1:
        raise InputError(f"array 't' has shape {t.shape}, expected (N+1,)", file=path)
    columns: dict[str, np.ndarray] = {}
    if all(n in arrays for n in needed) and needed:
        for n in needed:
            columns[n] = arrays[n]
    elif "x" in arrays:
        x = arrays["x"]
        if x.ndim != 2 or x.shape[1] != len(order):
            raise InputError(
                f"array 'x' has shape {x.shape}, expected (N+1, {len(order)}) with columns {', '.join(order)}",
                file=path,
            )
        columns = {n: x[:, order.index(n)] for n in needed}
    else:
        missing = next(n for n in needed if n not in arrays)
        raise InputError(
            f"missing array '{missing}' (or 'x' with columns {', '.join(order)})",
            file=path,
            hint=f"arrays: {', '.join(names)}",
        )
    for name, a in [("t", t)] + list(columns.items()):
        if not np.issubdtype(a.dtype, np.number) or a.dtype.kind == "c":
            raise InputError(f"array '{name}' does not hold real numbers ({a.dtype})", file=path)
        if a.shape != t.shape:
            raise InputError(
                f"array '{name}' has {a.shape[0] if a.ndim else 0} samples, 't' has {t.shape[0]}", file=path
            )
        bad = ~np.isfinite(a.astype(float))
        if bad.any():
            k = int(np.argmax(bad))
            raise InputError(
                f"array '{name}' holds a value that is not a finite number at sample {k}: {a[k]}", file=path
            )
    return Trace(path, t.astype(float), {n: a.astype(float) for n, a in columns.items()})


def read_trace(path: str, needed: tuple[str, ...], order: tuple[str, ...]) -> tuple[Trace, float]:
    """Load ``path`` (.csv or .npz) and check its time column; return it and the time step."""
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        trace = _read_csv(path, needed)
    elif suffix == ".npz":
        trace = _read_npz(path, needed, order)
    else:
        raise InputError(f"trace must be .csv or .npz, not '{suffix or Path(path).name}'", file=path)
    t = trace.t
    if len(t) < 2:
        raise InputError(f"a trace needs at least 2 samples to tell the time step, got {len(t)}", file=path)
    steps = np.diff(t)
    if (steps <= 0).any():
        k = int(np.argmax(steps <= 0)) + 1
        raise InputError(f"time must increase: t = {t[k]:g} after t = {t[k - 1]:g}", file=path, line=trace.line(k))
    uneven = np.abs(steps - steps[0]) > UNIFORM_TOL * steps[0]
    if uneven.any():
        k = int(np.argmax(uneven)) + 1
        raise InputError(
            f"time step is not uniform: t goes from {t[k - 1]:g} to {t[k]:g} (a step of {steps[k - 1]:g} s), "
            f"the first step is {steps[0]:g} s",
            file=path,
            line=trace.line(k),
        )
    n = len(t) - 1
    dt = float((t[-1] - t[0]) / n)
    if not dt >= MIN_DT:
        raise InputError(f"the time step {dt:g} s is below the smallest supported, {MIN_DT:g} s", file=path)
    grid = t[0] + dt * np.arange(n + 1)
    off = np.abs(t - grid) > UNIFORM_TOL * dt
    if off.any():  # small steps that drift away from the grid
        k = int(np.argmax(off))
        raise InputError(
            f"time step is not uniform: t = {t[k]:g} is off the grid t0 + k * {dt:g} s",
            file=path,
            line=trace.line(k),
        )
    return trace, dt


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
