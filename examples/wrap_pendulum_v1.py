"""Gymnasium's Pendulum-v1 rewarded by a compiled MITL spec, driven by a random agent.

    pip install 'mitlc[gym]'
    python examples/wrap_pendulum_v1.py                               # problem 1, 3 s
    python examples/wrap_pendulum_v1.py specs/pendulum/p5_timed_visit.mitl --seed 4

Each line is one step: the clock tau, the angle q from upright, the marked
places M_k+1, the compiled reward r(M_k, M_k+1) and Pendulum-v1's own reward.
The episode ends at the spec's horizon; the monitor's verdict on the whole
trace is printed at the end.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec", nargs="?", default=str(ROOT / "specs" / "pendulum" / "p1_swing_up.mitl"))
    parser.add_argument("--seed", type=int, default=1, help="seeds the environment and the random agent")
    parser.add_argument("--marking-obs", choices=["dict", "box"], default="dict")
    args = parser.parse_args(argv)

    try:
        import gymnasium as gym

        from mitlc.gym import MitlRewardWrapper, pendulum_v1_state
    except ImportError as err:
        print(f"{err}", file=sys.stderr)
        return 1
    from mitlc.errors import MitlError

    try:
        env = MitlRewardWrapper(
            gym.make("Pendulum-v1"),
            args.spec,
            pendulum_v1_state,
            marking_obs=args.marking_obs,
            verdict="end",
            truncate_at_horizon=True,
        )
    except MitlError as err:
        print(err.render(), file=sys.stderr)
        return 2

    names = env.place_names
    print(f"spec {Path(args.spec).name}: {env.mitl_spec.formula}")
    print(f"places {', '.join(names)}; dt = {env.dt} s; horizon {env.horizon} s")
    env.action_space.seed(args.seed)
    obs, info = env.reset(seed=args.seed)
    q = env.state(obs["obs"] if args.marking_obs == "dict" else obs[:3])[0]
    print(f"tau  0.00  q {q:+.3f}  M {_marked(info['marking'], names)}")
    total, env_total, done = 0.0, 0.0, False
    while not done:
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        done = terminated or truncated
        q = env.state(obs["obs"] if args.marking_obs == "dict" else obs[:3])[0]
        total += reward
        env_total += float(info["env_reward"])
        print(
            f"tau {info['tau']:5.2f}  q {q:+.3f}  M {_marked(info['marking'], names):28s}"
            f"  r {reward:+6.2f}  env r {float(info['env_reward']):+7.3f}"
        )
    print(f"return {total:+.2f} (Pendulum-v1's own reward would give {env_total:+.2f})")
    verdict = info.get("verdict")
    if verdict is not None:
        what = (
            "satisfied"
            if verdict["satisfied"]
            else f"violated at {verdict['violation_time']} s by {verdict['failing']}"
        )
        print(f"monitor: {what}, robustness {verdict['robustness']:+.3f}")
    env.close()
    return 0


def _marked(marking: np.ndarray, names: tuple[str, ...]) -> str:
    return ", ".join(n for n, m in zip(names, marking, strict=True) if m)


if __name__ == "__main__":
    sys.exit(main())
