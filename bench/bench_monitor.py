"""Monitor scaling: the cost per sample stays flat from 10^3 to 10^6 samples.

Run:  python bench/bench_monitor.py [--seed 0] [--repeat 5] [--max-exp 6]

For formulas with interval operators at dt = 0.01 (windows of 100 and 200
samples) it prints the median time of :func:`mitlc.monitor.monitor` (verdict,
robustness, violation time and failing subformula) on one trace of growing
length, the time per sample, and its ratio against the smallest size measured
in the same process. A flat ``per-sample ratio`` means linear cost. It then
times a naive evaluation, one ``max``/``min`` per window offset
(O(N x window)), at one size and prints how many times slower it is. It
prints timings; it asserts nothing about them.
"""

from __future__ import annotations

import argparse

import numpy as np
from _timing import timed  # bench/ is on sys.path when a bench runs

from mitlc.monitor.offline import monitor, signals
from mitlc.spec.parse import parse_formula, parse_spec

DT = 0.01
SPEC = parse_spec("prop a = x > 0\nprop b = y > 0\nformula G[0,2] (a -> F[0,1] b)")
FORMULAS = (
    "G[0,2] (a -> F[0,1] b)",
    "G (a -> F[0,1] b)",
    "F[1,3] G[0,2] b",
    "a U[1,2] b",
)


def trace(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """Periodic signals with a little noise: ``b`` holds for 0.75 s of every 1.5 s,
    ``a`` for 3.5 s of every 7 s (from the start), so each formula gets the same verdict at every
    length (the violated one exercises the violation time and blame too)."""
    t = np.arange(n) * DT
    x = np.sin(2 * np.pi * t / 7.0 + 0.3) + rng.normal(0.0, 0.01, n)
    y = np.sin(2 * np.pi * t / 1.5) + rng.normal(0.0, 0.01, n)
    return {"x": x, "y": y}


def naive_window(x: np.ndarray, lo: int, hi: int, op: np.ufunc, ident: float) -> np.ndarray:
    """``y[k] = op(x[k+lo .. min(k+hi, N)])``: one pass per window offset."""
    n = len(x)
    out = np.full(n, ident)
    for j in range(lo, hi + 1):
        if j >= n:
            break
        out[: n - j] = op(out[: n - j], x[j:])
    return out


def naive_first(states: dict[str, np.ndarray]) -> np.ndarray:
    """Robustness of ``G[0,2] (a -> F[0,1] b)`` by the naive O(N x window) method."""
    ra, rb = states["x"], states["y"]
    f = naive_window(rb, 0, round(1 / DT), np.maximum, -np.inf)
    body = np.maximum(-ra, f)
    return naive_window(body, 0, round(2 / DT), np.minimum, np.inf)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=5, help="timings per size (median); 10^6 uses fewer")
    ap.add_argument("--max-exp", type=int, default=6, help="largest size is 10^MAX_EXP samples")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    sizes = [10**e for e in range(3, args.max_exp + 1)]
    traces = {n: trace(rng, n) for n in sizes}

    print(f"mitlc monitor: one trace, dt = {DT} s; time per sample should stay flat")
    for text in FORMULAS:
        f = parse_formula(text)
        print(f"\nformula: {text}")
        print(f"{'samples':>9} {'median ms':>10} {'ns/sample':>10} {'per-sample ratio':>17}  verdict")
        base = None
        for n in sizes:
            states = traces[n]
            repeat = max(1, args.repeat if n < 10**6 else min(args.repeat, 3))
            monitor(SPEC, states, DT, f)  # warm-up
            sec = timed(lambda states=states, f=f: monitor(SPEC, states, DT, f), repeat)
            per = sec / n * 1e9
            base = per if base is None else base
            res = monitor(SPEC, states, DT, f)
            verdict = "satisfied" if res.satisfied[0] else f"violated at t = {res.violation_time[0]:g} s"
            print(f"{n:>9} {sec * 1e3:>10.2f} {per:>10.1f} {per / base:>17.2f}  {verdict}")

    n = 10**5 if args.max_exp >= 5 else sizes[-1]
    states = traces[n]
    f = parse_formula(FORMULAS[0])
    fast_sig = signals(SPEC, states, DT, f)[FORMULAS[0]][0]
    slow_sig = naive_first(states)
    if not np.array_equal(fast_sig, slow_sig):  # a sanity check, not a timing assertion
        raise SystemExit("the naive and the sliding-window robustness differ")
    fast = timed(lambda: signals(SPEC, states, DT, f), args.repeat)
    slow = timed(lambda: naive_first(states), args.repeat)
    print(f"\nnaive O(N x window) baseline, {FORMULAS[0]} at {n} samples (windows of 101 and 201 samples):")
    print(f"  sliding window (van Herk/Gil-Werman): {fast * 1e3:8.2f} ms  (robustness signals of every subformula)")
    print(f"  naive, one pass per window offset:    {slow * 1e3:8.2f} ms  (robustness of the formula only)")
    print(f"  naive / sliding: {slow / fast:.1f}x")


if __name__ == "__main__":
    main()
