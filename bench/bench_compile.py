"""Compiler scaling: places grow linearly with formula size; a 50-operator formula compiles fast.

Run:  python bench/bench_compile.py [--seed 0] [--repeat 20]

For random formulas over 4 propositions of growing size it prints the place
and transition counts, places per operator, and the median time to parse and
compile, as ratios against the smallest size measured in the same process
(a flat ``time/op ratio`` means linear cost).
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np
from _timing import timed  # bench/ is on sys.path when a bench runs

from mitlc.petri.compile import compile_spec
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_spec

PROPS = "prop a = x < 0\nprop b = x > 1\nprop c = y < 0\nprop d = 0 < x < 1 and y > 2\n"
UNARY = ("not", "F", "G", "Fi", "Gi", "w")
BINARY = ("and", "or", "implies", "U", "Ui", "R")


def random_formula(rng: np.random.Generator, ops: int) -> A.Formula:
    """A random formula with exactly ``ops`` operator nodes over atoms a..d."""
    if ops == 0:
        return A.Atom(str(rng.choice(list("abcd"))))
    kind = rng.choice(UNARY + BINARY)
    lo = float(rng.integers(0, 3))
    iv = A.Interval(lo, lo + float(rng.integers(1, 3)))
    if kind in UNARY:
        child = random_formula(rng, ops - 1)
        return {
            "not": lambda: A.Not(child),
            "F": lambda: A.Eventually(child),
            "G": lambda: A.Globally(child),
            "Fi": lambda: A.Eventually(child, iv),
            "Gi": lambda: A.Globally(child, iv),
            "w": lambda: A.Weighted(float(rng.integers(1, 10)), child),
        }[kind]()
    left_ops = int(rng.integers(0, ops))
    left, right = random_formula(rng, left_ops), random_formula(rng, ops - 1 - left_ops)
    return {
        "and": lambda: A.And(left, right),
        "or": lambda: A.Or(left, right),
        "implies": lambda: A.Implies(left, right),
        "U": lambda: A.Until(left, right),
        "Ui": lambda: A.Until(left, right, iv),
        "R": lambda: A.Release(left, right),
    }[kind]()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--samples", type=int, default=8, help="random formulas per size")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    sizes = [5, 10, 25, 50, 100, 200]
    print(f"{'ops':>5} {'places':>7} {'trans':>6} {'places/op':>9} {'ms':>8} {'ms/op':>7} {'ratio':>6}")
    base = None
    at_50 = []
    for n in sizes:
        places, trans, times = [], [], []
        for _ in range(args.samples):
            text = PROPS + "formula " + str(random_formula(rng, n)) + "\n"
            spec = parse_spec(text)
            rs = compile_spec(spec)
            places.append(len(rs.net.places))
            trans.append(len(rs.net.transitions))
            times.append(timed(lambda text=text: compile_spec(parse_spec(text)), args.repeat))
        ms = 1000 * statistics.median(times)
        per_op = ms / n
        base = base or per_op
        if n == 50:
            at_50 = times
        print(
            f"{n:>5} {statistics.mean(places):>7.1f} {statistics.mean(trans):>6.1f} "
            f"{statistics.mean(places) / n:>9.2f} {ms:>8.2f} {per_op:>7.3f} {per_op / base:>6.2f}"
        )
    print(
        f"\n50-operator formulas: parse + compile median {1000 * statistics.median(at_50):.1f} ms, "
        f"worst {1000 * max(at_50):.1f} ms (budget 50 ms)"
    )


if __name__ == "__main__":
    main()
