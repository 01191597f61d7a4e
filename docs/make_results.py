"""Run the thesis's five problems and write docs/results.md with its figures.

For every problem: 30 runs for each of five seeds with the shipped spec, the options its row
names (the spec's own where it names none) and one set of settings for all (SETTINGS: the
defaults but for the RBF width; a P4 row with the default width beside it); success by the
monitor on each run's final greedy rollout, as the mean over the seeds with its 95 % interval,
the final mean return and the wall time; then the comparisons on seed 0 (update masking M_k vs
M_k+1, the anti-wind-up, problem 4's conjunction).

    python docs/make_results.py            # about 11 minutes on 2 cores
    python docs/make_results.py --readme   # README's sentence again, from docs/figures/results.json

Figures go to docs/figures/ (learning_<p>.png, rollout_<p>.png, masking.png).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from results_stats import interval, machine  # noqa: E402  (docs/, the script's own folder)

from mitlc.fileio import atomic_write, write_block  # noqa: E402
from mitlc.learn.plots import learning_curve, png_bytes, rollout_figure  # noqa: E402
from mitlc.learn.sacpn import Sacpn, SacpnSettings  # noqa: E402
from mitlc.monitor.offline import monitor  # noqa: E402
from mitlc.petri.compile import CompileOptions, compile_spec  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402

COMMAND = "python docs/make_results.py"
RUNS = 30
SEEDS = (0, 1, 2, 3, 4)
TARGET = 0.95  # issue 18: each of P1-P5 at 0.95 or more, mean over 5 seeds x 30 runs
FIGURES = ROOT / "docs" / "figures"

# One set of settings for all five: the RBF width (thesis silent) at 0.5 x the centre spacing instead of
# the default 1.0, under which problem 4's runs park at a target (the P4-width1 row shows it).
SETTINGS = {"rbf_width": 0.5}

PROBLEMS = [
    # key, spec, trials, compile options over the spec's own (the table's design and flags; "settings":
    # learner settings over SETTINGS), target, what the thesis reports
    (
        "P1",
        "p1_swing_up.mitl",
        500,
        {},
        TARGET,
        "kappa = abs(q) < 0.3: a good swing-up policy in about 400 trials (Fig. 4-3c,d)",
    ),
    (
        "P2",
        "p2_avoid.mitl",
        500,
        {},
        TARGET,
        "a very nice convergence of the learning curve; swings up the long way round (Fig. 4-5)",
    ),
    (
        "P3",
        "p3_avoid_speed_limit.mitl",
        1000,
        {},
        TARGET,
        "most runs learn the slow swing-up; some swing straight through psi (Fig. 4-8)",
    ),
    (
        "P4",
        "p4_alternate.mitl",
        1500,
        {},
        TARGET,
        "the learning curve converges to a negative value; alternation shown (Fig. 4-11). "
        "The spec reads & as the min over the terms whose timing gate is open (not in the thesis)",
    ),
    (
        "P4-width1",
        "p4_alternate.mitl",
        1500,
        {"settings": {"rbf_width": 1.0}},
        TARGET,
        "the default RBF width, 1.0 x the centre spacing",
    ),
    ("P4-literal", "p4_alternate.mitl", 1500, {"conjunction": "literal"}, 0.6, "the thesis's literal min of (4-17)"),
    (
        "P5",
        "p5_timed_visit.mitl",
        1000,
        {"violations": "permanent"},
        TARGET,
        "the transient visits kappa in [1, 2] s only, with a margin (Fig. 4-13)",
    ),
]


def train(spec_file: str, trials: int, seed: int, options: dict | None = None, **settings):
    from mitlc.monitor.rewards import pay

    spec = load_spec(ROOT / "specs" / "pendulum" / spec_file)
    options = dict(options or {})
    settings = {**SETTINGS, **options.pop("settings", {}), **settings}
    rs = compile_spec(spec, CompileOptions.from_spec(spec, **options))
    agent = pay(Sacpn(rs, SacpnSettings(**settings), runs=RUNS, seed=seed))
    start = time.perf_counter()
    agent.train(trials)
    wall = time.perf_counter() - start
    ro = agent.rollout(agent.evaluation_states())
    res = monitor(spec, ro.states, ro.dt, spec.monitor_formula)
    return {
        "agent": agent,
        "spec": spec,
        "rollout": ro,
        "monitor": res,
        "success": float(res.satisfied.mean()),
        "final_return": float(agent.returns[:, -10:].mean()),
        "wall_s": wall,
        "max_abs_xi": float(np.abs(agent.xi).max()),
    }


# Problem 4's check, kappa then upsilon then kappa, as far as a rollout got: the targets it visited in order.
P4_STAGES = ("F kappa", "F (kappa & F upsilon)", "F (kappa & F (upsilon & F kappa))")


def p4_failures(r: dict) -> dict[str, int]:
    """How problem 4's failed rollouts fail: entered psi, or how many of the three visits they made."""
    from mitlc.spec.parse import parse_formula

    spec, ro = r["spec"], r["rollout"]
    failed = ~r["monitor"].satisfied
    psi = ~monitor(spec, ro.states, ro.dt, parse_formula("G !psi")).satisfied
    visits = sum(monitor(spec, ro.states, ro.dt, parse_formula(f)).satisfied.astype(int) for f in P4_STAGES)
    up_first = monitor(spec, ro.states, ro.dt, parse_formula("!kappa U upsilon")).satisfied
    out = {"psi": int((failed & psi).sum())}
    for n in range(3):
        out[f"visits {n}"] = int((failed & ~psi & (visits == n)).sum())
    out["upsilon first, parked"] = int((failed & ~psi & (visits == 0) & up_first).sum())
    return out


