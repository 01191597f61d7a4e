"""``mitlc check`` on long CSV traces: pyarrow's reader and the chunked numpy one against the old row-by-row one.

Run:  python bench/bench_check.py [--repeat 3] [--big | --startup]

Writes pendulum traces (columns t, q, qdot at dt = 0.05 s, every number as ``repr`` writes it,
17 significant digits or so, as ``mitlc simulate --trace`` does) to a temporary directory and prints:
the median time of :func:`mitlc.monitor.trace.read_trace`'s CSV readers (pyarrow's, where pyarrow
is installed, and numpy's) and of the old reader (:func:`old_read_csv`, the code before issue #17
part 3, kept here as the baseline) on 100k and 1M rows; the median wall time of a whole ``mitlc
check`` process on 100k rows with each reader (``MITLC_CSV_READER=numpy`` for numpy's) and of a
bare ``python -c "import numpy"`` (the floor every start-up pays); with ``--big``, the wall time
and peak RSS of a whole ``mitlc check`` on the longest trace mitlc reads (``MAX_STEPS + 1`` =
1,000,001 rows, about 55 MiB of text) and of its refusal one row past the limit, with each reader.
With ``--startup`` only whole processes, each the fastest of ``--repeat`` (at least 5, interleaved):
``mitlc check`` on 61 and 100k rows against ``python -c "import numpy"``, ``check --net`` of
``pendulum/p3_avoid_speed_limit`` (tables too small to keep) on 100k rows, and of
``pendulum/n1_reach_in_time`` (576 markings) on 61 rows with its tables built in every process
(``MITLC_CACHE_DIR=``, what ``--net`` did before it kept them) and read from the disk cache
(:mod:`mitlc.runtime.tablefile`); then n1's ``NetRuntime`` in this process, both ways.
It prints timings; it asserts nothing about them.

Measured with ``--startup --repeat 7`` on a quiet 2-core machine (2026-12-07, Python 3.11, mitlc's
``.pyc`` written by ``python -m compileall mitlc``: without them, as under ``PYTHONDONTWRITEBYTECODE=1``,
every process compiles mitlc's modules again, some 0.07 s more), seconds and times the floor:

======================================  =======  ========
process                                 seconds  x floor
======================================  =======  ========
``python -c "import numpy"``              0.100     1.00
``check``, 61 rows                        0.211     2.11
``check``, 100k rows, pyarrow             0.277     2.77
``check``, 100k rows, numpy reader        0.291     2.92
``check --net`` p3, 100k rows             0.310     3.11
``check --net`` n1, tables built          0.357     3.57
``check --net`` n1, tables kept           0.245     2.45
``check`` n1, 61 rows                     0.206     2.07
======================================  =======  ========

Since 2026-12-08 ``--startup`` also prints the import of check's own libraries, nothing of mitlc's
(``python -c 'import numpy, click'``, ``+ lark``, ``+ pyarrow.csv``): on a quiet machine, fastest of 7,
1.09, 1.35 and 1.76 times the floor (0.089 s), with ``check`` 2.09 on 61 rows and 2.86 on 100k rows
(pyarrow's): the libraries alone take 100k rows past 1.5 times the floor.

n1's ``NetRuntime``: tables built 39.8 ms (96.8 ms before the reward was tabulated from the distinct rows
of the places it reads), read from disk 4.3 ms. pyarrow is imported for a CSV of
2 MB or more only (:data:`mitlc.monitor.trace.ARROW_MIN_BYTES`), so a short check no longer pays its
import. What a short check spends past numpy's import (``python -X importtime``): lark's import and
the parse of a spec, click, mitlc's own modules (``mitlc.spec.ast``'s and ``mitlc.spec.predicates``'
frozen dataclasses about 25 ms together).
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from _timing import timed  # bench/ is on sys.path when a bench runs

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.errors import InputError
from mitlc.limits import MAX_STEPS
from mitlc.monitor.trace import READER_ENV, Trace, _pyarrow, _read_csv_arrow, _read_csv_numpy

SPEC = str(ROOT / "specs" / "pendulum" / "p3_avoid_speed_limit.mitl")
NEEDED = ("q", "qdot")
DT = 0.05


def old_read_csv(path: str, needed: tuple[str, ...]) -> Trace:
    """The CSV reader before issue #17 part 3 (pure Python: csv, one float per cell, a list of lines).
    tests/test_light_cli.py checks the new reader against it."""
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
    return Trace(path, t, data, lines)  # type: ignore[arg-type]  # a list indexes as SourceLines does


def write_csv(path: Path, n: int) -> None:
    """A swinging pendulum's trace of ``n`` samples, written 1M rows at a time."""
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("t,q,qdot\n")
        for k0 in range(0, n, 1_000_000):
            t = np.arange(k0, min(n, k0 + 1_000_000)) * DT
            q, qdot = 0.2 * np.sin(t), 0.2 * np.cos(t)
            fh.write(
                "".join(f"{a!r},{b!r},{c!r}\n" for a, b, c in zip(t.tolist(), q.tolist(), qdot.tolist(), strict=True))
            )


