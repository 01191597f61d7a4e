"""Reward designs measured against what the field uses: writes docs/benchmarks.md.

For each task and each reward design (``option reward``: the compiled net, shaped and graded
propositions, and the field's sparse, robustness and robustness-window rewards generated from the
same spec), SACPN trains ``--runs`` runs for each of ``--seeds`` seeds with the default settings.
Every ``trials / 10`` trials the greedy policies are rolled out from a fixed set of initial states
and judged by the monitor, which gives the learning curve and the trials to reach 0.8 success;
the final rollouts give the success rate (mean and 95 % interval over the seeds), the control
effort (mean |u|) and the chattering (the input's total variation per second).

    python docs/make_benchmarks.py --jobs 2            # the page: about an hour on 2 cores
    python docs/make_benchmarks.py --quick --out DIR   # seconds: what the test suite runs

Writes docs/benchmarks.md, docs/figures/benchmarks.png, docs/figures/benchmarks.json and the table
between ``<!-- benchmarks:begin -->`` and ``<!-- benchmarks:end -->`` in README.md (with ``--out``,
the first three in DIR instead, README untouched); ``--render JSON`` writes them again from a
run's data file without training. The cart's section quotes docs/figures/benchmarks_sb3.json, which
``python docs/make_sb3_benchmarks.py`` writes: run that one first.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

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

DESIGNS = ("net", "shaped", "graded", "sparse", "robustness", "robustness-window")
CART_PLANT = "examples/cart/cart_plant.py"
# key, spec (relative to the repository), plant file or None, trials, what it is
TASKS = [
    ("P1", "specs/pendulum/p1_swing_up.mitl", None, 500, "swing up and stay up"),
    ("P2", "specs/pendulum/p2_avoid.mitl", None, 500, "swing up, never through psi"),
    ("P3", "specs/pendulum/p3_avoid_speed_limit.mitl", None, 1000, "P2 and a speed limit"),
    ("P4", "specs/pendulum/p4_alternate.mitl", None, 1500, "alternate between two targets"),
    ("P5", "specs/pendulum/p5_timed_visit.mitl", None, 1000, "visit kappa in [1, 2] s only"),
    ("N3", "specs/pendulum/n3_bounded_response.mitl", None, 500, "every fast spell ends within 0.5 s, then up"),
    ("N2", "specs/pendulum/n2_hold_up.mitl", None, 500, "up within 1.5 s, then hold slowly"),
    ("cart", "examples/cart/cart_small_goal.mitl", CART_PLANT, 1500, "a small goal: abs(x - 1) < 0.2, abs(v) < 0.3"),
]
QUICK_TASKS = [
    ("P1", "specs/pendulum/p1_swing_up.mitl", None, 20, "swing up"),
    ("cart", "examples/cart/cart_small_goal.mitl", CART_PLANT, 20, "small goal"),
]
EVALS = 10  # learning-curve points per training
README_BEGIN, README_END = "<!-- benchmarks:begin -->", "<!-- benchmarks:end -->"
SB3_BEGIN, SB3_END = "<!-- sb3:begin -->", "<!-- sb3:end -->"  # docs/make_sb3_benchmarks.py's section, kept
TARGET = 0.8


def train(job: tuple) -> dict:
    """One training of ``runs`` runs: its learning curve and final greedy rollouts by the monitor."""
    key, spec_file, plant_file, trials, design, seed, runs = job
    from mitlc.errors import TrainingError
    from mitlc.learn.sacpn import Sacpn, SacpnSettings
    from mitlc.monitor.offline import monitor
    from mitlc.monitor.rewards import pay
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.plants.user import load_plants
    from mitlc.spec.parse import load_spec

    if plant_file is not None:
        load_plants(str(ROOT / plant_file))
    spec = load_spec(ROOT / spec_file)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, reward=design))
    agent = pay(Sacpn(rs, SacpnSettings(), runs=runs, seed=seed))
    # the learning curve's rollouts start from states of their own, the same at every point
    x0 = agent.sample_init([np.random.default_rng([seed, 7, r]) for r in range(runs)])
    curve, at = [], []
    start = time.perf_counter()
    step = max(1, trials // EVALS)
    done = 0
    error = None
    while done < trials:
        n = min(step, trials - done)
        try:
            agent.train(n, total=trials)
        except TrainingError as exc:  # every run diverged: a result too (nothing succeeds)
            error = str(exc)
            break
        done += n
        ro = agent.rollout(x0.copy())
        curve.append(float(monitor(spec, ro.states, ro.dt).satisfied.mean()))
        at.append(done)
    wall = time.perf_counter() - start
    if error is not None:
        at += list(range(done + step, trials + 1, step))[: EVALS - len(at)] or [trials]
        curve += [0.0] * (len(at) - len(curve))
        return {
            "job": [key, design, seed],
            "success": 0.0,
            "curve": curve,
            "at": at,
            "reach": None,
            "effort": float("nan"),
            "chatter": float("nan"),
            "wall_s": wall,
            "kernel": agent.kernel,
            "error": error,
        }
    ro = agent.rollout(agent.evaluation_states())
    res = monitor(spec, ro.states, ro.dt)
    u = ro.actions
    tv = np.abs(np.diff(u, axis=1)).sum(axis=1) / (u.shape[1] * ro.dt)
    reach = next((t for t, s in zip(at, curve, strict=True) if s >= TARGET), None)
    return {
        "error": None,
        "job": [key, design, seed],
        "success": float(res.satisfied.mean()),
        "curve": curve,
        "at": at,
        "reach": reach,
        "effort": float(np.abs(u).mean()),
        "chatter": float(tv.mean()),
        "wall_s": wall,
        "kernel": agent.kernel,
    }


def _job_file(job: tuple) -> str:
    """A cached training's file name: the job and a digest of the code that trains it."""
    import mitlc

    key, _, _, trials, design, seed, runs = job
    digest = hashlib.sha256(repr((job, mitlc.__version__, code_digest(__file__))).encode()).hexdigest()[:12]
    return f"{key}-{design}-s{seed}-r{runs}-t{trials}-{digest}.json"


