"""Throughput of the HyRL training loop (thesis chapter 3), in run-steps per second.

One run-step is one sample of one run (plant step, automaton step and reward,
features, actor and critic update).  Measures, in one process and on one core
(BLAS threads pinned to 1), on a mass-damper spec:

* the batched learner (:meth:`mitlc.learn.hyrl.HybridLearner.train`) at R runs at once;
* the baseline: the same R runs trained one after the other (R = 1 each), which
  is what a per-run loop costs; the learner draws every run's numbers from that
  run's own generator, so both give the same returns (checked);
* the cost of the spec's ``q`` centres against the other choice (``q_warp`` 0.5 or 1, R runs);

and prints the ratios.

    python bench/bench_hyrl.py [--spec overshoot] [--runs 20] [--trials 10]
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
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _timing import timed  # noqa: E402

from mitlc.learn.hyrl import HybridLearner, HyrlSettings  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="overshoot", help="a spec under specs/mass_damper/, without .mitl")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--trials", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    spec = load_spec(ROOT / "specs" / "mass_damper" / f"{args.spec}.mitl")
    R, T = args.runs, args.trials

    def batched(settings: HyrlSettings | None = None) -> HybridLearner:
        lrn = HybridLearner(spec, settings, runs=R, seed=0)
        lrn.train(T)
        return lrn

    ref = batched()
    steps = R * T * ref.n_steps
    # the runs one at a time: run r of a batch draws from SeedSequence(seed).spawn(R)[r]; a
    # one-run learner seeded with that child's entropy and spawn key draws the same numbers
    children = np.random.SeedSequence(0).spawn(R)

    def one_by_one() -> list[np.ndarray]:
        out = []
        for c in children:
            lrn = HybridLearner(spec, runs=1, seed=0)
            pair = c.spawn(2)
            lrn.rngs = [np.random.Generator(np.random.PCG64(pair[0]))]
            lrn.train(T)
            out.append(lrn.returns[0])
        return out

    same = np.allclose(np.array(one_by_one()), ref.returns, rtol=0, atol=1e-9)
    t_batch = timed(batched, args.repeat)
    t_loop = timed(one_by_one, args.repeat)
    other = 1.0 if ref.q_warp != 1.0 else 0.5  # the spec's q centres against the other choice
    t_other = timed(lambda: batched(HyrlSettings(q_warp=other)), args.repeat)
    print(
        f"HyRL on {args.spec}: {R} runs x {T} trials x {ref.n_steps} samples, {ref.n_features} features, "
        f"{ref.n_modes} modes, q_warp {ref.q_warp:g}"
    )
    print(f"  batched (R = {R}):          {t_batch:7.3f} s  {steps / t_batch:10.0f} run-steps/s")
    print(
        f"  one run at a time (R = 1): {t_loop:7.3f} s  {steps / t_loop:10.0f} run-steps/s  "
        f"(same returns: {'yes' if same else 'NO'})"
    )
    print(f"  q_warp {other:g} instead:         {t_other:7.3f} s  {steps / t_other:10.0f} run-steps/s")
    print(f"ratio batched / one at a time: {t_loop / t_batch:.1f}x faster")
    print(f"ratio q_warp {ref.q_warp:g} / q_warp {other:g}: {t_batch / t_other:.2f}x the time")
    if not same:
        raise SystemExit("the batched learner's returns differ from the runs trained one at a time")


if __name__ == "__main__":
    main()
