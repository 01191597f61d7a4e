"""What a new spec's first training spends compiling its kernel, alone and after another spec's.

Run:  python bench/bench_kernel_compile.py [--repeat 3] [--kernel numba|simd]

:mod:`mitlc.learn.jitcache` keeps a kernel on disk one module per function, named by the hash of
its text, so the second spec's kernel on a machine compiles only what differs from the first's
(its trial, the plant's step, its predicates) and loads the rest compiled. For each pair of shipped
specs ``A -> B`` below, each in fresh processes and a fresh ``MITLC_CACHE_DIR``: the first trial of
``B`` (one run; the compile and the trial) with an empty cache (**cold**, the baseline: every
function compiled, as before the kernels were split), and with ``A``'s kernel compiled before by
another process (**after A**); the fastest of ``--repeat`` each, and their ratio. It prints
timings; it asserts nothing about them.

``--repeat 2`` on this project's 2-core machine, another job on the other core (docs/training.md)::

    first trial of B (one run), seconds, fastest of 2, kernel = numba
      pendulum/n1_reach_in_time -> pendulum/n2_hold_up: cold  11.77  after A   3.65  cold / after  3.22x
      pendulum/p1_swing_up -> pendulum/p4_alternate: cold   5.96  after A   2.63  cold / after  2.26x
      pendulum/p2_avoid -> pendulum/n3_bounded_response: cold  12.75  after A   8.24  cold / after  1.55x
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

PAIRS = [
    ("pendulum/n1_reach_in_time", "pendulum/n2_hold_up"),  # timed obligations, other predicates
    ("pendulum/p1_swing_up", "pendulum/p4_alternate"),  # no obligations
    ("pendulum/p2_avoid", "pendulum/n3_bounded_response"),  # a first kernel without obligations
]

FIRST_TRIAL = """
import sys, time
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.petri.compile import compile_spec
from mitlc.spec.parse import load_spec
agent = Sacpn(compile_spec(load_spec(sys.argv[1])), SacpnSettings(kernel=sys.argv[2]), runs=1, seed=0)
assert agent.kernel == sys.argv[2], agent.kernel_reason
t0 = time.perf_counter()
agent.train(1)
print(time.perf_counter() - t0)
"""


def first_trial(spec: str, kernel: str, cache: str) -> float:
    """Seconds of ``spec``'s first trial in a new process with the kernel cache ``cache``."""
    env = {**os.environ, "MITLC_CACHE_DIR": cache, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    path = str(ROOT / "specs" / f"{spec}.mitl")
    out = subprocess.run([sys.executable, "-c", FIRST_TRIAL, path, kernel], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(out.stderr)
    return float(out.stdout.split()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--kernel", choices=("numba", "simd"), default="numba")
    args = ap.parse_args()
    print(f"first trial of B (one run), seconds, fastest of {args.repeat}, kernel = {args.kernel}")
    for a, b in PAIRS:
        cold, after = [], []
        for _ in range(args.repeat):  # interleaved: a slow moment of the machine hits both
            with tempfile.TemporaryDirectory() as cache:
                cold.append(first_trial(b, args.kernel, cache))
            with tempfile.TemporaryDirectory() as cache:
                first_trial(a, args.kernel, cache)
                after.append(first_trial(b, args.kernel, cache))
        c, f = min(cold), min(after)
        print(f"  {a} -> {b}: cold {c:6.2f}  after A {f:6.2f}  cold / after {c / f:5.2f}x", flush=True)


if __name__ == "__main__":
    main()
