"""What racing the designs in several processes gains: ``mitlc train``'s race in one process and in N.

Run:  python bench/bench_race.py [--spec bench/suite/specs/unicycle_two_waypoints.mitl] [--workers 2]
                                 [--trials 500] [--repeat 1]

Races the designs of :mod:`mitlc.sweep.race` on one spec exactly as ``mitlc train --spec SPEC`` does
(its race runs, trials and search generations; the search designs first, then SACPN's), with
``workers=1`` and ``workers=N`` alternately, ``--repeat`` times each, and prints the median wall
time of each, their ratio, the designs raced and the winner, and checks that both races give the
same entries, winner and (where a search won) the same gains to the bit. A race whose first design
satisfies every race run ends there in both (nothing to spread); the default spec races all nine
designs (none sweeps it). SACPN's compiled kernel is compiled (or read from the disk cache) once
before the timings, so neither side pays for it.

Measured 2026-12-07 on this 2-core machine, nothing else running, the default spec (the race of all
nine designs, 8 runs each, 100 generations or 250 trials; the quadratic search scored by the averaged
robustness won): 46.84 s in one process, 26.04 s in two (**1.80x**), the same race. Before the forked
processes held one BLAS thread each (``mitlc.learn.search.forked_child``: CMA-ES's eigendecompositions
run in OpenBLAS, which starts a thread per core in every process) the same bench printed 43.64 s and
43.14 s (1.01x), and 42.29 s and 23.97 s (1.76x) with ``OPENBLAS_NUM_THREADS=1`` set by hand.
docs/training.md quotes these figures.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.cli.train import TRIALS, _monitor_judge  # noqa: E402
from mitlc.learn.sacpn import SacpnSettings  # noqa: E402
from mitlc.learn.search import SearchRuns, SearchSettings  # noqa: E402
from mitlc.petri.compile import CompileOptions, compile_spec  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402
from mitlc.sweep.race import greedy_verdicts, race, search_generations  # noqa: E402
from mitlc.sweep.task import sacpn_learner  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", type=Path, default=ROOT / "bench" / "suite" / "specs" / "unicycle_two_waypoints.mitl")
    ap.add_argument("--workers", type=int, default=2, help="processes to race in (default 2)")
    ap.add_argument("--runs", type=int, default=30, help="the training's runs (default 30: 8 race runs)")
    ap.add_argument("--trials", type=int, default=TRIALS, help=f"the training's trials (default {TRIALS})")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=1, help="races per side; the median is kept (default 1)")
    a = ap.parse_args(argv)
    spec = load_spec(a.spec)
    rs = compile_spec(spec, CompileOptions.from_spec(spec))
    settings = SacpnSettings()

    def build(st: SacpnSettings, r: int, s: int):
        return sacpn_learner(rs, st, r, s)

    def search(r: int, changes: dict):
        return SearchRuns(rs, r, a.seed, SearchSettings(**changes), _monitor_judge(spec), workers=w)

    build(settings, 1, 0).train(1)  # SACPN's kernel compiled (or read from the cache) before the timings
    times: dict[int, list[float]] = {1: [], a.workers: []}
    got = {}
    for _ in range(a.repeat):
        for w in (1, a.workers):
            t0 = time.perf_counter()
            got[w] = race(
                build,
                greedy_verdicts,
                settings,
                a.runs,
                a.trials,
                a.seed,
                search=search,
                generations=search_generations(a.trials),
                workers=w,
            )
            times[w].append(time.perf_counter() - t0)
    one, many = got[1], got[a.workers]
    assert one is not None and many is not None
    if one.record() != many.record():
        raise SystemExit("the race in several processes is not the race in one")
    if one.searched is not None and not np.array_equal(one.searched.weights, many.searched.weights):
        raise SystemExit("the winning search's gains differ between the races")
    t1, tn = statistics.median(times[1]), statistics.median(times[a.workers])
    print(f"race on {a.spec.name}, {len(one.entries)} designs raced, {one.winner} won (median of {a.repeat}):")
    print(f"  1 process   : {t1:8.2f} s")
    print(f"  {a.workers} processes : {tn:8.2f} s")
    print(f"  speed-up {t1 / tn:.2f}x; the same entries, winner and gains")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
