"""The numbers of docs/verify.md: falsifiers against uniform sampling, and what a report costs.

    python docs/make_verify_results.py        # about 2 minutes on 2 cores

Writes the section between the ``verify`` markers of docs/verify.md, its data
docs/figures/verify.json and the figure docs/figures/verify_p1_cex.png (the least robust
counterexample of ``mitlc verify --policy p1 --disturb u=1 --pieces 3``).

1. A planted weakness: a PD controller on the mass-damper whose gain falls towards one start
   (tests/test_verify.py's ``Planted``), about 0.15 % of the init box failing ``F[0,2] G home``.
2. A trained policy: problem 1 (8 runs x 300 trials, seed 0, as docs/verify.md trains it)
   under an input disturbance ``|d| <= 1`` constant over each third of the horizon.
3. A policy trained on part of an init box: problem 5 trained from ``q in [-pi/2, 0]`` and
   verified on the spec's ``[-pi/2, pi/2]``.

For each, every falsifier (``cma``, ``de``, ``uniform``) searches from 10 seeds with the same
budget of rollouts, stopping at the first counterexample (no start from a sample): how many
seeds found one, and after how many rollouts (the median of those that did).

For the first two, also what ``mitlc verify``'s defaults find from each seed
(:func:`mitlc.verify.run.verify_policy`: 1000 samples, then ``de`` through 1000 rollouts).

4. ``mitlc verify --samples 1000 --budget 1000`` on the five problems' policies (8 runs each,
   the trials of docs/make_violation_results.py): its wall time, the command as a user runs it.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.fileio import atomic_write, json_text, write_block  # noqa: E402
from mitlc.learn.policy import load_policy  # noqa: E402
from mitlc.spec.parse import load_spec, parse_spec  # noqa: E402
from mitlc.verify import SearchSpace, falsify, parse_disturb, verify_policy  # noqa: E402
from mitlc.verify.rollout import evaluate  # noqa: E402

COMMAND = "python docs/make_verify_results.py"
PAGE = ROOT / "docs" / "verify.md"
FIGURES = ROOT / "docs" / "figures"
DATA = FIGURES / "verify.json"
BEGIN, END = "<!-- verify:begin -->", "<!-- verify:end -->"
METHODS = ("cma", "de", "uniform")
SEEDS = range(10)
FRACTION_SAMPLES = 40000
PROBLEMS = [  # spec, trials
    ("p1_swing_up", 300),
    ("p2_avoid", 500),
    ("p3_avoid_speed_limit", 1000),
    ("p4_alternate", 1500),
    ("p5_timed_visit", 1000),
]

PLANTED_SPEC = parse_spec(
    "plant mass-damper\ninit q in [-1, 1], qdot in [-1, 1]\nhorizon 3\n"
    "prop home = abs(q) < 0.1\nformula F[0, 2] G home\n"
)


class Planted:
    """tests/test_verify.py's planted weakness: PD control whose gain falls within 0.15 of (0.7, 0.6)."""

    runs = 1
    dt = 0.03
    spec = PLANTED_SPEC

    def reset(self, x0: np.ndarray) -> np.ndarray:
        d = np.linalg.norm(x0 - np.array([0.7, 0.6]), axis=1)
        return 1.0 - 0.995 * np.maximum(0.0, 1.0 - d / 0.15)

    def act(self, x: np.ndarray, gain: np.ndarray) -> np.ndarray:
        return -(20.0 * gain) * x[:, 0] - 6.0 * x[:, 1]

    def step(self, gain: np.ndarray, x_next: np.ndarray) -> np.ndarray:
        return gain


def mitlc(*args: str, cwd: Path) -> str:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    res = subprocess.run([sys.executable, "-m", "mitlc", *args], cwd=cwd, env=env, capture_output=True, text=True)
    if res.returncode not in (0, 1):
        raise SystemExit(f"mitlc {' '.join(args)} failed:\n{res.stdout}{res.stderr}")
    return res.stdout


