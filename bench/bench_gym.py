"""The Gymnasium wrapper's cost per step over the bare environment, in each ``verdict`` mode.

Run:  python bench/bench_gym.py [--steps 1200] [--repeat 15] [--spec pendulum/p1_swing_up]

Steps ``Pendulum-v1`` (its bare step, unwrapped, reset every episode's length: 60 steps for P1's
3 s at 0.05 s) and :class:`mitlc.gym.MitlRewardWrapper` around it with a constant input, in one
process, the runs of each mode interleaved: the wrapper with ``verdict="off"`` (the net alone),
``"end"`` and ``"step"`` as they are; the same three on the reference path (``, reference``: the
runtime's ``(1, n)`` arrays, the start found by :meth:`~mitlc.runtime.NetRuntime.reset`, the
episode's verdict by :func:`mitlc.monitor.monitor`), which the fast path equals to the bit
(tests/test_gym_fast_path.py); and ``"step"`` on the array online monitor
(:class:`mitlc.monitor.online.OnlineMonitor`, what ``"step"`` ran before the one-run monitor
:class:`mitlc.monitor.scalar.ScalarOnlineMonitor`). Episodes are truncated at the spec's horizon.
It prints the median microseconds per step of ``--repeat`` rounds of ``--steps`` steps, and each
mode's overhead: the median over the rounds of its time less the bare step's of the same round (a
load that drifts between rounds cancels), and that over ``"off"``'s. It prints timings; it asserts
nothing about them.

Measured 2026-12-07 (2 cores, the other busy with another job: every figure moves by a third
between runs; Python 3.11, numpy 2.4, p1_swing_up, ``F G kappa``), microseconds per step over the
bare step, this bench (15 rounds) on the code before (main at e6742ca) and after, run one after
the other; the quietest of three pairs of runs (bare step 11.6 / 12.3 us), then the median of the
three:

=====================  ===========  ==========  ==================
verdict                before       after       after, 3 runs
=====================  ===========  ==========  ==================
``off``                     9.6          4.4      6.0 (4.4-6.6)
``end``                    13.9          6.5      9.0 (6.5-9.1)
``step``                   18.3          7.3     10.7 (7.3-10.8)
``off``, reference         23.2         18.7
``end``, reference         28.7         24.9
``step``, reference        34.2         27.5
``step``, array monitor   109.7        112.0
=====================  ===========  ==========  ==================

(before: 10.1-13.3, 13.9-16.7 and 18.0-21.7 over the three runs).

Measured 2026-12-08 on a quiet 2-core machine, ``--repeat 15``, two runs of this bench on the code
after (main at 57fac6b: the Pendulum-v1 reader's ``arctan2`` on arrays of one it keeps, one marking
copy a step) and of the code before (main at 39ca212, in its own process), interleaved, bare step
10.3-10.5 us: microseconds per step over the bare step, before -> after, ``off`` 3.6 / 3.5 -> 3.0 /
3.1, ``end`` 5.0 / 5.0 -> 4.4 / 4.6, ``step`` 6.0 / 5.9 -> 5.3 / 5.4. Where the net is tabulated and
untimed, a step is the propositions as one generated function, two look-ups in nested lists and a
marking row copied; ``end`` over ``off`` is the verdict of each (violated) 60-step episode by
:class:`mitlc.monitor.scalar_offline.ScalarTraceMonitor` (about 70 us, against the offline
monitor's 180 us); ``step`` over ``end`` the one-run online monitor (about 1 us a sample for
``F G kappa``) and its ``info`` entry. Where an episode ends satisfied, ``step`` takes its verdict
from the online monitor and judges nothing more.
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
