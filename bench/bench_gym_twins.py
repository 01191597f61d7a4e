"""What the numpy twins of Gymnasium's continuous classic-control environments save.

A trainer's copies of ``Pendulum-v1`` or ``MountainCarContinuous-v0`` are reset by Gymnasium and
stepped by a twin (:mod:`mitlc.plants.gym_twins`: the environment's numbers to the bit, all copies
in a few numpy operations). This bench steps ``B`` copies of each, in one process, both ways:
through Gymnasium's synchronous vector environment (the baseline: one Python ``step`` per copy) and
through the twin, with the same actions, and prints microseconds per copy-step and the ratio, for
a few batch sizes (a search generation of the race rolls out 8 runs x 16 candidates x 4 starts = 512
copies; 30 runs of SACPN are 30). It also checks that both ways gave the same observations.

    python bench/bench_gym_twins.py [--steps 100]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.plants.gym_twins import TWINS  # noqa: E402


def one(env_id: str, B: int, steps: int) -> tuple[float, float]:
    """Seconds per copy-step through the vector environment and through the twin, on the same actions."""
    import gymnasium as gym

    vec = gym.make_vec(
        env_id,
        num_envs=B,
        vectorization_mode="sync",
        vector_kwargs={"copy": False},
        max_episode_steps=2**62,
        disable_env_checker=True,
    )
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.0, 1.0, size=(steps, B, 1)).astype(np.float32)
    vec.reset(seed=list(range(B)))
    twin = TWINS[env_id](vec.envs[0].unwrapped, B)
    twin.load(vec.envs)
    t0 = time.perf_counter()
    for k in range(steps):
        twin_obs, _ = twin.step(actions[k])
    fast = time.perf_counter() - t0
    t0 = time.perf_counter()
    for k in range(steps):
        obs, *_ = vec.step(actions[k])
    slow = time.perf_counter() - t0
    vec.close()
    if env_id.startswith("Pendulum") and not np.array_equal(obs, twin_obs):  # MountainCar autoresets at its goal
        raise SystemExit(f"{env_id}: the twin and the environment disagree")
    return slow / (steps * B), fast / (steps * B)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=100, help="steps per measurement (default 100)")
    a = ap.parse_args(argv)
    print(f"{'environment':<26} {'copies':>6} {'Gymnasium us':>13} {'twin us':>9} {'ratio':>7}")
    for env_id in TWINS:
        for B in (30, 512, 2048):
            slow, fast = one(env_id, B, a.steps)
            print(f"{env_id:<26} {B:>6} {slow * 1e6:>13.2f} {fast * 1e6:>9.3f} {slow / fast:>6.0f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