def rollout_png(r: dict, title: str) -> bytes:
    agent, ro = r["agent"], r["rollout"]
    rt = agent.runtime
    s = next((i for i, sub in enumerate(rt.net.subnets) if sub.kind == "state"), 0)
    places = rt.subnet_places[s]
    regions = np.searchsorted(places, rt.tables.marked[ro.codes[:5]][..., s])
    names = [rt.net.places[p].name for p in places]
    fig = rollout_figure(
        ro.states[:5],
        ro.actions[:5],
        regions,
        names,
        ro.dt,
        agent.plant.state_names,
        agent.u_max,
        title,
        list(r["monitor"].satisfied[:5]),
    )
    return png_bytes(fig)


def main() -> None:
    FIGURES.mkdir(parents=True, exist_ok=True)
    rows, raw = [], {}
    total_start = time.perf_counter()
    for key, spec_file, trials, options, target, thesis in PROBLEMS:
        per_seed = []
        fig = None
        for seed in SEEDS:
            color = f"C{seed % 10}"
            r = train(spec_file, trials, seed, options)
            per_seed.append(r)
            print(
                f"{key} seed {seed}: success {r['success']:.2f}, final return {r['final_return']:.1f}, "
                f"wall {r['wall_s']:.1f} s",
                flush=True,
            )
            fig = learning_curve(
                r["agent"].returns, title=f"{key}: {RUNS} runs per seed", label=f"seed {seed}", fig=fig, color=color
            )
        atomic_write(FIGURES / f"learning_{key.lower()}.png", png_bytes(fig))
        first = per_seed[0]
        atomic_write(
            FIGURES / f"rollout_{key.lower()}.png",
            rollout_png(
                first, f"{key}, seed 0: greedy rollouts of runs 0-4 (dashed: violates {first['spec'].monitor_formula})"
            ),
        )
        rows.append((key, spec_file, trials, options, target, thesis, per_seed))
        raw[key] = [
            {k: v for k, v in r.items() if k in ("success", "final_return", "wall_s", "max_abs_xi")} for r in per_seed
        ]
        for entry in raw[key]:
            entry["design"] = design_of(options, per_seed[0])
            entry["options"] = options
        if key.startswith("P4"):
            for r, entry in zip(per_seed, raw[key], strict=True):
                entry["failures"] = r["failures"] = p4_failures(r)

    # comparisons on seed 0
    comparisons = []
    fig = None
    for key, spec_file, trials, options, *_ in PROBLEMS:
        if key in ("P4-width1", "P4-literal"):
            continue
        r = train(spec_file, trials, 0, options, mask="next")
        comparisons.append(("mask", key, r))
        print(f"{key} mask=next: success {r['success']:.2f}, final return {r['final_return']:.1f}", flush=True)
        if key == "P1":
            base = next(x for x in rows if x[0] == "P1")[6][0]
            fig = learning_curve(
                base["agent"].returns, title="P1: update masking", label="M_k (gradient, default)", color="C0"
            )
            fig = learning_curve(r["agent"].returns, label="M_k+1 (Algorithm 1 as printed)", fig=fig, color="C3")
    atomic_write(FIGURES / "masking.png", png_bytes(fig))
    for sigma in (3.0, 5.0):
        for sat in ("applied", "none"):
            r = train("p2_avoid.mitl", 1000, 0, None, saturation=sat, sigma=sigma)
            comparisons.append((f"saturation={sat}, sigma={sigma:g}", "P2", r))
            print(
                f"P2 saturation={sat} sigma={sigma}: success {r['success']:.2f}, max|xi| {r['max_abs_xi']:.0f}",
                flush=True,
            )
    total = time.perf_counter() - total_start
    write_doc(rows, comparisons, total)
    raw["_run"] = {
        "command": COMMAND,
        "machine": machine("numba"),
        "minutes": round(total / 60, 1),
        "runs": RUNS,
        "settings": " ".join(f"--set {k}={v:g}" for k, v in SETTINGS.items()),
    }
    atomic_write(FIGURES / "results.json", json.dumps(raw, indent=1) + "\n")
    write_readme()


