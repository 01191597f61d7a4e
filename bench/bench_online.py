"""Online monitoring: the verdict of every prefix, per sample, against re-reading the prefix.

Run:  python bench/bench_online.py [--seed 0] [--samples 2000] [--dt 0.05]

For the shipped pendulum specs' formulas (and two nested ones) it feeds one random-walk
trace sample by sample to :class:`mitlc.monitor.online.OnlineMonitor` and prints the mean
microseconds per sample over the first 100 samples and over the last 100 of
``--samples``, against the old way (the Gymnasium wrapper's before #17): the offline
monitor over the whole prefix ``x_0 .. x_k`` after every sample, timed in the same
process on the same trace at the same prefix lengths. A flat online column means
constant time per sample; the offline column grows with ``k``. Every prefix's verdict is
checked equal between the two (a sanity check, not a timing assertion). It prints timings;
it asserts nothing about them.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mitlc.monitor.offline import monitor
from mitlc.monitor.online import OnlineMonitor
from mitlc.spec.parse import parse_formula, parse_spec

SPEC = parse_spec(
    "plant pendulum\nprop kappa = abs(q) < 0.3\nprop psi = abs(q - 1.5) < 0.2\n"
    "prop upsilon = abs(q) > 2.8\nprop fast = abs(qdot) > 4\nformula F G kappa\n"
)
FORMULAS = (
    "F G kappa",  # P1
    "F G kappa & 10 * G !psi",  # P2
    "5 * G F kappa & 5 * G F upsilon & 25 * G !psi",  # P4
    "F[0,1.5] G kappa & 5 * G !fast",  # N2
    "G (fast -> F[0,0.5] !fast) & F G kappa",
    "G[0,1] F[1,2] kappa",  # bounded: final after 3 s
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--dt", type=float, default=0.05)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    n, dt = args.samples, args.dt
    q = np.cumsum(rng.normal(0, 0.15, n)) + 1.0
    qdot = rng.normal(0, 3, n)
    x = np.stack([q, qdot], axis=1)
    early, late = range(0, 100), range(n - 100, n)
    print(f"one trace of {n} samples at dt = {dt} s; microseconds per sample (mean of 100 samples)")
    print(f"{'formula':<48} {'online k<100':>13} {'online last':>12} {'offline k<100':>14} {'offline last':>13}")
    for text in FORMULAS:
        f = parse_formula(text)
        mon = OnlineMonitor(SPEC, dt, f)
        per = np.empty(n)
        verdicts = np.empty(n, dtype=bool)
        for k in range(n):
            t0 = time.perf_counter()
            v = mon.update(x[k])
            per[k] = time.perf_counter() - t0
            verdicts[k] = v.satisfied[0]
        off = {}
        for k in list(early) + list(late):
            t0 = time.perf_counter()
            res = monitor(SPEC, x[None, : k + 1], dt, f)
            off[k] = time.perf_counter() - t0
            if bool(res.satisfied[0]) != verdicts[k]:
                raise SystemExit(f"{text}: the online and offline verdicts differ at sample {k}")
        on_e, on_l = per[list(early)].mean() * 1e6, per[list(late)].mean() * 1e6
        off_e = np.mean([off[k] for k in early]) * 1e6
        off_l = np.mean([off[k] for k in late]) * 1e6
        mark = "" if mon.constant_time else "  (not constant time)"
        print(f"{text:<48} {on_e:>13.1f} {on_l:>12.1f} {off_e:>14.1f} {off_l:>13.1f}{mark}")
        print(f"{'':<48} {'':>13} {'':>12} {'offline/online, last:':>28} {off_l / on_l:.0f}x")


if __name__ == "__main__":
    main()
