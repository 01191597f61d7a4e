"""``mitlc check`` on long CSV traces: pyarrow's reader and the chunked numpy one against the old row-by-row one.

Run:  python bench/bench_check.py [--repeat 3] [--big]

Writes pendulum traces (columns t, q, qdot at dt = 0.05 s, every number as ``repr`` writes it,
17 significant digits or so, as ``mitlc simulate --trace`` does) to a temporary directory and prints:
the median time of :func:`mitlc.monitor.trace.read_trace`'s CSV readers (pyarrow's, where pyarrow
is installed, and numpy's) and of the old reader (:func:`old_read_csv`, the code before issue #17
part 3, kept here as the baseline) on 100k and 1M rows; the median wall time of a whole ``mitlc
check`` process on 100k rows with each reader (``MITLC_CSV_READER=numpy`` for numpy's) and of a
bare ``python -c "import numpy"`` (the floor every start-up pays); with ``--big``, the wall time
and peak RSS of a whole ``mitlc check`` on the longest trace mitlc reads (``MAX_STEPS + 1`` =
1,000,001 rows, about 55 MiB of text) and of its refusal one row past the limit, with each reader.
It prints timings; it asserts nothing about them.
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


def run_check(trace: Path, reader: str, *options: str) -> tuple[float, float]:
    """Wall seconds and peak RSS (MiB) of one whole ``mitlc check`` process with ``reader``'s CSV reader."""
    code = (  # VmHWM, the peak RSS of this process's own memory: ru_maxrss would keep the bench's across exec
        "import resource, sys\nfrom mitlc.cli.main import main\n"
        "try:\n    main(sys.argv[1:])\nexcept SystemExit as e:\n    code = e.code\n"
        "try:\n    hwm = next(int(s.split()[1]) for s in open('/proc/self/status') if s.startswith('VmHWM:'))\n"
        "except OSError:\n    hwm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "sys.stderr.write(f'{hwm}\\n')\nsys.exit(code)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT), READER_ENV: reader}
    t0 = time.perf_counter()
    r = subprocess.run(
        [sys.executable, "-c", code, "check", *options, SPEC, str(trace)],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.perf_counter() - t0
    if r.returncode not in (0, 1) and "samples (rows), the most supported" not in r.stderr:
        raise SystemExit(f"mitlc check failed: {r.stdout}{r.stderr}")
    return wall, int(r.stderr.strip().splitlines()[-1]) / 1024  # VmHWM and ru_maxrss are in KiB on Linux


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--big", action="store_true", help="also a whole mitlc check on the longest trace (1,000,001 rows)")
    args = ap.parse_args()
    readers = ["pyarrow", "numpy"] if _pyarrow() is not None else ["numpy"]
    if len(readers) == 1:
        print("(pyarrow is not installed: the numpy reader only)")
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
