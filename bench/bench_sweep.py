"""Throughput of ``mitlc sweep``: tasks per minute with 1 and 2 workers, and their ratio.

Runs the same small sweep (problem 2, ``weight.psi=1,2,5,10`` x 2 seeds = 8
tasks of 30 runs x 100 trials by default) into a fresh directory once per
worker count, through :func:`mitlc.sweep.run_sweep` exactly as the command
does, and prints tasks per minute (wall time of the whole sweep, worker start
included) and the speed-up of 2 workers over 1.  It also checks that every
worker count gave the same metrics.  ``--backend ray`` measures Ray instead
(a local Ray with that many CPUs, started before the clock starts; its start-up
time is printed apart); ``--backend both`` measures both.

    python bench/bench_sweep.py [--runs 30] [--trials 100] [--seeds 2] [--backend local|ray|both] [--repeat 1]

The machine's other load counts: on a shared 2-core machine the 2-worker
figure is only as good as the second core is free, so the script prints how
busy the machine was before it started and how many cores' worth of CPU time
the tasks actually got (their CPU seconds over the wall time).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.spec.parse import load_spec  # noqa: E402
from mitlc.sweep import LocalBackend, RayBackend, plan_sweep, run_sweep  # noqa: E402

SPEC = ROOT / "specs" / "pendulum" / "p2_avoid.mitl"
GRID = ("weight.psi=1,2,5,10",)
METRICS = ("success_rate", "final_return", "greedy_return", "error")


def measure(plan, backend) -> tuple[float, float, dict]:
    """Wall seconds of the whole sweep into a fresh directory, the tasks' CPU seconds, and the metrics."""
    with tempfile.TemporaryDirectory() as d:
        start = time.perf_counter()
        outcome = run_sweep(plan, Path(d) / "out", backend)
        wall = time.perf_counter() - start
    if outcome.failed or outcome.finished != len(plan.tasks):
        raise SystemExit(f"sweep failed: {outcome.failed}")
    cpu = sum(r["cpu_s"] for r in outcome.records.values())
    return wall, cpu, {k: {m: r[m] for m in METRICS} for k, r in outcome.records.items()}


def busy_fraction(seconds: float = 2.0) -> float | None:
    """Fraction of this machine's CPU time in use (by anyone) over ``seconds``, from /proc/stat."""

    def sample():
        with open("/proc/stat") as fh:
            v = [int(x) for x in fh.readline().split()[1:]]
        return sum(v), v[3] + v[4]  # total, idle + iowait

    try:
        t0, i0 = sample()
        time.sleep(seconds)
        t1, i1 = sample()
    except OSError:
        return None
    return 1.0 - (i1 - i0) / max(1, t1 - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--backend", choices=["local", "ray", "both"], default="local")
    ap.add_argument("--repeat", type=int, default=1, help="measure each worker count this many times (alternating)")
    args = ap.parse_args()

    plan = plan_sweep(load_spec(SPEC), GRID, range(args.seeds), args.runs, args.trials)
    n = len(plan.tasks)
    print(f"{n} tasks: problem 2, {' '.join(GRID)} x {args.seeds} seeds, {args.runs} runs x {args.trials} trials")
    busy = busy_fraction()
    if busy is not None:
        print(f"before: {100 * busy:.0f} % of this machine's {os.cpu_count()} cores busy with other work")
    backends = ["local", "ray"] if args.backend == "both" else [args.backend]
    reference = None
    for name in backends:
        rate: dict[int, list[float]] = {1: [], 2: []}
        for _ in range(args.repeat):
            for workers in (1, 2):
                if name == "local":
                    wall, cpu, records = measure(plan, LocalBackend(workers=workers))
                    extra = ""
                else:
                    import ray

                    t0 = time.perf_counter()
                    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, logging_level="WARNING")
                    startup = time.perf_counter() - t0
                    try:
                        wall, cpu, records = measure(plan, RayBackend(workers=workers))
                    finally:
                        ray.shutdown()
                    extra = f" (Ray start-up {startup:.1f} s, not counted)"
                if reference is None:
                    reference = records
                elif records != reference:
                    raise SystemExit(f"{name} with {workers} worker(s) gave other metrics than the first measurement")
                rate[workers].append(n / wall * 60)
                print(
                    f"{name:5s} {workers} worker{'s' if workers > 1 else ' '}: {wall:6.1f} s, "
                    f"{rate[workers][-1]:6.1f} tasks/min; the tasks got {cpu / wall:.2f} cores of CPU time{extra}"
                )
        r1, r2 = statistics.median(rate[1]), statistics.median(rate[2])
        what = "median " if args.repeat > 1 else ""
        print(f"{name:5s} {what}tasks/min: 1 worker {r1:.1f}, 2 workers {r2:.1f}; 2 workers / 1 worker: {r2 / r1:.2f}x")
    print("metrics identical across all measurements: yes")


if __name__ == "__main__":
    main()