def what_of(key: str) -> str:
    """A task's words (for a data file written before they were kept in it)."""
    return next((w for k, *_, w in TASKS if k == key), "")


def _fmt_interval(values: list[float]) -> str:
    m, h = interval(values)
    return f"{m:.2f}" if not np.isfinite(h) else f"{m:.2f} ± {h:.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=1, help="parallel training processes")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--quick", action="store_true", help="two tasks, 2 seeds x 3 runs, 20 trials: a smoke run")
    ap.add_argument("--out", default=None, help="write the page, figure and data here instead of docs/")
    ap.add_argument(
        "--render", default=None, metavar="JSON", help="write the page, figure and README table from a run's data"
    )
    args = ap.parse_args()
    out = Path(args.out) if args.out else ROOT / "docs"
    figures = out / "figures" if args.out is None else out
    if args.render is not None:
        data = json.loads(Path(args.render).read_text(encoding="utf-8"))
        render(data, out, figures, readme=args.out is None and not data.get("quick"))
        return
    tasks = QUICK_TASKS if args.quick else TASKS
    seeds = 2 if args.quick else args.seeds
    runs = 3 if args.quick else args.runs
    command = "python docs/make_benchmarks.py" + (" --quick" if args.quick else f" --jobs {args.jobs}")
    if not args.quick and (args.seeds, args.runs) != (5, 30):
        command += f" --seeds {args.seeds} --runs {args.runs}"
    t0 = time.perf_counter()
    jobs = [(k, f, p, t, d, s, runs) for k, f, p, t, _ in tasks for d in DESIGNS for s in range(seeds)]
    # each finished training is kept (runs/benchmarks-cache, keyed by the job and the code's version),
    # so a run that stops is resumed by running the same command again
    cache = None if args.quick else ROOT / "runs" / "benchmarks-cache"
    results, kept = run_cached(train, jobs, args.jobs, cache, _job_file)
    minutes = (time.perf_counter() - t0) / 60
    data: dict = {
        "command": command,
        "minutes": round(minutes, 1),
        "machine": machine("numba"),
        "resumed": kept,
        "quick": args.quick,
        "runs": runs,
        "seeds": seeds,
        "tasks": {},
    }
    for key, spec_file, _, trials, what in tasks:
        entry = {}
        for design in DESIGNS:
            rs = [r for r in results if r["job"][0] == key and r["job"][1] == design]
            entry[design] = {
                k: [r[k] for r in rs] for k in ("success", "curve", "at", "reach", "effort", "chatter", "wall_s")
            }
        data["tasks"][key] = {"spec": spec_file, "trials": trials, "what": what, "designs": entry}
    render(data, out, figures, readme=args.out is None and not args.quick)
    print(f"wrote {out / 'benchmarks.md'} in {minutes:.1f} min", flush=True)


