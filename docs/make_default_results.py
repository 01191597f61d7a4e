"""Train the thesis's five problems and the four nested-timing specs as `mitlc train --spec FILE`
trains them, at every default, and write their section of docs/results.md.

docs/results.md's other sections reproduce chapter 4 with SACPN (`--learner sacpn`, the trials and
options each problem's row names). This one asks what a user gets who names only the spec and a
seed: the default race of SACPN's designs and the policy search (docs/training.md), 30 runs x
mitlc train's default trials, success by the monitor on each run's final greedy policy from its
evaluation start, as `mitlc train` prints it. Issue 31's bar is a mean of 0.95 over 5 seeds.

    python docs/make_default_results.py --jobs 2      # about 25 minutes on 2 cores
    python docs/make_default_results.py --render      # the section again from docs/figures/defaults.json

Each training runs the command line in a process of its own (`python -m mitlc train --spec FILE
--seed S --out DIR --no-report --no-plots`) and is read back from its metrics.json; finished
trainings are kept under runs/defaults-cache (keyed by the code's digest), so a stopped run resumes.
Writes the block between <!-- defaults:begin --> and <!-- defaults:end --> of docs/results.md and of
README.md, and docs/figures/defaults.json.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "docs"))

from results_stats import code_digest, interval, machine, run_cached  # noqa: E402

from mitlc.fileio import atomic_write, write_block  # noqa: E402

COMMAND = "python docs/make_default_results.py --jobs {jobs}"
SEEDS = (0, 1, 2, 3, 4)
TARGET = 0.95
DATA = ROOT / "docs" / "figures" / "defaults.json"
PAGE = ROOT / "docs" / "results.md"
README = ROOT / "README.md"
BEGIN, END = "<!-- defaults:begin -->", "<!-- defaults:end -->"

SPECS = [  # key, spec under specs/pendulum, what it asks
    ("P1", "p1_swing_up.mitl", "swing up and stay"),
    ("P2", "p2_avoid.mitl", "swing up and stay, never through psi"),
    ("P3", "p3_avoid_speed_limit.mitl", "P2 under a speed limit"),
    ("P4", "p4_alternate.mitl", "alternate between two regions"),
    ("P5", "p5_timed_visit.mitl", "visit kappa in [1, 2] s only"),
    ("N1", "n1_reach_in_time.mitl", "reach within 2 s and stay, two obstacles"),
    ("N2", "n2_hold_up.mitl", "up within 1.5 s, then hold slowly"),
    ("N3", "n3_bounded_response.mitl", "every fast spell ends within 0.5 s"),
    ("N4", "n4_recurring_window.mitl", "F[1,2] under G[0,1]"),
]


def train(job: tuple) -> dict:
    """One `mitlc train --spec FILE --seed S` at the defaults, in a process of its own; its metrics."""
    key, spec_file, seed = job
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [sys.executable, "-m", "mitlc", "train", "--spec", str(ROOT / "specs" / "pendulum" / spec_file)]
        cmd += ["--seed", str(seed), "--out", str(out), "--no-report", "--no-plots"]
        t0 = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp)
        wall = time.perf_counter() - t0
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} exited {done.returncode}: {done.stderr.strip()[-500:]}")
        m = json.loads((out / "metrics.json").read_text(encoding="utf-8"))
    race = m.get("race") or {}
    return {
        "job": f"{key} seed {seed}",
        "key": key,
        "seed": seed,
        "success": float(m["success_rate"]),
        "runs": int(m["runs"]),
        "trials": int(m["trials"]),
        "learner": m.get("learner", "sacpn"),
        "winner": race.get("winner", m.get("learner", "sacpn")),
        "wall_s": round(wall, 1),
    }


def _job_file(job: tuple) -> str:
    digest = hashlib.sha256(repr((job, code_digest(__file__))).encode()).hexdigest()[:12]
    return f"{job[0]}-{job[2]}-{digest}.json"


def _budget(data: dict) -> str:
    """The trials the trainings ran, as their metrics say: SACPN's, and the generations of a search that won."""
    recs = [r for rs in data["specs"].values() for r in rs]
    sacpn = sorted({r["trials"] for r in recs if r["learner"] != "search"})
    search = sorted({r["trials"] for r in recs if r["learner"] == "search"})
    text = " or ".join(map(str, sacpn)) + " trials"
    return text + (f" ({' or '.join(map(str, search))} generations where the search won)" if search else "")


