"""Violation-aware rewards (docs/semantics.md section 6) against the thesis's reward.

    python docs/make_violation_results.py --jobs 1     # about 15 minutes (--jobs 2: about 8)

Writes the section between the ``violations`` markers of docs/results.md
(docs/make_results.py keeps it when it rewrites the page), its data
docs/figures/violations.json and the figures docs/figures/violations_<problem>.png.

1. Problems 2 and 3 with equal weights (specs/pendulum/unit_weights/): 30
   runs for each of four seeds, ``--violations off`` against ``permanent``;
   success by the monitor, how the failures fail, learning curves.
2. The five shipped specs, ``off`` against ``permanent``, same seeds.
3. Why the learner does what it does under the penalty: the two choices of
   SACPN for violation penalties (``violation_value``, ``penalty_ramp``)
   switched off one at a time on the equal-weight problems, two seeds.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.fileio import atomic_write, write_block  # noqa: E402
from mitlc.learn.sacpn import Sacpn, SacpnSettings  # noqa: E402
from mitlc.monitor.offline import monitor  # noqa: E402
from mitlc.petri.compile import CompileOptions, compile_spec  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402

COMMAND = "python docs/make_violation_results.py --jobs {jobs}"
RUNS, SEEDS, ABLATION_SEEDS = 30, (0, 1, 2, 3), (0, 1)
FIGURES = ROOT / "docs" / "figures"
BEGIN, END = "<!-- violations:begin -->", "<!-- violations:end -->"

UNIT = [  # key, spec, trials
    ("P2 (4-15)", "unit_weights/p2_avoid.mitl", 2000),
    ("P3, equal weights", "unit_weights/p3_avoid_speed_limit.mitl", 2000),
]
SHIPPED = [
    ("P1", "p1_swing_up.mitl", 500),
    ("P2", "p2_avoid.mitl", 500),
    ("P3", "p3_avoid_speed_limit.mitl", 1000),
    ("P4", "p4_alternate.mitl", 1500),
    ("P5", "p5_timed_visit.mitl", 1000),
]
ABLATIONS = [  # label, settings overrides
    ("known value, ramp 0.75 (default)", {}),
    ("known value, no ramp", {"penalty_ramp": 0.0}),
    ("learned value, ramp 0.75", {"violation_value": "learned"}),
    ("learned value, no ramp (the previous design)", {"violation_value": "learned", "penalty_ramp": 0.0}),
]


def train(job: tuple) -> dict:
    spec_file, trials, seed, violations, overrides = job
    spec = load_spec(ROOT / "specs" / "pendulum" / spec_file)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))
    agent = Sacpn(rs, SacpnSettings(**overrides), runs=RUNS, seed=seed)
    start = time.perf_counter()
    agent.train(trials)
    wall = time.perf_counter() - start
    ro = agent.rollout(agent.evaluation_states())
    res = monitor(spec, ro.states, ro.dt)
    return {
        "job": [spec_file, trials, seed, violations, overrides],
        "returns": agent.returns,
        "success": float(res.satisfied.mean()),
        "wall_s": wall,
        "failing": dict(Counter(f for f in res.failing if f)),
        "penalty": rs.penalty,
    }


def fmt_fail(results: list[dict]) -> str:
    c: Counter = Counter()
    for r in results:
        c.update(r["failing"])
    return ", ".join(f"{n} x `{f}`" for f, n in c.most_common()) or "none"


def rate(results: list[dict]) -> tuple[float, float]:
    """Success over all runs of all seeds, and its binomial standard error."""
    p = float(np.mean([r["success"] for r in results]))
    return p, math.sqrt(max(p * (1 - p), 1e-12) / (RUNS * len(results)))


def per_seed(results: list[dict]) -> str:
    return " / ".join(f"{r['success']:.2f}" for r in results)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=1, help="parallel training processes")
    args = ap.parse_args()
    t0 = time.perf_counter()
    jobs: list[tuple] = []
    for _, spec_file, trials in UNIT + SHIPPED:
        for mode in ("off", "permanent"):
            jobs += [(spec_file, trials, seed, mode, {}) for seed in SEEDS]
    for _, spec_file, trials in UNIT:
        for _, overrides in ABLATIONS[1:]:
            jobs += [(spec_file, trials, seed, "permanent", overrides) for seed in ABLATION_SEEDS]
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        results = []
        for r in pool.map(train, jobs):
            print(f"{r['job']}: success {r['success']:.2f} ({r['wall_s']:.0f} s)", flush=True)
            results.append(r)

    def pick(spec_file: str, mode: str, overrides: dict | None = None, seeds=SEEDS) -> list[dict]:
        return [
            r
            for s in seeds
            for r in results
            if r["job"][0] == spec_file
            and r["job"][2] == s
            and r["job"][3] == mode
            and r["job"][4] == (overrides or {})
        ]

    from mitlc.learn.plots import learning_curve, png_bytes

    seeds_text = ", ".join(str(s) for s in SEEDS)
    lines = [
        BEGIN,
        "## Violation-aware rewards (`--violations permanent`)",
        "",
        f"Generated by `{COMMAND.format(jobs=args.jobs)}` (it took {{minutes}} min). {RUNS} runs for each of the seeds "
        f"{seeds_text}, default settings; success by the monitor on each run's final greedy rollout "
        "(per seed, and over all runs with its binomial standard error). `permanent` adds an absorbing "
        "violated place per watched part and subtracts c = r_max - r_floor + 1 from every step from the "
        "first violation on, so that every such step earns less than any step without a violation "
        "(docs/semantics.md, section 6). SACPN learns under it with two choices of its own "
        "([training.md](training.md#violation-penalties)): the critic is given the penalty's exact "
        "share of the value, and the penalty ramps in over the first 3/4 of the trials.",
        "",
        "| problem | trials | violations | success per seed | success (all runs) | c | failures "
        "(all seeds) | wall s per seed |",
        "| --- | ---: | --- | ---: | ---: | ---: | --- | ---: |",
    ]
    data: dict = {
        "command": COMMAND.format(jobs=args.jobs),
        "runs": RUNS,
        "seeds": list(SEEDS),
        "unit": {},
        "shipped": {},
        "ablation": {},
    }
    for key, spec_file, trials in UNIT:
        fig = None
        data["unit"][key] = {}
        for mode, color in (("off", "C3"), ("permanent", "C2")):
            rs = pick(spec_file, mode)
            p, se = rate(rs)
            data["unit"][key][mode] = {"success": [r["success"] for r in rs], "failing": fmt_fail(rs)}
            fig = learning_curve(
                np.concatenate([r["returns"] for r in rs]),
                title=f"{key}: {RUNS} runs x {len(SEEDS)} seeds",
                label=f"violations {mode}",
                fig=fig,
                color=color,
            )
            lines.append(
                f"| {key} (`{spec_file}`) | {trials} | {mode} | {per_seed(rs)} | {p:.2f} ± {se:.2f} | "
                f"{rs[0]['penalty']:g} | {fmt_fail(rs)} | {np.mean([r['wall_s'] for r in rs]):.0f} |"
            )
        name = spec_file.split("/")[-1].split("_")[0]
        atomic_write(FIGURES / f"violations_{name}.png", png_bytes(fig))
    lines += [
        "",
        f"Learning curves (mean return per trial over all {RUNS * len(SEEDS)} runs, 10-90 % band; the "
        "returns of `permanent` are those of its full reward, penalties included, also while the "
        "learner's penalty ramps in, so the two curves are on different scales):",
        "",
        "![P2 equal weights](figures/violations_p2.png)",
        "![P3 equal weights](figures/violations_p3.png)",
        "",
        "The shipped specs (their weights as in the thesis), the same seeds:",
        "",
        "| problem | trials | success off (per seed) | success permanent (per seed) | off, all runs "
        "| permanent, all runs | difference | c |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    losses, lower = [], []
    for key, spec_file, trials in SHIPPED:
        off, perm = pick(spec_file, "off"), pick(spec_file, "permanent")
        (po, so), (pp, sp) = rate(off), rate(perm)
        diff, se = pp - po, math.hypot(so, sp)
        if diff < -2 * se:
            losses.append(key)
        if diff < 0:
            lost = round(-diff * RUNS * len(SEEDS))
            lower.append(f"{key} ({lost} of {RUNS * len(SEEDS)} runs, {fmt_fail(perm)})")
        data["shipped"][key] = {"off": [r["success"] for r in off], "permanent": [r["success"] for r in perm]}
        lines.append(
            f"| {key} | {trials} | {per_seed(off)} | {per_seed(perm)} | {po:.2f} | {pp:.2f} | "
            f"{diff:+.3f} ± {se:.3f} | {perm[0]['penalty']:g} |"
        )
    lines += [
        "",
        (
            "No shipped problem loses success with the option on by more than two standard errors."
            if not losses
            else f"With the option on, {', '.join(losses)} lose(s) success by more than two standard errors."
        )
        + (
            f" Fewer runs succeed with the option on in: {'; '.join(lower)}."
            if lower
            else " No shipped problem has fewer successful runs with the option on."
        ),
        "",
        f"What the learner's two choices do, on the equal-weight problems ({RUNS} runs, seeds "
        f"{', '.join(str(s) for s in ABLATION_SEEDS)}, `--violations permanent`):",
        "",
        "| learner | " + " | ".join(f"{k} success per seed" for k, _, _ in UNIT) + " |",
        "| --- | " + " | ".join("---:" for _ in UNIT) + " |",
    ]
    for label, overrides in ABLATIONS:
        row = []
        for key, spec_file, _ in UNIT:
            rs = pick(spec_file, "permanent", overrides, ABLATION_SEEDS)
            data["ablation"].setdefault(label, {})[key] = [r["success"] for r in rs]
            row.append(per_seed(rs))
        lines.append(f"| {label} | " + " | ".join(row) + " |")
    lines += ["", END]
    minutes = (time.perf_counter() - t0) / 60
    data["minutes"] = round(minutes, 1)
    block = "\n".join(lines).replace("{minutes}", f"{minutes:.1f}") + "\n"
    atomic_write(FIGURES / "violations.json", json.dumps(data, indent=1) + "\n")
    write_block(ROOT / "docs" / "results.md", BEGIN, END, block)


if __name__ == "__main__":
    main()
