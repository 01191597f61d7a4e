"""The Gymnasium wrapper's cost per step over the bare environment, in each ``verdict`` mode.

Run:  python bench/bench_gym.py [--steps 2000] [--repeat 5] [--spec pendulum/p1_swing_up]

Steps ``Pendulum-v1`` (its bare step, unwrapped) and :class:`mitlc.gym.MitlRewardWrapper`
around it with a constant input, in one process, the runs of each mode interleaved: the
wrapper with ``verdict="off"`` (the baseline: the net alone), ``"end"`` and ``"step"`` as they
are, and ``"step"`` on the array online monitor (:class:`mitlc.monitor.online.OnlineMonitor`,
what ``"step"`` ran before the one-run monitor :class:`mitlc.monitor.scalar.ScalarOnlineMonitor`).
Episodes are truncated at the spec's horizon. It prints the median microseconds per step of
``--repeat`` runs of ``--steps`` steps, the wrapper's overhead over the bare step and that
overhead over ``"off"``'s. It prints timings; it asserts nothing about them.

Measured (2 cores shared with other jobs, Python 3.11, p1_swing_up, ``F G kappa``, median of 7;
bare step 11.1), microseconds per step over the bare step:

=====================  =========  ==========
verdict                overhead   / ``off``
=====================  =========  ==========
``off``                     9.7        1.0
``end``                    13.3        1.4
``step``                   16.6        1.7
``step``, array monitor    87.8        9.0
=====================  =========  ==========

``end`` over ``off`` is the offline monitor once per (violated) episode of 60 steps; ``step`` over
``end`` the one-run online monitor (1.3 us a sample for ``F G kappa`` alone) and its ``info`` entry.
Where an episode ends satisfied, ``step`` takes its verdict from the online monitor and skips the
offline one.
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import gymnasium as gym
import numpy as np

from mitlc.gym import MitlRewardWrapper, pendulum_v1_state
from mitlc.monitor.online import OnlineMonitor
from mitlc.spec.parse import load_spec


def run_once(reset: Any, step: Any, steps: int, seed: int, episode: int | None = None) -> float:
    """Microseconds per step of ``steps`` steps (a reset when an episode ends, or every ``episode``
    steps: the bare environment's episodes as long as the wrapper's)."""
    a = np.array([0.5], dtype=np.float32)
    reset(seed=seed)
    k = 0
    t0 = time.perf_counter()
    for _ in range(steps):
        out = step(a)
        k += 1
        if out[2] or out[3] or k == episode:
            reset()
            k = 0
    return (time.perf_counter() - t0) / steps * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1200)
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--spec", default="pendulum/p1_swing_up")
    args = ap.parse_args()
    spec = load_spec(args.spec)

    def make(verdict: str) -> MitlRewardWrapper:
        return MitlRewardWrapper(
            gym.make("Pendulum-v1").unwrapped, spec, pendulum_v1_state, verdict=verdict, truncate_at_horizon=True
        )

    def reference(verdict: str) -> MitlRewardWrapper:  # the runtime's arrays and the offline monitor
        env = make(verdict)
        env._step1 = None  # noqa: SLF001 - the array path: step_code and reward_code on (1, n) arrays
        env._judge = None  # noqa: SLF001 - the episode's verdict by mitlc.monitor.monitor
        return env

    array = reference("step")
    array._online = OnlineMonitor(spec, array.dt)  # noqa: SLF001 - the monitor "step" ran before the one-run one
    array._online_scalar = False  # noqa: SLF001
    bare = gym.make("Pendulum-v1").unwrapped
    episode = make("off").runtime.steps or int(round(spec.horizon / bare.dt))
    envs: dict[str, Any] = {"bare": bare, "off": make("off"), "end": make("end"), "step": make("step")}
    for verdict in ("off", "end", "step"):
        envs[f"{verdict}, reference"] = reference(verdict)
    envs["step, array monitor"] = array
    times: dict[str, list[float]] = {name: [] for name in envs}
    for r in range(args.repeat):  # interleaved: a load that comes and goes hits every mode alike
        for name, env in envs.items():
            times[name].append(run_once(env.reset, env.step, args.steps, r, episode if name == "bare" else None))
    t = {name: statistics.median(ts) for name, ts in times.items()}
    # the overhead of a round: the mode's time less the bare step's of the same round (a load that
    # drifts between rounds cancels out), then the median over the rounds
    over = {
        name: statistics.median(a - b for a, b in zip(ts, times["bare"], strict=True)) for name, ts in times.items()
    }
    print(f"Pendulum-v1 with {args.spec} ({spec.formula}); microseconds per step, median of {args.repeat}")
    print(f"  bare environment step: {t['bare']:8.1f} (reset every {episode} steps, as the wrapper's episodes)")
    print(f"  {'verdict':<20} {'step':>8} {'overhead':>9} {'/ off':>6}")
    for name in envs:
        if name != "bare":
            print(f"  {name:<20} {t[name]:8.1f} {over[name]:9.1f} {over[name] / over['off']:6.1f}")


if __name__ == "__main__":
    main()