def render(data: dict) -> str:
    """The section of docs/results.md, from the run's data alone."""
    lines = [
        BEGIN,
        "## At the defaults: what `mitlc train --spec FILE` gives",
        "",
        f"Generated by `{data['command']}` in {data['minutes']:.1f} min ({data['machine']}). Each spec of "
        "`specs/pendulum/` trained as `mitlc train --spec FILE --seed S` trains it with nothing else given: "
        f"the race of SACPN's designs and the policy search, then the winner on {data['runs']} runs for "
        f"{_budget(data)} (docs/training.md, the race). Success: the runs whose final greedy policy the monitor "
        "accepts from "
        "the run's evaluation start (what `mitlc train` prints), per seed, then the mean over seeds "
        f"{', '.join(map(str, data['seeds']))} with its 95 % interval (Student's t); the target is "
        f"{data['target']:.2f}. **Won by**: the design the race chose, per seed; **s**: a training's wall time, "
        "the race included, mean over seeds.",
        "",
        "| spec | per seed | mean (95 %) | won by | s |",
        "| --- | ---: | ---: | --- | ---: |",
    ]
    missed = []
    for key, spec_file, what in SPECS:
        recs = sorted(data["specs"][key], key=lambda r: r["seed"])
        m, h = interval([r["success"] for r in recs])
        won = Counter(r["winner"] for r in recs)
        each = " / ".join(f"{r['success']:.2f}" for r in recs)
        lines.append(
            f"| {key} `{spec_file}`: {what} | {each} | **{m:.2f} ± {h:.2f}** | "
            f"{', '.join(f'{w} x{n}' for w, n in won.most_common())} | "
            f"{sum(r['wall_s'] for r in recs) / len(recs):.0f} |"
        )
        if m < data["target"]:
            missed.append(f"{key} {m:.2f}")
    lines += [""]
    if missed:
        lines.append(f"Below {data['target']:.2f} at the defaults: {', '.join(missed)}.")
    else:
        lines.append(f"Every spec reaches {data['target']:.2f} at the defaults.")
    lines += ["", END]
    return "\n".join(lines) + "\n"


def readme_line(data: dict) -> str:
    """README.md's block under its suite line: each spec's mean success at the defaults."""
    cells = []
    for key, _, _ in SPECS:
        m, h = interval([r["success"] for r in data["specs"][key]])
        cells.append(f"{key} {m:.2f} ± {h:.2f}")
    return (
        f"{BEGIN}\nThe thesis's five problems and the four nested-timing specs at these defaults, with nothing but "
        f"the spec and a seed given, {len(data['seeds'])} seeds x {data['runs']} runs, mean success and its 95 % "
        f"interval: {', '.join(cells)} (`{data['command']}`; "
        "[docs/results.md](docs/results.md#at-the-defaults-what-mitlc-train---spec-file-gives)).\n"
        f"{END}\n"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=1, help="trainings at once")
    ap.add_argument("--render", action="store_true", help="write the section again from its data")
    args = ap.parse_args()
    if args.render:
        data = json.loads(DATA.read_text(encoding="utf-8"))
    else:
        t0 = time.perf_counter()
        jobs = [(key, f, seed) for key, f, _ in SPECS for seed in SEEDS]
        results, kept = run_cached(train, jobs, args.jobs, ROOT / "runs" / "defaults-cache", _job_file)
        data = {
            "command": COMMAND.format(jobs=args.jobs),
            "minutes": round((time.perf_counter() - t0) / 60, 1),
            "machine": machine("numba"),
            "resumed": kept,
            "seeds": list(SEEDS),
            "runs": results[0]["runs"],
            "target": TARGET,
            "specs": {key: [r for r in results if r["key"] == key] for key, _, _ in SPECS},
        }
        atomic_write(DATA, json.dumps(data, indent=1) + "\n")
    write_block(PAGE, BEGIN, END, render(data))
    write_block(README, BEGIN, END, readme_line(data))


if __name__ == "__main__":
    main()
