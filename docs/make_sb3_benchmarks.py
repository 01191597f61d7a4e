"""Stable-Baselines3 SAC on Gymnasium's Pendulum-v1, with and without counterfactual markings.

The compiled reward of a thesis spec pays SAC through :class:`mitlc.gym.MitlRewardWrapper`
(``marking_obs="box"``: Pendulum's observation and the marking); with ``--crm`` rows the replay
buffer is :class:`mitlc.crm.CounterfactualReplayBuffer`. After ``--steps`` environment steps the
deterministic policy runs ``--episodes`` episodes from seeded resets, each judged by the monitor
on its whole trace; a row is the success rate's mean and 95 % interval over ``--seeds`` seeds,
with the mean |u|, the input's total variation per second and the wall time.

    python docs/make_sb3_benchmarks.py --jobs 2          # the section of docs/benchmarks.md
    python docs/make_sb3_benchmarks.py --quick --out DIR  # a smoke run

Writes the block between ``<!-- sb3:begin -->`` and ``<!-- sb3:end -->`` of docs/benchmarks.md and
docs/figures/benchmarks_sb3.json (with ``--out``, ``sb3.md`` and the data file in DIR).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from results_stats import interval, machine  # noqa: E402  (docs/, the script's own folder)

from mitlc.fileio import atomic_write, write_block  # noqa: E402

BEGIN, END = "<!-- sb3:begin -->", "<!-- sb3:end -->"
# key, spec, reward design, counterfactual markings
ROWS = [
    ("P1", "specs/pendulum/p1_swing_up.mitl", "net", False),
    ("P1", "specs/pendulum/p1_swing_up.mitl", "shaped", False),
    ("P4", "specs/pendulum/p4_alternate.mitl", "net", False),
    ("P4", "specs/pendulum/p4_alternate.mitl", "net", True),
]


def train(job: tuple) -> dict:
    key, spec_file, design, crm, seed, steps, episodes = job
    import gymnasium as gym
    import torch
    from stable_baselines3 import SAC

    from mitlc.gym import MitlRewardWrapper, pendulum_v1_state
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.spec.parse import load_spec

    torch.set_num_threads(1)
    spec = load_spec(ROOT / spec_file)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, reward=design))

    def make(verdict: str) -> MitlRewardWrapper:
        return MitlRewardWrapper(
            gym.make("Pendulum-v1"), rs, pendulum_v1_state, marking_obs="box", verdict=verdict, truncate_at_horizon=True
        )

    env = make("off")
    kwargs: dict = {}
    if crm:
        from mitlc.crm import CounterfactualReplayBuffer

        kwargs = {"replay_buffer_class": CounterfactualReplayBuffer, "replay_buffer_kwargs": {"wrapper": env}}
    model = SAC("MlpPolicy", env, seed=seed, device="cpu", verbose=0, **kwargs)
    start = time.perf_counter()
    model.learn(steps)
    wall = time.perf_counter() - start
    test = make("end")
    wins, effort, chatter = [], [], []
    for e in range(episodes):
        obs, _ = test.reset(seed=10_000 * (seed + 1) + e)
        us = []
        while True:
            a, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = test.step(a)
            us.append(float(np.asarray(a).reshape(-1)[0]))  # Pendulum-v1's action is the torque, in [-2, 2] N m
            if terminated or truncated:
                break
        wins.append(bool(info["verdict"]["satisfied"]))
        u = np.array(us)
        effort.append(float(np.abs(u).mean()))
        chatter.append(float(np.abs(np.diff(u)).sum() / (len(u) * test.dt)))
    added = int(getattr(model.replay_buffer, "added", 0))
    return {
        "job": [key, design, crm, seed],
        "success": float(np.mean(wins)),
        "effort": float(np.mean(effort)),
        "chatter": float(np.mean(chatter)),
        "wall_s": wall,
        "counterfactual_per_step": added / steps,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--steps", type=int, default=12_000, help="environment steps per training")
    ap.add_argument("--episodes", type=int, default=20, help="deterministic test episodes per training")
    ap.add_argument("--quick", action="store_true", help="1 seed, 200 steps, 2 episodes: a smoke run")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    seeds, steps, episodes = (1, 200, 2) if args.quick else (args.seeds, args.steps, args.episodes)
    command = "python docs/make_sb3_benchmarks.py" + (" --quick" if args.quick else f" --jobs {args.jobs}")
    if not args.quick and (args.seeds, args.steps, args.episodes) != (5, 12_000, 20):
        command += f" --seeds {args.seeds} --steps {args.steps} --episodes {args.episodes}"
    t0 = time.perf_counter()
    jobs = [(k, f, d, c, s, steps, episodes) for k, f, d, c in ROWS for s in range(seeds)]
    results = []
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for r in pool.map(train, jobs):
            print(f"{r['job']}: success {r['success']:.2f} ({r['wall_s']:.0f} s)", flush=True)
            results.append(r)
    minutes = (time.perf_counter() - t0) / 60
    import stable_baselines3
    import torch

    lines = [
        BEGIN,
        "## Stable-Baselines3 SAC on Gymnasium's Pendulum-v1",
        "",
        f"Generated by `{command}` in {minutes:.1f} min ({machine('numba')}, torch {torch.__version__}, "
        f"stable-baselines3 {stable_baselines3.__version__}). SAC with Stable-Baselines3's defaults for "
        f"{steps} environment steps, paid by the spec's compiled reward through `MitlRewardWrapper` "
        '(`marking_obs="box"`); **CRM**: with `mitlc.crm.CounterfactualReplayBuffer`. Success: the fraction '
        f"of {episodes} deterministic test episodes (seeded resets) that the monitor accepts, mean and 95 % "
        f"interval over {seeds} seeds. Pendulum-v1's torque limit is 2 N m, not the thesis pendulum's.",
        "",
        "| spec | reward | CRM | success | per seed | abs(u) | TV/s | counterfactual / step | wall s |",
        "| --- | --- | --- | ---: | --- | ---: | ---: | ---: | ---: |",
    ]
    data = {"command": command, "minutes": round(minutes, 1), "steps": steps, "seeds": seeds, "rows": []}
    for key, spec_file, design, crm in ROWS:
        rs = [r for r in results if r["job"][:3] == [key, design, crm]]
        succ = [r["success"] for r in rs]
        m, h = interval(succ)
        cell = f"{m:.2f}" if not np.isfinite(h) else f"{m:.2f} ± {h:.2f}"
        lines.append(
            f"| {key} | `{design}` | {'yes' if crm else 'no'} | **{cell}** | "
            f"{' / '.join(f'{s:.2f}' for s in succ)} | {np.mean([r['effort'] for r in rs]):.2f} | "
            f"{np.mean([r['chatter'] for r in rs]):.1f} | {np.mean([r['counterfactual_per_step'] for r in rs]):.2f} | "
            f"{np.mean([r['wall_s'] for r in rs]):.0f} |"
        )
        data["rows"].append({"spec": spec_file, "design": design, "crm": crm, "results": rs})
    lines += ["", END]
    block = "\n".join(lines) + "\n"
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        atomic_write(out / "sb3.md", block)
        atomic_write(out / "benchmarks_sb3.json", json.dumps(data, indent=1) + "\n")
    else:
        atomic_write(ROOT / "docs" / "figures" / "benchmarks_sb3.json", json.dumps(data, indent=1) + "\n")
        write_block(ROOT / "docs" / "benchmarks.md", BEGIN, END, block)
    print(f"done in {minutes:.1f} min", flush=True)


if __name__ == "__main__":
    main()