def compare(policy, spec, space: SearchSpace, steps: int, budget: int) -> dict:
    """Each falsifier from each seed, stopping at the first counterexample; and the failing
    fraction of :data:`FRACTION_SAMPLES` uniform scenarios."""

    def objective(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        j = evaluate(policy, spec, space, z, steps)
        return j.robustness, j.satisfied

    z = space.sample(FRACTION_SAMPLES, np.random.default_rng(12345))
    failing = 1 - float(np.mean(np.concatenate([objective(z[a : a + 2000])[1] for a in range(0, len(z), 2000)])))
    out: dict = {"budget": budget, "failing_fraction": failing, "methods": {}}
    for m in METHODS:
        firsts = [falsify(objective, space.dim, budget, m, seed=s).first for s in SEEDS]
        got = [f for f in firsts if f is not None]
        out["methods"][m] = {
            "found": len(got),
            "seeds": len(firsts),
            "median_rollouts": float(np.median(got)) if got else None,
            "first": firsts,
        }
        print(f"  {m:8s} found {len(got)}/{len(firsts)}; rollouts to the first: {firsts}", flush=True)
    return out


def defaults(policy, spec, space: SearchSpace, steps: int) -> dict:
    """What ``mitlc verify`` does by default (1000 samples, then ``de`` from the least robust of them
    through 1000 rollouts) from each seed: how many seeds ended with a counterexample, and how
    many of those the samples alone had found."""
    found = by_samples = 0
    for s in SEEDS:
        o = verify_policy(policy, spec, space, steps, samples=1000, budget=1000, method="de", seed=s)
        found += o.violations > 0
        by_samples += o.sampled.satisfied < o.sampled.samples
    print(f"  mitlc verify's defaults: a counterexample from {found}/{len(SEEDS)} seeds "
          f"({by_samples} by the 1000 samples alone)", flush=True)  # fmt: skip
    return {"found": found, "by_samples": by_samples, "seeds": len(SEEDS)}


def main() -> None:
    started = time.perf_counter()
    results: dict = {"command": COMMAND, "python": platform.python_version(), "numpy": np.__version__}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        print("planted weakness (mass-damper, hand-built PD):", flush=True)
        space = SearchSpace.of(PLANTED_SPEC)
        results["planted"] = {b: compare(Planted(), PLANTED_SPEC, space, 100, b) for b in (200, 500)}
        results["planted_defaults"] = defaults(Planted(), PLANTED_SPEC, space, 100)

        print("problem 1 (8 runs x 300 trials, seed 0) with |d_u| <= 1 over 3 pieces:", flush=True)
        mitlc("train", "--spec", str(ROOT / "specs/pendulum/p1_swing_up.mitl"), "--runs", "8", "--trials", "300",
              "--out", "p1", "-q", "--no-plots", cwd=work)  # fmt: skip
        p1 = load_policy(work / "p1")
        space = SearchSpace.of(p1.spec, (), parse_disturb(["u=1"], p1.spec), pieces=3, runs=p1.runs)
        results["p1_disturbed"] = compare(p1, p1.spec, space, 100, 200)
        results["p1_defaults"] = defaults(p1, p1.spec, space, 100)
        mitlc("verify", "--policy", "p1", "--disturb", "u=1", "--pieces", "3", "--out", "p1d", cwd=work)
        atomic_write(FIGURES / "verify_p1_cex.png", (work / "p1d" / "cex_000.png").read_bytes())

        print("problem 5 trained from q in [-pi/2, 0], verified on [-pi/2, pi/2]:", flush=True)
        text = (ROOT / "specs/pendulum/p5_timed_visit.mitl").read_text()
        (work / "p5_half.mitl").write_text(text.replace("init q in [-pi/2, pi/2]", "init q in [-pi/2, 0]"))
        mitlc("train", "--spec", "p5_half.mitl", "--runs", "8", "--trials", "1000", "--out", "p5h", "-q", "--no-plots",
              cwd=work)  # fmt: skip
        p5 = load_policy(work / "p5h")
        full = load_spec(ROOT / "specs/pendulum/p5_timed_visit.mitl")
        space = SearchSpace.of(full, runs=p5.runs)
        results["p5_half_box"] = compare(p5, full, space, 100, 200)

        print("mitlc verify --samples 1000 --budget 1000 on the five problems (8 runs each):", flush=True)
        timing = {}
        for name, trials in PROBLEMS:
            mitlc("train", "--spec", str(ROOT / f"specs/pendulum/{name}.mitl"), "--runs", "8", "--trials", str(trials),
                  "--out", name, "-q", "--no-plots", cwd=work)  # fmt: skip
            t0 = time.perf_counter()
            out = mitlc("verify", "--policy", name, "--samples", "1000", "--budget", "1000", cwd=work)
            wall = time.perf_counter() - t0
            first = out.splitlines()[0]
            timing[name] = {"seconds": round(wall, 2), "sampled": first.split(" rollouts")[0].split(": ")[1]}
            print(f"  {name}: {wall:.1f} s; {first}", flush=True)
        results["timing"] = timing
    results["seconds"] = round(time.perf_counter() - started, 1)
    atomic_write(DATA, json_text(results, indent=1))
    write_block(PAGE, BEGIN, END, block(results))
    print(f"wrote {DATA.relative_to(ROOT)} and the block of {PAGE.relative_to(ROOT)} in {results['seconds']} s")


def block(r: dict) -> str:
    def row(label: str, c: dict) -> str:
        cells = []
        for m in METHODS:
            v = c["methods"][m]
            med = "" if v["median_rollouts"] is None else f" (median {v['median_rollouts']:g})"
            cells.append(f"{v['found']}/{v['seeds']}{med}")
        return f"| {label} | {c['failing_fraction']:.2%} | {c['budget']} | " + " | ".join(cells) + " |"

    def d(x: dict) -> str:
        return f"{x['found']} seeds of {x['seeds']} ({x['by_samples']} by the samples alone)"

    lines = [
        BEGIN,
        "| case | failing fraction | budget | cma | de | uniform |",
        "| --- | --- | --- | --- | --- | --- |",
        row("planted weakness (mass-damper)", r["planted"][200]),
        row("planted weakness (mass-damper)", r["planted"][500]),
        row("problem 1, disturbance 1 over 3 pieces", r["p1_disturbed"]),
        row("problem 5 trained on half its box", r["p5_half_box"]),
        "",
        "Seeds (of 10) whose search found a counterexample within the budget, and the median number of "
        "rollouts it took; the failing fraction is that of "
        f"{FRACTION_SAMPLES:,} uniform scenarios. With `mitlc verify`'s defaults (1000 samples, then `de` "
        "from the least robust sample through 1000 rollouts) a verification ended with a counterexample "
        f"from {d(r['planted_defaults'])} on the planted weakness and {d(r['p1_defaults'])} on the "
        "disturbed problem 1.",
        "",
        "| problem | `mitlc verify --samples 1000 --budget 1000` | satisfied samples |",
        "| --- | --- | --- |",
        *(f"| {n} | {t['seconds']:.1f} s | {t['sampled']} |" for n, t in r["timing"].items()),
        "",
        f"`{COMMAND}` ({r['seconds']:.0f} s, Python {r['python']}, numpy {r['numpy']}; the data: "
        "[figures/verify.json](figures/verify.json)).",
        END,
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
