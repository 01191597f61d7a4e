"""The Gymnasium wrapper's cost per step over the bare environment, today against the old path.

Run:  python bench/bench_gym.py [--steps 2000] [--repeat 3] [--spec pendulum/p1_swing_up]

Steps ``Pendulum-v1`` (its bare step, unwrapped) and :class:`mitlc.gym.MitlRewardWrapper`
around it with a constant input, in one process: the wrapper with ``verdict="off"``, ``"end"``
and ``"step"`` as they are, and the old path of each (before #17: the net stepped on markings,
``NetRuntime.step`` and ``.reward``, and for ``"step"`` the offline monitor over the whole
prefix ``x_0 .. x_k`` after every step, which this bench still calls). Episodes are
truncated at the spec's horizon. It prints the median microseconds per step of
``--repeat`` runs of ``--steps`` steps, the wrapper's overhead over the bare step, and the
ratios old / new. It prints timings; it asserts nothing about them.
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import gymnasium as gym
import numpy as np

from mitlc.gym import MitlRewardWrapper, pendulum_v1_state
from mitlc.spec.parse import load_spec


def old_path(env: MitlRewardWrapper, verdict: bool) -> Any:
    """The wrapper's step as it was: markings, not codes; the offline monitor on the prefix."""
    env._marking_of = None  # noqa: SLF001 - a bench of the wrapper's own internals
    env._code = None  # noqa: SLF001
    env._step1 = None  # noqa: SLF001
    online = env._online  # noqa: SLF001
    env._online = None  # noqa: SLF001
    step = env.step

    def stepped(action: Any) -> Any:
        out = step(action)
        if verdict and online is not None and not (out[2] or out[3]):
            env._add_verdict(out[4])  # noqa: SLF001
        return out

    return stepped


def per_step(reset: Any, step: Any, steps: int, repeat: int) -> float:
    a = np.array([0.5], dtype=np.float32)
    times = []
    for r in range(repeat):
        reset(seed=r)
        t0 = time.perf_counter()
        for _ in range(steps):
            out = step(a)
            if out[2] or out[3]:
                reset()
        times.append((time.perf_counter() - t0) / steps * 1e6)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--spec", default="pendulum/p1_swing_up")
    args = ap.parse_args()
    spec = load_spec(args.spec)
    bare = gym.make("Pendulum-v1").unwrapped
    t_bare = per_step(bare.reset, bare.step, args.steps, args.repeat)
    print(f"Pendulum-v1 with {args.spec} ({spec.formula}); microseconds per step, median of {args.repeat}")
    print(f"  bare environment step: {t_bare:8.1f}")
    print(f"  {'verdict':<8} {'new':>8} {'over bare':>10} {'old':>8} {'over bare':>10} {'old/new':>8}")
    for verdict in ("off", "end", "step"):

        def make(verdict: str = verdict) -> MitlRewardWrapper:
            env = gym.make("Pendulum-v1").unwrapped
            return MitlRewardWrapper(env, spec, pendulum_v1_state, verdict=verdict, truncate_at_horizon=True)

        new = make()
        t_new = per_step(new.reset, new.step, args.steps, args.repeat)
        old = make()
        t_old = per_step(old.reset, old_path(old, verdict == "step"), args.steps, args.repeat)
        print(
            f"  {verdict:<8} {t_new:8.1f} {t_new - t_bare:10.1f} {t_old:8.1f} {t_old - t_bare:10.1f} "
            f"{t_old / t_new:8.1f}"
        )


if __name__ == "__main__":
    main()
