"""Stable-Baselines3 SAC on Gymnasium's Pendulum-v1, with and without counterfactual markings, and on the cart.

The compiled reward of a thesis spec pays SAC through :class:`mitlc.gym.MitlRewardWrapper`
(``marking_obs="box"``: Pendulum's observation and the marking); with ``--crm`` rows the replay
buffer is :class:`mitlc.gym.crm.CounterfactualReplayBuffer`. The cart with the small goal
(examples/cart/) runs as :class:`mitlc.gym.MitlPlantEnv`, the plant as an environment paying
the compiled reward. After the row's environment steps (``--steps`` for the pendulum) the
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
import hashlib  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from results_stats import code_digest, interval, machine, run_cached  # noqa: E402  (docs/, the script's own folder)

from mitlc.fileio import atomic_write, write_block  # noqa: E402

BEGIN, END = "<!-- sb3:begin -->", "<!-- sb3:end -->"
CART_PLANT = "examples/cart/cart_plant.py"
CART_STEPS = 15_000  # the cart's trainings, whatever --steps says (it sizes the pendulum's)
# key, spec, reward design, counterfactual markings, plant file (None: Pendulum-v1 through the wrapper)
ROWS = [
    ("P1", "specs/pendulum/p1_swing_up.mitl", "net", False, None),
    ("P1", "specs/pendulum/p1_swing_up.mitl", "shaped", False, None),
    ("P4", "specs/pendulum/p4_alternate.mitl", "net", False, None),
    ("P4", "specs/pendulum/p4_alternate.mitl", "net", True, None),
    ("cart", "examples/cart/cart_small_goal.mitl", "net", False, CART_PLANT),
    ("cart", "examples/cart/cart_small_goal.mitl", "shaped", False, CART_PLANT),
]


def train(job: tuple) -> dict:
    key, spec_file, design, crm, plant_file, seed, steps, episodes = job
    import gymnasium as gym
    import torch
    from stable_baselines3 import SAC

    from mitlc.gym import MitlPlantEnv, MitlRewardWrapper, pendulum_v1_state
    from mitlc.monitor.offline import monitor
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.plants.user import load_plants
    from mitlc.spec.parse import load_spec

    torch.set_num_threads(1)
    if plant_file is not None:
        load_plants(str(ROOT / plant_file))
    spec = load_spec(ROOT / spec_file)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, reward=design))

    def make(verdict: str) -> gym.Env:
        if plant_file is not None:  # the monitor judges the plant's states, the observation's first entries
            return MitlPlantEnv(rs, plant=spec.plant_name, marking_obs="box")
        return MitlRewardWrapper(
            gym.make("Pendulum-v1"), rs, pendulum_v1_state, marking_obs="box", verdict=verdict, truncate_at_horizon=True
        )

    env = make("off")
    kwargs: dict = {}
    if crm:
        from mitlc.gym.crm import CounterfactualReplayBuffer

        kwargs = {"replay_buffer_class": CounterfactualReplayBuffer, "replay_buffer_kwargs": {"wrapper": env}}
    model = SAC("MlpPolicy", env, seed=seed, device="cpu", verbose=0, **kwargs)
    start = time.perf_counter()
    model.learn(steps)
    wall = time.perf_counter() - start
    test = make("end")
    wins, effort, chatter = [], [], []
    n_state = len(spec.plant.state) if spec.plant is not None else 0
    for e in range(episodes):
        obs, _ = test.reset(seed=10_000 * (seed + 1) + e)
        us, xs = [], [np.asarray(obs, dtype=float)[:n_state]]
        while True:
            a, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = test.step(a)
            us.append(float(np.asarray(a).reshape(-1)[0]))  # the input: Pendulum-v1's torque, the cart's force
            xs.append(np.asarray(obs, dtype=float)[:n_state])
            if terminated or truncated:
                break
        if plant_file is not None:
            wins.append(bool(monitor(spec, np.array(xs), test.dt).satisfied[0]))
        else:
            wins.append(bool(info["verdict"]["satisfied"]))
        u = np.array(us)
        effort.append(float(np.abs(u).mean()))
        chatter.append(float(np.abs(np.diff(u)).sum() / (len(u) * test.dt)))
    added = int(getattr(model.replay_buffer, "added", 0))
    return {
        "job": [key, design, crm, seed],
        "steps": steps,
        "success": float(np.mean(wins)),
        "effort": float(np.mean(effort)),
        "chatter": float(np.mean(chatter)),
        "wall_s": wall,
        "counterfactual_per_step": added / steps,
    }


def _job_file(job: tuple) -> str:
    """A cached training's file name: the job and a digest of the code that trains it."""
    import mitlc

    digest = hashlib.sha256(repr((job, mitlc.__version__, code_digest(__file__))).encode()).hexdigest()[:12]
    key, _, design, crm, _, seed, steps, episodes = job
    return f"{key}-{design}-{'crm' if crm else 'plain'}-s{seed}-n{steps}-e{episodes}-{digest}.json"


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
    jobs = [
        (k, f, d, c, pf, s, steps if pf is None or args.quick else CART_STEPS, episodes)
        for k, f, d, c, pf in ROWS
        for s in range(seeds)
    ]
    # each finished training is kept (runs/sb3-cache, keyed by the job and a digest of the code), so a
    # run that stops is resumed by running the same command again
    cache = None if args.quick else ROOT / "runs" / "sb3-cache"
    results, kept = run_cached(train, jobs, args.jobs, cache, _job_file)
    minutes = (time.perf_counter() - t0) / 60
    import stable_baselines3
    import torch

    cart_steps = steps if args.quick else CART_STEPS
    lines = [
        BEGIN,
        "## Stable-Baselines3 SAC on Gymnasium's Pendulum-v1 and on the cart",
        "",
        f"Generated by `{command}` in {minutes:.1f} min{' (resumed from its cache)' if kept else ''} "
        f"({machine('numba')}, torch {torch.__version__}, stable-baselines3 {stable_baselines3.__version__}). "
        f"SAC with Stable-Baselines3's defaults for {steps} environment steps on Pendulum-v1 ({cart_steps} on the "
        "cart), paid by the spec's compiled reward with the row's design: Pendulum-v1 through `MitlRewardWrapper` "
        '(`marking_obs="box"`), the cart of examples/cart/ as `MitlPlantEnv`; **CRM**: with '
        "`mitlc.gym.crm.CounterfactualReplayBuffer`. Success: the fraction of "
        f"{episodes} deterministic test episodes (seeded resets) that the monitor accepts, mean and 95 % "
        f"interval over {seeds} seeds. Pendulum-v1's torque limit is 2 N m, not the thesis pendulum's.",
        "",
        "| spec | reward | CRM | steps | success | per seed | abs(u) | TV/s | counterfactual / step | wall s |",
        "| --- | --- | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: |",
    ]
    data = {"command": command, "minutes": round(minutes, 1), "steps": steps, "seeds": seeds, "rows": []}
    for key, spec_file, design, crm, _plant in ROWS:
        rs = [r for r in results if r["job"][:3] == [key, design, crm]]
        succ = [r["success"] for r in rs]
        m, h = interval(succ)
        cell = f"{m:.2f}" if not np.isfinite(h) else f"{m:.2f} ± {h:.2f}"
        lines.append(
            f"| {key} | `{design}` | {'yes' if crm else 'no'} | {rs[0]['steps']} | **{cell}** | "
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
