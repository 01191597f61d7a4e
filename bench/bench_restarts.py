"""What the policy search's restarts do to one training: success before and after, and their time.

Run:  python bench/bench_restarts.py [--spec specs/pendulum/p4_alternate.mitl] [--set harmonics=2]
      [--runs 30] [--generations 100] [--seed 0] [--workers 2]

Trains :class:`mitlc.learn.search.SearchRuns` (the settings ``--set`` names, else the search's
defaults) as ``mitlc train --learner search`` does, then prints each run's last generation's best
fitness (a satisfied rollout scores 2 or more), how many runs passed their check
(:meth:`~mitlc.learn.search.SearchRuns.check_scores`), the success from the runs' evaluation starts
(what ``mitlc train`` prints) before :meth:`~mitlc.learn.search.SearchRuns.restart_failed` and after
it, the runs restarted and kept, and the seconds of the training and of the restarts. It asserts
nothing about them.

Measured on this project's 2-core machine (2026-12-07, nothing else running, ``--workers 2``, the
defaults ``--runs 30 --generations 100 --seed 0``, one round of restarts: the default then, ``--set
restarts=1`` now; since record 38 three rounds run, each on the runs the rounds before left failing):

==================================================  ===========  ==========  =========  ========
spec, settings                                      before       after       training   restarts
==================================================  ===========  ==========  =========  ========
P4 ``p4_alternate.mitl``, ``--set harmonics=2``      0.93         1.00        7.6 s      3.1 s
the suite's ``cartpole_catch_and_centre``            0.80         0.93        25.4 s     11.3 s
==================================================  ===========  ==========  =========  ========

P4: runs 16 and 17 ended at a best fitness of 0.55 and 0.45 (no candidate satisfied its starts) against
2.17-2.38; 24 of 30 passed their check; the 6 that failed were restarted and all 6 kept the restart.
The catch (the plain search, its race's winner at seed 0): 6 runs ended at about -0.85 (the pole let
fall at once) against 2.08-2.10; 20 of 30 passed their check; 10 restarted, 6 kept the restart.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.cli.train import _monitor_judge  # noqa: E402
from mitlc.learn.search import SearchRuns, SearchSettings  # noqa: E402
from mitlc.learn.settings import parse_assignments  # noqa: E402
from mitlc.monitor.offline import monitor  # noqa: E402
from mitlc.petri.compile import compile_spec  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402


def success(agent: SearchRuns) -> float:
    """The share of runs whose gains satisfy the spec from their evaluation starts."""
    spec = agent.spec
    ro = agent.rollout(agent.evaluation_states())
    return float(np.mean(monitor(spec, ro.states, ro.dt, spec.monitor_formula).satisfied))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default=str(ROOT / "specs/pendulum/p4_alternate.mitl"))
    ap.add_argument("--set", action="append", default=[], dest="sets", help="a search setting NAME=VALUE")
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--generations", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    spec = load_spec(args.spec)
    settings = SearchSettings(**parse_assignments(SearchSettings, args.sets))
    agent = SearchRuns(compile_spec(spec), args.runs, args.seed, settings, _monitor_judge(spec), workers=args.workers)
    t0 = time.perf_counter()
    agent.train(args.generations)
    trained = time.perf_counter() - t0
    before = success(agent)
    passed = int((agent.check_scores().min(axis=1) >= 2.0).sum())
    last = agent.returns[:, -1].copy()  # the restarts write into returns
    t0 = time.perf_counter()
    agent.restart_failed(args.generations)
    restarting = time.perf_counter() - t0
    print(f"{args.spec} {' '.join(args.sets) or '(defaults)'} seed {args.seed}: {args.runs} runs x {args.generations}")
    print("  last generation's best fitness per run:", " ".join(f"{v:.2f}" for v in last))
    print(f"  passed their check: {passed} of {args.runs}")
    print(f"  success before restarts {before:.2f}, after {success(agent):.2f}")
    print(f"  restarted {agent.restarted}, kept {agent.kept_restarts}")
    print(f"  training {trained:.1f} s, restarts {restarting:.1f} s")


if __name__ == "__main__":
    main()