README_BEGIN, README_END = "<!-- results:begin -->", "<!-- results:end -->"


def design_of(options: dict, r: dict) -> str:
    """A row's reward design: its own option, else its spec's."""
    return options.get("reward") or r["spec"].option("reward")


def flags(options: dict) -> str:
    """A row's options as the command line's flags (the design aside)."""
    out = [f"--{k} {v}" for k, v in options.items() if k not in ("reward", "settings")]
    out += [f"--set {k}={v:g}" for k, v in options.get("settings", {}).items()]
    return " ".join(out)


def write_readme() -> None:
    """README's sentence on the five problems at 5 seeds x 30 runs, from docs/figures/results.json."""
    raw = json.loads((FIGURES / "results.json").read_text(encoding="utf-8"))
    run = raw["_run"]
    cells, missed = [], []
    for key, *_rest in PROBLEMS:
        if key not in raw or key in ("P4-width1", "P4-literal"):
            continue
        m, h = interval([e["success"] for e in raw[key]])
        design, extra = raw[key][0]["design"], flags(raw[key][0]["options"])
        said = " ".join(
            x for x in (f"`--reward {design}`" if design != "net" else "", f"`{extra}`" if extra else "") if x
        )
        cells.append(f"{key} {m:.2f} ± {h:.2f}" + (f" ({said})" if said else ""))
        if m < TARGET:
            missed.append(key)
    n = len(raw["P1"])
    text = (
        f"With the compiled reward and one set of settings for all five (`{run['settings']}`), spec options in "
        f"brackets, {n} seeds x {run['runs']} runs, mean success and its 95 % interval: {', '.join(cells)}"
        + (f"; {', '.join(missed)} below the target of {TARGET:.2f}" if missed else "")
        + f" (`{run['command']}`, {run['minutes']:.0f} min on {run['machine']}; "
        "[docs/results.md](docs/results.md))."
    )
    write_block(ROOT / "README.md", README_BEGIN, README_END, f"{README_BEGIN}\n{text}\n{README_END}\n")