def run_check(
    trace: Path, reader: str, *options: str, spec: str = SPEC, env_extra: dict[str, str] | None = None
) -> tuple[float, float]:
    """Wall seconds and peak RSS (MiB) of one whole ``mitlc check`` process with ``reader``'s CSV reader."""
    code = (  # VmHWM, the peak RSS of this process's own memory: ru_maxrss would keep the bench's across exec
        "import resource, sys\nfrom mitlc.cli.main import main\n"
        "try:\n    main(sys.argv[1:])\nexcept SystemExit as e:\n    code = e.code\n"
        "try:\n    hwm = next(int(s.split()[1]) for s in open('/proc/self/status') if s.startswith('VmHWM:'))\n"
        "except OSError:\n    hwm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "sys.stderr.write(f'{hwm}\\n')\nsys.exit(code)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT), READER_ENV: reader, **(env_extra or {})}
    t0 = time.perf_counter()
    r = subprocess.run(
        [sys.executable, "-c", code, "check", *options, spec, str(trace)],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.perf_counter() - t0
    if r.returncode not in (0, 1) and "samples (rows), the most supported" not in r.stderr:
        raise SystemExit(f"mitlc check failed: {r.stdout}{r.stderr}")
    return wall, int(r.stderr.strip().splitlines()[-1]) / 1024  # VmHWM and ru_maxrss are in KiB on Linux


def fastest(fn: Callable[[], float], repeat: int) -> float:
    """The least of ``repeat`` calls of ``fn`` (seconds): on a shared machine, the start-up's own cost."""
    return min(fn() for _ in range(repeat))


def startup(tmp: Path, repeat: int, readers: list[str]) -> None:
    """Whole processes, each the fastest of ``repeat`` (interleaved): ``mitlc check`` against the
    start-up floor ``python -c 'import numpy'``, and ``check --net`` with its net's tables kept on disk
    against them built in every call (``MITLC_CACHE_DIR=``, as before the tables were kept)."""
    big, small = tmp / "trace_100000.csv", tmp / "trace_61.csv"
    write_csv(big, 100_000)
    write_csv(small, 61)
    cache = tmp / "cache"
    kept, built = {"MITLC_CACHE_DIR": str(cache)}, {"MITLC_CACHE_DIR": ""}
    n1 = str(ROOT / "specs" / "pendulum" / "n1_reach_in_time.mitl")
    run_check(small, readers[0], "--net", spec=n1, env_extra=kept)  # the tables written once
    runs: dict[str, Callable[[], float]] = {
        "python -c 'import numpy'": lambda: timed(
            lambda: subprocess.run([sys.executable, "-c", "import numpy"], check=True), 1
        ),
        "check, 61 rows": lambda: run_check(small, readers[0])[0],
    }
    # what check's own libraries cost to import, nothing of mitlc's: the least a check built on them can take
    libraries = ["numpy, click", "numpy, click, lark"] + (
        ["numpy, click, lark, pyarrow.csv"] if "pyarrow" in readers else []
    )
    for mods in libraries:
        runs[f"python -c 'import {mods}'"] = lambda m=mods: timed(
            lambda: subprocess.run([sys.executable, "-c", f"import {m}"], check=True), 1
        )
    for reader in readers:
        runs[f"check, 100k rows, {reader}"] = lambda r=reader: run_check(big, r)[0]
    runs["check --net p3, 100k rows"] = lambda: run_check(big, readers[0], "--net", env_extra=kept)[0]
    runs["check --net n1, 61 rows, tables built"] = lambda: run_check(
        small, readers[0], "--net", spec=n1, env_extra=built
    )[0]
    runs["check --net n1, 61 rows, tables kept"] = lambda: run_check(
        small, readers[0], "--net", spec=n1, env_extra=kept
    )[0]
    runs["check n1, 61 rows"] = lambda: run_check(small, readers[0], spec=n1)[0]
    times: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(repeat):  # interleaved: a load that comes and goes hits every run alike
        for name, fn in runs.items():
            times[name].append(fn())
    floor = min(times["python -c 'import numpy'"])
    print(f"whole processes, the fastest of {repeat}:")
    for name, ts in times.items():
        print(f"  {name:<52} {min(ts):.3f} s  {min(ts) / floor:5.2f} x the floor")
    print()
    sys.path.insert(0, str(ROOT))
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.runtime import NetRuntime
    from mitlc.spec.parse import load_spec

    rs = compile_spec(load_spec(n1), CompileOptions(violations="permanent"))
    os.environ["MITLC_CACHE_DIR"] = str(cache)
    # a net compiled afresh each time: a process keeps the last net's tables (NetRuntime), which is not a build
    fresh = [compile_spec(load_spec(n1), CompileOptions(violations="permanent")) for _ in range(repeat)]
    t_built = min(timed(lambda rs=rs: NetRuntime(rs, dt=DT, steps=60), 1) for rs in fresh)
    t_kept = fastest(lambda: timed(lambda: NetRuntime(rs, dt=DT, steps=60, tables_cache=True), 1), repeat)
    print(f"n1's NetRuntime (576 markings): tables built {t_built * 1e3:.1f} ms, read from disk {t_kept * 1e3:.1f} ms")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--big", action="store_true", help="also a whole mitlc check on the longest trace (1,000,001 rows)")
    ap.add_argument("--startup", action="store_true", help="only whole processes: check's start-up and check --net's")
    args = ap.parse_args()
    readers = ["pyarrow", "numpy"] if _pyarrow() is not None else ["numpy"]
    if len(readers) == 1:
        print("(pyarrow is not installed: the numpy reader only)")
    if args.startup:
        with tempfile.TemporaryDirectory() as tmp:
            startup(Path(tmp), max(args.repeat, 5), readers)
        return
    with tempfile.TemporaryDirectory() as tmp:
        print("CSV reading (t, q, qdot as repr writes them), median seconds:")
        print(f"{'rows':>10} {'old':>9} {'numpy':>9} {'pyarrow':>9} {'old/numpy':>10} {'numpy/pyarrow':>14}")
        for n in (100_000, 1_000_000):
            path = Path(tmp) / f"trace_{n}.csv"
            write_csv(path, n)
            fast = timed(lambda p=str(path): _read_csv_arrow(p, NEEDED), args.repeat) if len(readers) > 1 else math.nan
            new = timed(lambda p=str(path): _read_csv_numpy(p, NEEDED), args.repeat)
            old = timed(lambda p=str(path): old_read_csv(p, NEEDED), args.repeat)
            print(f"{n:>10} {old:>9.3f} {new:>9.3f} {fast:>9.3f} {old / new:>10.1f} {new / fast:>14.1f}")
        small = Path(tmp) / "trace_100000.csv"
        print()
        bare = statistics.median(
            timed(lambda: subprocess.run([sys.executable, "-c", "import numpy"], check=True), 1) for _ in range(3)
        )
        print(f"python -c 'import numpy':              {bare:.3f} s (the start-up floor)")
        for reader in readers:
            walls = [run_check(small, reader)[0] for _ in range(max(3, args.repeat))]
            wall = statistics.median(walls)
            print(
                f"whole mitlc check, 100k rows, {reader:>7}: {wall:.3f} s (median of {len(walls)}), "
                f"{wall / bare:.2f} x the floor"
            )
        walls = [run_check(small, readers[0], "--net")[0] for _ in range(max(3, args.repeat))]
        print(f"whole mitlc check --net, 100k rows:     {statistics.median(walls):.3f} s (median of {len(walls)})")
        for p in Path(tmp).glob("*.csv"):
            p.unlink()
        if args.big:
            for n in (MAX_STEPS + 1, MAX_STEPS + 2):  # the longest trace read, and one row past the limit
                big = Path(tmp) / f"trace_{n}.csv"
                write_csv(big, n)
                size = big.stat().st_size / 2**20
                print()
                for reader in readers:
                    wall, rss = run_check(big, reader)
                    print(
                        f"whole mitlc check, {n:,} rows ({size:.0f} MiB), {reader:>7}: {wall:.1f} s, "
                        f"peak RSS {rss:.0f} MiB"
                    )
                big.unlink()
    print(f"(bench process peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB)")


if __name__ == "__main__":
    main()