def render(data: dict, out: Path, figures: Path, readme: bool) -> None:
    """The page, the figure, the data file and (for the docs) README's table, from a run's data."""
    runs, seeds = data["runs"], data["seeds"]
    out.mkdir(parents=True, exist_ok=True)
    figures.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Benchmarks: reward designs against what the field uses",
        "",
        f"Generated by `{data['command']}` in {data['minutes']:.1f} min "
        f"({data.get('machine') or machine('numba')}). Do not edit by hand; rerun it.",
        "",
        f"Every cell: SACPN with default settings, {runs} runs for each of {seeds} seeds, the spec as shipped "
        "with `option reward` set to the design (docs/semantics.md, section 5: `net` is Table 4-2's compiled "
        "reward; `shaped` and `graded` grade its propositions; `sparse`, `robustness` and `robustness-window` "
        "are the field's rewards, paid by the monitor). **Success**: the fraction of runs whose final greedy "
        "rollout (from the run's own evaluation start) satisfies the spec by the monitor, as the mean over the "
        "seeds and its 95 % interval (Student's t). **Trials to 0.8**: the first of the "
        f"{EVALS} evaluation points (every tenth of the training, greedy rollouts from fixed starts) at which "
        "0.8 of the runs succeed, median over the seeds that get there (their number in brackets). "
        "**abs(u)**: the greedy policies' mean input size; **TV/s**: the input's total variation per second "
        "(chattering), means over runs and seeds.",
        "",
        "| task | trials | design | success | per seed | trials to 0.8 | abs(u) | TV/s | wall s |",
        "| --- | ---: | --- | ---: | --- | ---: | ---: | ---: | ---: |",
    ]
    summary = []
    for key, task in data["tasks"].items():
        what = (task.get("what") or what_of(key)).replace("|", "\\|")  # a table cell
        means = {}
        for design in DESIGNS:
            d = task["designs"][design]
            succ = d["success"]
            reach = [r for r in d["reach"] if r is not None]
            means[design] = float(np.mean(succ))
            reach_text = f"{int(np.median(reach))} ({len(reach)})" if reach else f"- (0 of {len(succ)})"
            lines.append(
                f"| {key}: {what} | {task['trials']} | `{design}` | **{_fmt_interval(succ)}** | "
                f"{' / '.join(f'{s:.2f}' for s in succ)} | {reach_text} | "
                f"{np.nanmean(d['effort']):.2f} | {np.nanmean(d['chatter']):.1f} | {np.mean(d['wall_s']):.0f} |"
            )
        best = max(DESIGNS, key=lambda d: means[d])
        field = max(DESIGNS[3:], key=lambda d: means[d])
        ours = max(DESIGNS[:3], key=lambda d: means[d])
        verdict = (
            "ties" if abs(means[ours] - means[field]) < 0.05 else ("wins" if means[ours] > means[field] else "loses")
        )
        summary.append(
            f"- {key}: best `{best}` ({means[best]:.2f}); mitlc's best (`{ours}`, {means[ours]:.2f}) {verdict} "
            f"against the field's best (`{field}`, {means[field]:.2f}); `net` {means['net']:.2f}, "
            f"`shaped` {means['shaped']:.2f}."
        )
    lines += ["", "## What the numbers say", "", *summary, ""]
    cart = data["tasks"].get("cart")
    if cart is not None and max(float(np.mean(d["success"])) for d in cart["designs"].values()) < TARGET:
        lines += _cart_section(cart["spec"])
    page = out / "benchmarks.md"
    old = page.read_text(encoding="utf-8") if page.is_file() else ""
    sb3 = old[old.index(SB3_BEGIN) : old.index(SB3_END) + len(SB3_END)] if SB3_BEGIN in old and SB3_END in old else ""
    lines += [
        'A design "loses" where its mean success is more than 0.05 below the other\'s.',
        "",
        sb3
        or f"{SB3_BEGIN}\nStable-Baselines3 SAC on a Gymnasium environment, with and without counterfactual "
        "markings: `python docs/make_sb3_benchmarks.py` writes this section.\n"
        + SB3_END,
        "",
        "![success against trials](figures/benchmarks.png)" if figures != out else "![](benchmarks.png)",
        "",
    ]
    _figure(list(data["tasks"]), data, figures / "benchmarks.png")
    atomic_write(figures / "benchmarks.json", json.dumps(data, indent=1) + "\n")
    atomic_write(out / "benchmarks.md", "\n".join(lines))
    if readme:
        _readme(data)


