"""Train the built-in SACPN learner on a pendulum spec from Python, then judge it.

    python examples/train_pendulum.py                                  # problem 1, 4 runs x 500 trials
    python examples/train_pendulum.py specs/pendulum/p2_avoid.mitl --trials 2000 --runs 8 --out runs/p2

The same as ``mitlc train``, as library calls: compile the spec, train
``runs`` independent learners at once (:class:`mitlc.learn.sacpn.Sacpn`, thesis
Algorithm 1 with the settings of Table 4-4), roll each one's greedy policy out
from its own initial state, and judge the rollouts with the monitor (the
spec's ``check`` formula, or its formula).  A seed reproduces the whole run to
the bit.  On problem 1 (swing up with a weak motor) the defaults take a few
seconds and every run learns to swing up and stay up.

Writes ``<out>/params.npz`` (the learner's checkpoint, readable by
``mitlc simulate`` and ``mitlc.load_policy``) and ``<out>/rollout.npz``: run 0's
greedy rollout as a trace ``mitlc check SPEC <out>/rollout.npz`` reads (``t``,
``q``, ``qdot``), and every run's states, actions and rewards.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import mitlc
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.monitor.offline import monitor

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec", nargs="?", default=str(ROOT / "specs" / "pendulum" / "p1_swing_up.mitl"))
    parser.add_argument("--trials", type=int, default=500, help="trials per run (3 s each for the pendulum specs)")
    parser.add_argument("--runs", type=int, default=4, help="independent learners trained at once")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--report", type=int, default=5, help="progress lines while training")
    parser.add_argument("--out", default="out", help="directory for params.npz and rollout.npz")
    args = parser.parse_args(argv)

    try:
        spec = mitlc.load_spec(args.spec)
        rs = mitlc.compile_spec(spec)
        agent = Sacpn(rs, SacpnSettings(), runs=args.runs, seed=args.seed)
    except mitlc.MitlError as err:
        print(err.render(), file=sys.stderr)
        return 2

    print(f"spec {Path(args.spec).name}: {spec.formula}")
    print(f"{args.runs} runs x {args.trials} trials of {agent.n_steps} steps (dt = {agent.dt} s), seed {args.seed}")
    chunk = max(1, args.trials // max(1, args.report))
    while agent.trial < args.trials:
        # total: the whole plan, so that a violation penalty's ramp spans all the chunks
        returns = agent.train(min(chunk, args.trials - agent.trial), total=args.trials)  # (runs, chunk trials)
        print(f"trials {agent.trial:5d}: mean return of the last {returns.shape[1]} {returns.mean():+9.2f}")

    rollout = agent.rollout(agent.evaluation_states())
    verdict = monitor(spec, rollout.states, rollout.dt)
    for r in range(args.runs):
        what = (
            "satisfied"
            if verdict.satisfied[r]
            else (f"violated at {verdict.violation_time[r]:g} s by {verdict.failing[r]}")
        )
        print(f"run {r}: greedy return {rollout.returns[r]:+8.2f}, robustness {verdict.robustness[r]:+.3f}, {what}")
    print(f"satisfied {int(verdict.satisfied.sum())}/{args.runs}")

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    agent.save(out / "params.npz")
    # run 0's rollout as a trace `mitlc check SPEC rollout.npz` reads (t, q, qdot), and every
    # run's states, inputs and rewards beside it (check ignores arrays it does not need)
    t = np.arange(rollout.states.shape[1]) * rollout.dt
    np.savez(
        out / "rollout.npz",
        t=t,
        q=rollout.states[0, :, 0],
        qdot=rollout.states[0, :, 1],
        states=rollout.states,
        actions=rollout.actions,
        rewards=rollout.rewards,
        dt=rollout.dt,
    )
    print(f"wrote params.npz, rollout.npz to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
