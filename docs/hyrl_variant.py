"""One HyRL variant on a mass-damper spec: train, judge the greedy policies, print one JSON line.

The tables of docs/hyrl.md ("Why whole sides crept ...") were made with it, e.g.

    python docs/hyrl_variant.py overshoot --trials 800 --seed 2                       # the defaults
    python docs/hyrl_variant.py overshoot --trials 800 --seed 2 --set q_warp=1 --set alpha_a=0.08
    python docs/hyrl_variant.py rise_time --trials 2000 --seed 1 --set q_warp=0.5

(about 35 s per overshoot line and 190 s per rise-time line with 20 runs, one core).
``--set name=value`` overrides a :class:`mitlc.learn.hyrl.HyrlSettings` field (read by the
field's type, as ``mitlc train --set``).  Printed: ``success`` (runs whose greedy policy succeeds from
every initial state with ``|q0| >= 0.1``, of 50 evenly spaced), ``states`` (successful
(run, state) pairs among those), ``states_all`` (all 50), ``overshoot`` and
``unstable`` (pairs with ``|q0| >= 0.1`` that fail the criteria / meet them but do not
come to rest within 10% of the step), ``per_run`` and the learning curve in eighths.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.errors import MitlError  # noqa: E402
from mitlc.learn.hyrl import HybridLearner, HyrlSettings, evaluate  # noqa: E402
from mitlc.learn.settings import parse_assignments  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("spec", help="a spec under specs/mass_damper/, without .mitl")
    ap.add_argument("--trials", type=int, default=800)
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="NAME=VALUE")
    args = ap.parse_args(argv)
    try:
        kw = parse_assignments(HyrlSettings, args.sets)
        settings = HyrlSettings(**kw)
        spec = load_spec(ROOT / "specs" / "mass_damper" / f"{args.spec}.mitl")
        learner = HybridLearner(spec, settings, runs=args.runs, seed=args.seed)
        start = time.perf_counter()
        returns = learner.train(args.trials)
    except MitlError as exc:
        print(f"hyrl_variant.py: {exc}", file=sys.stderr)
        return 2
    ev = evaluate(learner)
    big = np.abs(ev.q0) >= 0.1
    ok = ev.ok()
    eighth = max(1, args.trials // 8)
    print(
        json.dumps(
            dict(
                spec=args.spec,
                seed=args.seed,
                runs=args.runs,
                trials=args.trials,
                set={k: list(v) if isinstance(v, tuple) else v for k, v in kw.items()},
                q_warp=learner.q_warp,
                success=round(ev.success_rate(big), 2),
                states=round(ev.state_rate(big), 3),
                states_all=round(ev.state_rate(), 3),
                overshoot=round(float((~ev.passed[:, big]).mean()), 3),
                unstable=round(float((ev.passed & ~ev.stabilised)[:, big].mean()), 3),
                per_run=[int(n) for n in ok[:, big].sum(axis=1)],
                wall_s=round(time.perf_counter() - start, 1),
                curve=[round(float(returns[:, i : i + eighth].mean()), 1) for i in range(0, args.trials, eighth)],
            )
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