# Fixed controllers of the cart (x, v: position and velocity; the force is bounded by 2 N).
CART_CONTROLLERS = [
    ("brake at the goal: u = -4 (x - 1) - 4 v", lambda x: -4.0 * (x[:, 0] - 1.0) - 4.0 * x[:, 1]),
    ("stand still: u = 0", lambda x: np.zeros(len(x))),
    ("full force left: u = -2", lambda x: np.full(len(x), -2.0)),
    ("full force right, into the stop: u = 2", lambda x: np.full(len(x), 2.0)),
]


def _cart_section(spec_file: str) -> list[str]:
    """What the compiled rewards pay fixed controllers of the cart, and whether the monitor accepts them."""
    from mitlc.learn.sacpn import Sacpn
    from mitlc.monitor.offline import monitor
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.plants.user import load_plants
    from mitlc.spec.parse import load_spec

    load_plants(str(ROOT / CART_PLANT))
    spec = load_spec(ROOT / spec_file)
    gamma = 0.0

    class Fixed(Sacpn):
        """SACPN's rollout with a fixed control law in place of the learned policy."""

        law = staticmethod(lambda x: np.zeros(len(x)))

        def policy(self, x, code, xi=None):  # type: ignore[override]
            return np.clip(self.law(x), -self.u_max, self.u_max)

    table = {}
    for design in ("net", "shaped"):
        rs = compile_spec(spec, CompileOptions.from_spec(spec, reward=design))
        for name, law in CART_CONTROLLERS:
            agent = Fixed(rs, runs=10, seed=0)
            agent.law = law
            gamma = agent.gamma  # SACPN's, from the trial's length
            ro = agent.rollout(agent.evaluation_states())
            disc = (ro.rewards * gamma ** np.arange(ro.rewards.shape[1])).sum(axis=1).mean()
            ok = monitor(spec, ro.states, ro.dt).satisfied.mean()
            table[name, design] = (float(disc), float(ro.rewards.sum(axis=1).mean()), float(ok))
    lines = [
        "## The cart: what its rewards pay",
        "",
        "No design gets SACPN to the cart's small goal. The rewards are not what stops it: "
        "fixed controllers from the same 10 starts, their return from the start discounted by SACPN's "
        f"gamma = {gamma} and undiscounted, under `net` and `shaped`, and the monitor's verdict:",
        "",
        "| controller | `net` discounted | `net` total | `shaped` discounted | `shaped` total | satisfies |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name, _ in CART_CONTROLLERS:
        n, sh = table[name, "net"], table[name, "shaped"]
        lines.append(f"| {name} | {n[0]:.2f} | {n[1]:.2f} | {sh[0]:.2f} | {sh[1]:.2f} | {n[2]:.2f} |")
    lines += [
        "",
        "Both rank the controller that satisfies the spec first and driving into the stop last; but under "
        "`net` pushing away from the goal earns what standing still earns (every step outside the goal "
        "pays -1 alike until the window of `F[0,2]` closes), and `shaped` adds little for being nearer. Our "
        "reading, not a measurement: exploration that heads for the goal meets the stop's penalty, "
        "exploration that heads away costs nothing more, and SACPN's linear actor-critic over 10 x 10 RBFs, "
        "exploring with white noise of 0.3 u_max, never sees the goal often enough to learn the braking.",
    ]
    sb3 = ROOT / "docs" / "figures" / "benchmarks_sb3.json"
    rows = json.loads(sb3.read_text(encoding="utf-8"))["rows"] if sb3.is_file() else []
    cells = [
        f"`{row['design']}` {_fmt_interval([r['success'] for r in row['results']])}"
        for row in rows
        if row["spec"] == spec_file
    ]
    if cells:
        lines[-1] += (
            " Stable-Baselines3's SAC, paid by the same rewards through `MitlPlantEnv` (the section below), "
            f"reaches {' and '.join(cells)}."
        )
    return lines + [""]


def _readme(data: dict) -> None:
    """README's table of the thesis's five problems: success over the seeds, net and shaped."""
    rows = [
        README_BEGIN,
        "| problem | formula | trials | `net` (Table 4-2) | `shaped` | best of the field's |",
        "| --- | --- | ---: | ---: | ---: | ---: |",
    ]
    from mitlc.spec.parse import load_spec

    for key, task in data["tasks"].items():
        if not key.startswith("P"):
            continue
        d = task["designs"]
        field = max(DESIGNS[3:], key=lambda n: float(np.mean(d[n]["success"])))
        formula = load_spec(ROOT / task["spec"]).formula
        rows.append(
            f"| {key} {task.get('what') or what_of(key)} | `{formula}` | {task['trials']} | "
            f"{_fmt_interval(d['net']['success'])} | {_fmt_interval(d['shaped']['success'])} | "
            f"{_fmt_interval(d[field]['success'])} (`{field}`) |"
        )
    rows += [
        "",
        f"Success by the monitor, mean over {data['seeds']} seeds x {data['runs']} runs with its 95 % interval; "
        f"`{data['command']}` ({data.get('machine') or machine('numba')}); the whole table, the nested-timing "
        "specs and the cart: [docs/benchmarks.md](docs/benchmarks.md).",
        README_END,
    ]
    write_block(ROOT / "README.md", README_BEGIN, README_END, "\n".join(rows) + "\n")


def _figure(tasks: list[str], data: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mitlc.learn.plots import png_bytes

    cols = min(4, len(tasks))
    rows = (len(tasks) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False, sharey=True)
    for ax, key in zip(axes.flat, tasks, strict=False):
        for i, design in enumerate(DESIGNS):
            d = data["tasks"][key]["designs"][design]
            curve = np.mean(np.array(d["curve"]), axis=0)
            ax.plot(d["at"][0], curve, marker=".", lw=1.2, color=f"C{i}", label=design)
        ax.axhline(TARGET, color="0.6", ls=":", lw=0.8)
        ax.set_title(key)
        ax.set_xlabel("trials")
        ax.set_ylim(-0.03, 1.03)
    for ax in axes.flat[len(tasks) :]:
        ax.axis("off")
    for ax in axes[:, 0]:
        ax.set_ylabel("success (mean over seeds)")
    axes.flat[0].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    atomic_write(path, png_bytes(fig))


if __name__ == "__main__":
    main()