def write_doc(rows, comparisons, total: float) -> None:
    s = SacpnSettings(**SETTINGS)
    lines = [
        "# Results: the thesis's five problems",
        "",
        f"Generated by `{COMMAND}` (do not edit by hand; rerun it). "
        f"Machine: {machine('numba')}; "
        f"the whole script took {total / 60:.1f} min. The machine was shared with other jobs while it ran, so "
        "wall times are upper bounds.",
        "",
        f"Every row: {RUNS} independent runs for each of {len(SEEDS)} seeds, the spec as shipped in "
        "`specs/pendulum/` with the reward design of the **design** column (`--reward`, or `option reward` in "
        "the spec; `net` is Table 4-2's compiled reward) and the options after its name (P5: `--violations "
        "permanent`, docs/semantics.md section 6), one set of settings for all "
        f"(`SacpnSettings({', '.join(f'{k}={v}' for k, v in SETTINGS.items())})`: gamma {s.gamma}, lambda "
        f"{s.lam}, alpha_c {s.alpha_c}, alpha_a {s.alpha_a}, 10 x 10 RBFs of width {s.rbf_width} x their "
        f"spacing, sigma = {s.sigma_frac} u_max, masking with M_k, anti-wind-up on; see "
        "[training.md](training.md)). The RBF width is not the default (1.0, which the thesis does not fix): "
        "with it problem 4's runs park at a target (the P4-width1 row and the paragraph below the table). "
        "**Success** is the fraction of runs whose final greedy rollout (no "
        "exploration, from an initial state drawn from the spec's `init` set with the run's own evaluation "
        "generator) satisfies the spec's monitor formula (`check` if the spec has one, else `formula`) by "
        "`mitlc.monitor`: per seed, then the mean over the seeds with its 95 % interval (Student's t). "
        "**Final return** is the mean over runs and seeds of the last 10 trials' returns (with exploration). "
        f"Wall time is the training time of the {RUNS} runs of a seed together, batched, on one core, "
        "mean over the seeds. The same training from the command line: "
        "`mitlc train --spec pendulum/p5_timed_visit --violations permanent --set rbf_width=0.5 --trials 1000 "
        "--seed 0`.",
        "",
        "| problem | design | trials | target | success per seed | success (95 %) | final return | wall s | "
        "thesis reports |",
        "| --- | --- | ---: | ---: | --- | ---: | ---: | ---: | --- |",
    ]
    missed = []
    for key, spec_file, trials, options, target, thesis, per_seed in rows:
        succ = [r["success"] for r in per_seed]
        m, h = interval(succ)
        cell = f"**{m:.2f} ± {h:.2f}**" if m >= target else f"{m:.2f} ± {h:.2f} (below)"
        if m < target:
            missed.append((key, m, target))
        flag = f", {flags(options)}" if flags(options) else ""
        design = design_of(options, per_seed[0])
        lines.append(
            f"| {key} (`{spec_file}`{flag}) | `{design}` | {trials} | {target:.2f} | "
            f"{' / '.join(f'{v:.2f}' for v in succ)} | {cell} | "
            f"{np.mean([r['final_return'] for r in per_seed]):.1f} | {np.mean([r['wall_s'] for r in per_seed]):.1f} | "
            f"{thesis} |"
        )
    lines += [""]
    if missed:
        lines.append("Targets missed: " + "; ".join(f"{k}: {m:.2f} against {t:.2f}" for k, m, t in missed) + ".")
    else:
        lines.append("Every problem reaches its target as the mean over the seeds.")
    p4 = {row[0]: row[6] for row in rows if row[0].startswith("P4")}
    if {"P4", "P4-width1", "P4-literal"} <= set(p4):
        fails = {k: {n: sum(r["failures"][n] for r in rs) for n in rs[0]["failures"]} for k, rs in p4.items()}
        total = {k: sum(1 - r["success"] for r in rs) * RUNS for k, rs in p4.items()}

        def how(k: str) -> str:
            f = fails[k]
            return (
                f"of its {total[k]:.0f} failed runs over all seeds, {f['psi']} entered psi, {f['visits 0']} never "
                f"reached kappa first ({f['upsilon first, parked']} of them went to upsilon, the target that was not "
                f"active, and stayed), {f['visits 1']} reached kappa and never went on to upsilon, "
                f"{f['visits 2']} reached kappa and upsilon but not kappa again"
            )

        lines += [
            "",
            "Problem 4's spec says `option conjunction = active`: & is the min over the terms whose timing gate "
            "is open (docs/semantics.md section 5). With the thesis's literal min of (4-17) (`--conjunction "
            f"literal`) and its flat reward, the same settings reach only "
            f"{np.mean([r['success'] for r in p4['P4-literal']]):.2f}: the gated term of the target that is not "
            "active is 0, so the min is never positive and arriving at a target earns nothing over waiting "
            "elsewhere without psi. With the active conjunction: "
            f"{np.mean([r['success'] for r in p4['P4']]):.2f}, {how('P4')}; with the default RBF width "
            f"{np.mean([r['success'] for r in p4['P4-width1']]):.2f}, {how('P4-width1')}. With `--conjunction "
            "literal`: "
            f"{how('P4-literal')}.",
        ]
        parked = fails["P4-width1"]["visits 0"] + fails["P4-width1"]["visits 1"]
        if parked > total["P4-width1"] / 2:
            lines[-1] += (
                " With the default width most failed runs park: they hold the pendulum at a target, or near one, "
                "for the rest of the "
                "trial. The reward of `G F` pays the active target's proposition on every step, so parking away "
                "from it costs as much per step as the swing towards it, and arriving pays one step's bonus: a "
                "local optimum (P4's learning curves in docs/benchmarks.md stop rising after a third of the "
                "training)."
            )
    lines += [
        "",
        "The thesis gives no success rates, only averaged learning curves and one transient per problem "
        "(the figures were lost in the text extraction, see READING-NOTES.md), so the comparison with it is "
        "qualitative. The independent implementation quoted in issue 4 reached 0.93 on P2 before winding up "
        "to 0.33, 0.70-0.93 on P3 and 0.57-0.70 on P4 (active conjunction).",
        "",
        "## Learning curves and rollouts",
        "",
        f"Learning curves: mean return per trial over the {RUNS} runs of each seed, with the 10-90 % band. "
        "Rollouts: the greedy policies of runs 0-4 of seed 0 (black: run 0), the background coloured by the "
        "marked place of the state region net in run 0's rollout; dashed lines violate the spec.",
        "",
    ]
    for key, *_ in rows:
        k = key.lower()
        lines += [
            f"### {key}",
            "",
            f"![learning curve {key}](figures/learning_{k}.png)",
            f"![rollouts {key}](figures/rollout_{k}.png)",
            "",
        ]
    lines += [
        "## Update masking: M_k (gradient) against M_k+1 (Algorithm 1 as printed)",
        "",
        "Seed 0, 30 runs, everything else default. `mask=next` is Algorithm 1 as printed: one feature trace "
        "and the updates weighted by the marking *after* the step, so the TD error of entering a place is "
        "credited to the new place rather than to the place whose policy acted.",
        "",
        "| problem | success, M_k | success, M_k+1 | final return, M_k | final return, M_k+1 | max abs(Xi), M_k+1 |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    by_key = {row[0]: row[6][0] for row in rows}
    for kind, key, r in comparisons:
        if kind != "mask":
            continue
        b = by_key[key]
        lines.append(
            f"| {key} | {b['success']:.2f} | {r['success']:.2f} | {b['final_return']:.1f} | "
            f"{r['final_return']:.1f} | {r['max_abs_xi']:.3g} |"
        )
    lines += [
        "",
        "![masking](figures/masking.png)",
        "",
        "## Actor wind-up (problem 2, 1000 trials, seed 0)",
        "",
        "`saturation=applied` (default) clips the policy to the input bound, updates with the exploration "
        "actually applied, and never moves a saturated output further past the bound; `none` is the "
        "thesis's update. max abs(Xi) is the largest actor parameter at the end.",
        "",
        "| setting | success | final return | max abs(Xi) |",
        "| --- | ---: | ---: | ---: |",
    ]
    for kind, _key, r in comparisons:
        if kind.startswith("saturation"):
            lines.append(f"| {kind} | {r['success']:.2f} | {r['final_return']:.1f} | {r['max_abs_xi']:.0f} |")
    sat = {kind: r for kind, _key, r in comparisons if kind.startswith("saturation")}
    fine = all(r["success"] >= 0.9 for r in sat.values())
    bounded = all(
        sat[f"saturation=applied, sigma={g:g}"]["max_abs_xi"] <= sat[f"saturation=none, sigma={g:g}"]["max_abs_xi"]
        for g in (3.0, 5.0)
    )
    lines += [
        "",
        "Read honestly: "
        + (
            "with masking by M_k, problem 2 does not wind up badly at these settings with or without the remedy"
            if fine
            else "at these settings the success rates differ (the table)"
        )
        + (
            "; the remedy bounds the parameters (the max abs(Xi) column)"
            if bounded
            else "; the remedy does not keep max abs(Xi) below the unprotected update's here"
        )
        + ". The independent implementation's wind-up (issue 4: max abs(Xi) 36 -> 264, "
        "success 0.93 -> 0.33) did appear during development with a *partial* remedy, the applied "
        "exploration without the rule that blocks outward updates. With only one-sided exploration at the "
        "bound, updates drift outwards whenever pulling back looked worse; the blocking rule removes that "
        "drift, which is why both parts are the default.",
    ]
    lines += ["", "Per-seed numbers in machine-readable form: [figures/results.json](figures/results.json).", ""]
    lines += [
        "## The weight sweep of Figure 4-6",
        "",
        "Problem 2 with the weight of `G !psi` in {1, 2, 5, 10, 20}, 3 seeds, with and without "
        "`--violations permanent`, run by `mitlc sweep` (`python docs/make_sweep_results.py`): the table "
        "and its reading are in [sweep_results.md](sweep_results.md).",
        "",
        "![success rate over the psi weight](figures/sweep_p2_weights.png)",
        "",
    ]
    page = ROOT / "docs" / "results.md"
    old = page.read_text(encoding="utf-8") if page.is_file() else ""
    # the sections other scripts write: docs/make_hyrl_results.py, docs/make_violation_results.py,
    # docs/make_nested_results.py, docs/make_default_results.py
    for name in ("hyrl", "violations", "nested", "defaults"):
        begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
        if begin in old and end in old:
            lines += [old[old.index(begin) : old.index(end) + len(end)], ""]
    atomic_write(page, "\n".join(lines))


if __name__ == "__main__":
    if sys.argv[1:] == ["--readme"]:
        write_readme()
    elif sys.argv[1:]:
        print(f"usage: {COMMAND} [--readme]", file=sys.stderr)
        sys.exit(2)
    else:
        main()
