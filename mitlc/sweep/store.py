"""Results on disk: Results go to a directory through :class:`ResultStore`: ``results.json`` (the
authoritative record) and ``results.csv``, both rewritten atomically after
every finished task, keyed by the task's configuration and seed so a re-run
skips what is done and never counts a task twice.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mitlc.errors import InputError
from mitlc.fileio import atomic_write, json_text
from mitlc.sweep.grid import Axis

RESULTS_JSON = "results.json"
RESULTS_CSV = "results.csv"
LOCK_FILE = ".sweep.lock"


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
        self._lock_fh: Any = None
        self._load()

    # the directory lock
    def __enter__(self) -> ResultStore:
        self.dir.mkdir(parents=True, exist_ok=True)
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX: no lock
            return self
        fh = open(self.dir / LOCK_FILE, "a")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            raise InputError(f"another sweep is writing to {self.dir}", file="--out") from None
        self._lock_fh = fh
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._lock_fh is not None:
            self._lock_fh.close()
            self._lock_fh = None

    def _load(self) -> None:
        path = self.dir / RESULTS_JSON
        if not path.is_file():
            return
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            header, records = data["header"], data["results"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise InputError(f"cannot read earlier results: {exc}", file=str(path)) from None
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
        if not isinstance(header, dict) or not isinstance(records, list):
            raise InputError(
                "cannot read earlier results: 'header' is not an object or 'results' not a list", file=str(path)
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
            f'{{"header": {_strict(self.header)},\n "axes": {_strict(axes)},\n "results": [\n{rows}\n ]}}\n'
            if rows
            else f'{{"header": {_strict(self.header)},\n "axes": {_strict(axes)},\n "results": []}}\n'
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
