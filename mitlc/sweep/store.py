"""Results on disk: Results go to a directory through :class:`ResultStore`: ``results.json`` (the
authoritative record) and ``results.csv``, both rewritten atomically after
every finished task, keyed by the task's configuration and seed so a re-run
skips what is done and never counts a task twice.

A sweep's folder is recognisably its own: ``results.json`` starts with ``"format": "mitlc-sweep"``,
``"version": 1`` (one written before the key, with its ``header`` and ``results``, is a sweep's too).
A folder holding anything else and no such file is the user's: a sweep refuses it (one line,
exit 2) and writes nothing there. The folder is locked while a sweep writes to it
(``fcntl.flock`` on ``.sweep.lock``, :class:`mitlc.fileio.FolderLock`).
"""

from __future__ import annotations

import csv
import io
import json
import os
import stat
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mitlc.errors import InputError
from mitlc.fileio import (
    FolderLock,
    LockBusy,
    atomic_write,
    clean_stale_temps,
    json_text,
    lock_owner_pid,
    missing_folders,
    remove_folders,
)
from mitlc.sweep.grid import Axis

RESULTS_JSON = "results.json"
RESULTS_CSV = "results.csv"
SWEEP_PNG = "sweep.png"
LOCK_FILE = ".sweep.lock"
FORMAT = "mitlc-sweep"
VERSION = 1
"""The ``format`` and ``version`` keys that make a ``results.json`` a mitlc sweep's."""
_RESULTS_LIMIT = 1 << 30
"""A ``results.json`` larger than 1 GiB (two million results) is not read."""


# ---------------------------------------------------------------- results on disk
# (atomic_write: mitlc.fileio, temp file + fsync + rename)


CSV_METRICS = ("success_rate", "final_return", "greedy_return", "failing", "wall_s", "cpu_s", "error", "host")


def _csv_cell(v: Any) -> Any:
    """A metric as a CSV cell: floats in full (``repr``), a blame count as ``G !psi: 3; F G kappa: 1``."""
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, dict):
        return "; ".join(f"{k}: {n}" for k, n in v.items())
    return v


