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

    python bench/bench_search.py [--spec bench/suite/specs/cartpole_slow_move.mitl] [--runs 30]
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", type=Path, default=ROOT / "bench" / "suite" / "specs" / "cartpole_slow_move.mitl")
    ap.add_argument("--runs", type=int, default=30, help="runs (default 30, mitlc train's)")
    ap.add_argument("--repeat", type=int, default=3, help="calls per part; the median is kept (default 3)")
    ap.add_argument("--generations", type=int, default=default_generations(0), help="generations to cost")
    a = ap.parse_args(argv)
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
