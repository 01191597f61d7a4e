"""Where a generation of the policy search (``mitlc train --learner search``) spends its time.

A generation of :class:`mitlc.learn.search.SearchRuns` with R runs is: every run's CMA-ES asks for
``popsize`` candidates, ``R * popsize * starts`` rows are rolled out on the plant in numpy
(``SearchRuns._roll``), the monitor judges every rollout (``judge``: satisfaction, robustness, the
time of the first violation, no failing part named: ``monitor(..., blame=False)``, as ``mitlc train``
judges its designs but the last, which adds the averaged robustness), and every
run's CMA-ES is told the fitness. This bench times the
three parts separately on one spec, in one process and on one core (BLAS threads pinned to 1),
each the median of ``--repeat`` calls on the same candidates and starts, and prints each part's
share of their sum, the seconds per generation and what ``--generations`` of them cost (the
default trial count of ``mitlc train --learner search``; a race of designs before it adds more),
then the baseline: the same judging with blame (each violated run's failing part named, as the
search judged before), and the ratios.
The issue's target for a suite task's training is 60 s on 2 cores: the shares say which part must
give way first.

With ``--workers N`` it measures instead what training the runs in ``N`` forked processes gains
(``mitlc train --workers``, :meth:`mitlc.learn.search.SearchRuns.train`): ``--train-generations`` generations
of the runs in one process and in ``N``, alternately, ``--repeat`` times each; it prints the median wall
times, their ratio, the processes' CPU seconds (what splitting the runs costs in per-call overhead) and
checks that both give the same gains and fitness to the bit. Measured on this 2-core machine, the
other core idle, 10 generations of ``cartpole_sway.mitl``, median of 3: 30 runs 12.78 s in one
process, 6.17 s in two (2.07x; CPU 0.95x); 8 runs (the race's) 3.61 s and 2.27 s (1.59x; CPU 1.18x).

    python bench/bench_search.py [--spec bench/suite/specs/cartpole_slow_move.mitl] [--runs 30] [--workers 2]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from _timing import timed  # noqa: E402  (bench/ is on sys.path when a bench runs)

from mitlc.learn.search import SearchRuns, SearchSettings, default_generations  # noqa: E402
from mitlc.monitor.offline import monitor  # noqa: E402
from mitlc.petri.compile import CompileOptions, compile_spec  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402


def parts(spec_path: Path, runs: int, repeat: int, seed: int = 0) -> tuple[dict[str, float], float]:
    """Median seconds of one generation's ask and tell, rollout and judging on ``spec_path`` (as
    ``mitlc train``'s search judges: no blame), and of the judging with blame (the baseline)."""
    import cma

    spec = load_spec(spec_path)
    rs = compile_spec(spec, CompileOptions())
    agent = SearchRuns(rs, runs, seed, SearchSettings())
    st = agent.settings
    P, S, R, f, m = st.popsize, st.starts, runs, agent.n_features, agent.n_inputs
    rng = np.random.default_rng(seed)
    searches = [
        cma.CMAEvolutionStrategy(np.zeros(f * m), st.sigma0, {"seed": r + 1, "popsize": P, "verbose": -9})
        for r in range(R)
    ]
    cand = np.array([s.ask() for s in searches])
    starts = np.repeat(np.stack([agent._draw(rng, S) for _ in range(R)]), P, axis=0).reshape(R * P * S, -1)
    W = np.repeat(cand.reshape(R * P, f, m), S, axis=0)
    states, _ = agent._roll(W, starts)
    fit = rng.standard_normal((R, P))

    def ask_tell() -> None:
        for r, s in enumerate(searches):
            c = s.ask()
            s.tell(c, list(fit[r]))

    return {
        "ask and tell (CMA-ES, per run)": timed(ask_tell, repeat),
        f"rollout ({R * P * S} rows x {agent.n_steps} steps, numpy)": timed(lambda: agent._roll(W, starts), repeat),
        "judge (the monitor on every rollout, no blame)": timed(
            lambda: monitor(spec, states, agent.dt, spec.monitor_formula, blame=False), repeat
        ),
    }, timed(lambda: monitor(spec, states, agent.dt, spec.monitor_formula), repeat)


def forked(spec_path: Path, runs: int, workers: int, generations: int, repeat: int) -> dict[int, tuple[float, float]]:
    """Median wall and CPU seconds of ``generations`` generations of ``runs`` runs in 1 and ``workers``
    processes, alternately; raises if the two do not give the same numbers."""
    import statistics
    import time

    import cma  # noqa: F401  (imported once, outside the timings)

    from mitlc.cli.train import _monitor_judge

    spec = load_spec(spec_path)
    rs = compile_spec(spec, CompileOptions())
    times: dict[int, list[tuple[float, float]]] = {1: [], workers: []}
    kept: dict[int, SearchRuns] = {}
    for _ in range(repeat):
        for w in (1, workers):
            agent = SearchRuns(rs, runs, 0, SearchSettings(), _monitor_judge(spec), workers=w)
            t0, c0 = time.perf_counter(), os.times()
            agent.train(generations)
            t1, c1 = time.perf_counter(), os.times()
            cpu = sum(c1[:4]) - sum(c0[:4])  # this process and its children, user and system
            times[w].append((t1 - t0, cpu))
            kept[w] = agent
    a, b = kept[1], kept[workers]
    if not (np.array_equal(a.weights, b.weights) and np.array_equal(a.returns, b.returns)):
        raise SystemExit("the runs trained in several processes are not the runs trained in one")
    return {w: (statistics.median(t for t, _ in v), statistics.median(c for _, c in v)) for w, v in times.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", type=Path, default=ROOT / "bench" / "suite" / "specs" / "cartpole_slow_move.mitl")
    ap.add_argument("--runs", type=int, default=30, help="runs (default 30, mitlc train's)")
    ap.add_argument("--repeat", type=int, default=3, help="calls per part; the median is kept (default 3)")
    ap.add_argument("--generations", type=int, default=default_generations(0), help="generations to cost")
    ap.add_argument("--workers", type=int, default=0, help="compare training in this many processes with one")
    ap.add_argument("--train-generations", type=int, default=10, help="generations per timed training (--workers)")
    a = ap.parse_args(argv)
    if a.workers > 1:
        got = forked(a.spec, a.runs, a.workers, a.train_generations, a.repeat)
        (t1, c1), (tn, cn) = got[1], got[a.workers]
        print(
            f"policy search, {a.train_generations} generations of {a.runs} runs on {a.spec.name} "
            f"(median of {a.repeat}):"
        )
        print(f"  1 process        : {t1:8.2f} s wall, {c1:8.2f} s CPU")
        print(f"  {a.workers} processes      : {tn:8.2f} s wall, {cn:8.2f} s CPU")
        print(f"  speed-up {t1 / tn:.2f}x; CPU {cn / c1:.2f}x; the same gains and fitness to the bit")
        return 0
    found, blamed = parts(a.spec, a.runs, a.repeat)
    total = sum(found.values())
    judged = list(found.values())[-1]
    print(f"policy search, one generation of {a.runs} runs on {a.spec.name}:")
    for name, sec in found.items():
        print(f"  {name:<48} {sec:8.3f} s  {sec / total:6.1%}")
    print(f"  {'sum':<48} {total:8.3f} s")
    print(
        f"judging with blame (the failing part named per violated run, as before): {blamed:.3f} s, "
        f"{blamed / judged:.2f}x the judging without; a generation {(total - judged + blamed) / total:.2f}x"
    )
    print(f"{a.generations} generations: {a.generations * total:.1f} s (the issue's target for a whole training: 60 s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