class ResultStore:
    """The results of one sweep directory: ``results.json`` (authoritative) and ``results.csv``.

    Records are keyed by task; :meth:`add` ignores a task already recorded, so
    a result is never counted twice, and rewrites both files atomically, so a
    crash at any moment leaves every finished task's result on disk.  While
    open, the directory is locked against a second sweep writing to it.
    """

    def __init__(self, out_dir: str | Path, header: Mapping[str, Any], axes: Sequence[Axis]) -> None:
        self.dir = Path(out_dir)
        self.header = dict(header)
        self.records: dict[str, dict] = {}
        self.axes: list[Axis] = list(axes)
        self._lock: FolderLock | None = None
        self._made: list[Path] = []
        self._load()

    # the directory lock
    def __enter__(self) -> ResultStore:
        d = self.dir
        for parent in [d, *d.parents]:
            if parent.exists() and not parent.is_dir():
                raise InputError(f"cannot create the output folder {d}: {parent} is a file", file="--out")
        made = missing_folders(d)
        try:
            d.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            remove_folders(made)
            raise InputError(f"cannot create the output folder {d}: {exc.strerror or exc}", file="--out") from None
        lock = FolderLock(d / LOCK_FILE)
        try:
            lock.acquire()
        except LockBusy as busy:
            pid = lock_owner_pid(busy.owner)
            raise InputError(
                f"another sweep is writing to {d}{f' (pid {pid})' if pid is not None else ''}", file="--out"
            ) from None
        except OSError as exc:
            remove_folders(made)
            raise InputError(f"cannot write into {d}: {exc.strerror or exc}", file="--out") from None
        self._lock = lock
        self._made = made
        clean_stale_temps(d, time.time() - 60, legacy=(RESULTS_JSON, RESULTS_CSV, SWEEP_PNG))
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None
        if self._made and not (self.dir / RESULTS_JSON).exists():  # it failed before its first write
            remove_folders(self._made)
        self._made = []

    def _load(self) -> None:
        d = self.dir
        if not d.is_dir():
            return  # a new folder (or a file: refused when the folder is made)
        try:
            names = sorted(p.name for p in d.iterdir() if not p.name.startswith("."))
        except OSError as exc:
            raise InputError(f"cannot read {d}: {exc.strerror or exc}", file="--out") from None
        path = d / RESULTS_JSON
        data = _read_results(path) if RESULTS_JSON in names else None
        if data is None:
            if names:
                shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
                raise InputError(
                    f"{d} holds files that are not a mitlc sweep ({shown}); a sweep writes only into a new or "
                    "empty folder or one of its own sweeps: give another --out",
                    file="--out",
                )
            return
        header, records = data.get("header"), data.get("results")
        if not isinstance(header, dict) or not isinstance(records, list):
            raise InputError(
                "cannot read earlier results: 'header' is not an object or 'results' not a list", file=str(path)
            )
        for k, v in self.header.items():
            if header.get(k) != v:
                what = (
                    "another spec text"
                    if k == "spec_sha256"
                    else f"{k} {header.get(k)}, not {v}"
                    if k in ("runs", "trials")
                    else f"spec {header.get(k)}, not {v}"
                )
                raise InputError(
                    f"{self.dir} holds a sweep with {what}",
                    file="--out",
                    hint="choose another --out directory, or use the same spec, --runs and --trials",
                )
        for i, r in enumerate(records):
            if not (isinstance(r, dict) and isinstance(r.get("task"), str)):
                raise InputError(f"cannot read earlier results: result {i + 1} has no 'task' key", file=str(path))
            self.records.setdefault(r["task"], r)
        known = {a.name for a in self.axes}
        axes = data.get("axes", {})
        for name, spec in axes.items() if isinstance(axes, dict) else ():
            if not (isinstance(spec, dict) and isinstance(spec.get("kind"), str) and isinstance(spec.get("key"), str)):
                raise InputError(f"cannot read earlier results: axis '{name}' has no kind and key", file=str(path))
            if name not in known:
                self.axes.append(Axis(name, spec["kind"], spec["key"], (), ()))
                known.add(name)

    def __contains__(self, key: str) -> bool:
        return key in self.records

    def __len__(self) -> int:
        return len(self.records)

    def add(self, record: Mapping[str, Any], write: bool = True) -> bool:
        """Record a finished task and (unless ``write`` is False) rewrite the files.

        Returns False, and changes nothing, if the task was already recorded.
        """
        if record["task"] in self.records:
            return False
        self.records[record["task"]] = dict(record)
        self.dirty = True
        if write:
            self.write()
        return True

    dirty = False
    """Records were added since the files were last written."""

    def json_text(self) -> str:
        """``results.json``: the header and axes, then one compact line per result."""
        axes = {a.name: {"kind": a.kind, "key": a.key} for a in self.axes}
        rows = ",\n".join("  " + _strict(r, separators=(",", ":")) for r in self.records.values())
        return (
            f'{{"format": "{FORMAT}", "version": {VERSION},\n "header": {_strict(self.header)},\n '
            f'"axes": {_strict(axes)},\n "results": [\n{rows}\n ]}}\n'
            if rows
            else f'{{"format": "{FORMAT}", "version": {VERSION},\n "header": {_strict(self.header)},\n '
            f'"axes": {_strict(axes)},\n "results": []}}\n'
        )

    def write(self) -> None:
        """Rewrite ``results.json``, then ``results.csv``, each atomically."""
        self.dir.mkdir(parents=True, exist_ok=True)
        atomic_write(self.dir / RESULTS_JSON, self.json_text())
        atomic_write(self.dir / RESULTS_CSV, self.csv_text())
        self.dirty = False

    def csv_text(self) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["task", "seed", *(a.name for a in self.axes), *CSV_METRICS])
        for r in self.records.values():
            metrics = [_csv_cell(r.get(m)) for m in CSV_METRICS]
            w.writerow([r["task"], r["seed"], *(a.lookup(r) for a in self.axes), *metrics])
        return buf.getvalue()


def _strict(obj: object, **kw: object) -> str:
    """Strict JSON of one value (a non-finite number is null), without the trailing newline."""
    return json_text(obj, **kw).rstrip("\n")  # type: ignore[arg-type]


def _read_results(path: Path) -> dict | None:
    """A sweep's ``results.json``, or None when the file is not one (not a regular file, too large,
    not JSON, or without the sweep's format key and not a sweep's from before it)."""
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode) or st.st_size > _RESULTS_LIMIT:
            return None
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(data, dict):
        return None
    if data.get("format") == FORMAT and isinstance(data.get("version"), int):
        return data
    header = data.get("header")
    legacy = "format" not in data and isinstance(header, dict) and {"runs", "trials"} <= set(header)
    return data if legacy and isinstance(data.get("results"), list) else None
