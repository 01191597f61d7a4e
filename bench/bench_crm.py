"""What counterfactual markings (mitlc.gym.crm) cost per environment step, against SB3's own buffer.

Run:  python bench/bench_crm.py [--steps 2000] [--repeat 3] [--spec pendulum/p4_alternate]

Records ``--steps`` transitions of a seeded random agent on Pendulum-v1 wrapped by
:class:`mitlc.gym.MitlRewardWrapper` (``marking_obs="box"``), then times adding them to
Stable-Baselines3's ``ReplayBuffer`` and to :class:`mitlc.gym.crm.CounterfactualReplayBuffer` in one
process, and prints the median microseconds per environment step of ``--repeat`` passes, the
counterfactual transitions added per step, and the ratio. It prints timings; it asserts nothing.
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym
import numpy as np
from stable_baselines3.common.buffers import ReplayBuffer

from mitlc.gym import MitlRewardWrapper, pendulum_v1_state
from mitlc.gym.crm import CounterfactualReplayBuffer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--spec", default="pendulum/p4_alternate")
    args = ap.parse_args()
    env = MitlRewardWrapper(
        gym.make("Pendulum-v1"),
        args.spec,
        pendulum_v1_state,
        marking_obs="box",
        verdict="off",
        truncate_at_horizon=True,
    )
    env.action_space.seed(0)
    obs, _ = env.reset(seed=0)
    rows = []
    for _ in range(args.steps):
        a = env.action_space.sample()
        nxt, r, term, trunc, info = env.step(a)
        rows.append((obs[None], nxt[None], a[None], np.array([r]), np.array([term]), [info]))
        obs = nxt if not (term or trunc) else env.reset()[0]

    def timed(make) -> tuple[float, int]:
        times, added = [], 0
        for _ in range(args.repeat):
            buf = make()
            t0 = time.perf_counter()
            for row in rows:
                buf.add(*row)
            times.append((time.perf_counter() - t0) / len(rows) * 1e6)
            added = getattr(buf, "added", 0)
        return statistics.median(times), added

    size = args.steps * 8
    plain, _ = timed(lambda: ReplayBuffer(size, env.observation_space, env.action_space, device="cpu"))
    crm, added = timed(
        lambda: CounterfactualReplayBuffer(size, env.observation_space, env.action_space, device="cpu", wrapper=env)
    )
    print(f"{args.spec} on Pendulum-v1, {args.steps} transitions; microseconds per environment step,")
    print(f"median of {args.repeat}")
    print(f"  SB3 ReplayBuffer.add:            {plain:8.1f}")
    print(
        f"  CounterfactualReplayBuffer.add:  {crm:8.1f}  ({added / args.steps:.2f} counterfactual transitions per step)"
    )
    per = added / args.steps
    each = f"{(crm - plain) / per:.1f} us per counterfactual transition" if per else "no counterfactual markings"
    print(f"  ratio: {crm / plain:.1f}x; {each}")


if __name__ == "__main__":
    main()
