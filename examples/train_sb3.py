"""Train Stable-Baselines3's SAC on Gymnasium's Pendulum-v1 rewarded by a compiled MITL spec.

It needs PyTorch (CI installs its CPU build and runs this briefly, tests/test_examples.py).
Install and run:

    pip install 'mitlc[gym]' stable-baselines3
    python examples/train_sb3.py                                   # problem 1, 30k steps
    python examples/train_sb3.py specs/pendulum/p2_avoid.mitl --timesteps 60000 --out runs/p2

What it does:

1. wraps ``Pendulum-v1`` with :class:`mitlc.gym.MitlRewardWrapper`: the reward is
   the spec's compiled reward ``r(M_k, M_k+1)``, the observation is Pendulum's
   ``[cos q, sin q, qdot]`` followed by the marking ``M_k`` of the reward net (a
   flat ``Box``, so SAC's ``MlpPolicy`` reads it; with ``marking_obs="dict"`` use
   ``MultiInputPolicy``), and an episode lasts the spec's horizon (3 s = 60 steps
   of 0.05 s);
2. trains SAC with Stable-Baselines3's defaults, seeded;
3. saves the model to ``<out>/sac_<spec>.zip`` and runs deterministic test
   episodes, printing each one's return and the monitor's verdict
   (``info["verdict"]``: the spec's ``check`` formula, or its formula).

Pendulum-v1 is not the thesis's DCSC pendulum (its torque limit is 2 N m and
its parameters differ), but both measure ``q`` from upright, so the spec's
regions mean the same thing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec", nargs="?", default=str(ROOT / "specs" / "pendulum" / "p1_swing_up.mitl"))
    parser.add_argument("--timesteps", type=int, default=30_000, help="environment steps to train for")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--episodes", type=int, default=10, help="deterministic test episodes after training")
    parser.add_argument("--out", default="runs", help="directory for the trained model")
    args = parser.parse_args(argv)

    try:
        from stable_baselines3 import SAC
    except ImportError:
        print(
            "train_sb3.py needs Stable-Baselines3 (and PyTorch), which mitlc does not install: "
            "pip install stable-baselines3 'mitlc[gym]'",
            file=sys.stderr,
        )
        return 1
    import gymnasium as gym

    from mitlc.errors import MitlError
    from mitlc.gym import MitlRewardWrapper, pendulum_v1_state

    def make_env() -> MitlRewardWrapper:
        return MitlRewardWrapper(
            gym.make("Pendulum-v1"),
            args.spec,
            pendulum_v1_state,
            marking_obs="box",
            verdict="end",
            truncate_at_horizon=True,
        )

    try:
        env = make_env()
    except MitlError as err:
        print(err.render(), file=sys.stderr)
        return 2
    print(f"spec {Path(args.spec).name}: {env.mitl_spec.formula}")
    print(f"observation: Pendulum-v1's 3 values + marking of {', '.join(env.place_names)}")

    model = SAC("MlpPolicy", env, seed=args.seed, verbose=1)
    model.learn(total_timesteps=args.timesteps)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"sac_{Path(args.spec).stem}.zip"
    model.save(path)
    print(f"saved {path}")

    test_env = make_env()
    satisfied = 0
    for episode in range(args.episodes):
        obs, info = test_env.reset(seed=10_000 + episode)
        total, done = 0.0, False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = test_env.step(action)
            total += reward
            done = terminated or truncated
        verdict = info.get("verdict")
        ok = verdict is not None and verdict["satisfied"]
        satisfied += ok
        what = (
            ""
            if verdict is None
            else ("  satisfied" if ok else f"  violated at {verdict['violation_time']} s by {verdict['failing']}")
        )
        print(f"test episode {episode}: return {total:+.1f}{what}")
    print(f"satisfied {satisfied}/{args.episodes}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
