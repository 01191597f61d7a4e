"""Train HyRL on the mass-damper specs (thesis chapter 3 and beyond) and write docs/hyrl_results.md.

    python docs/make_hyrl_results.py                  # the committed results
    python docs/make_hyrl_results.py --quick          # a smoke run (few runs and trials)

For each spec under ``specs/mass_damper/`` it trains ``runs`` independent runs
for the thesis's number of trials (800 for the overshoot, section 3-3-1; 2000
for the rise time, section 3-3-2), then rolls every run's greedy policy out
from 50 initial positions evenly spaced over the spec's initial range and
judges each rollout with the classical-criteria checker (``mitlc.hybrid.criteria``).
The combined spec (section 3-3-3) is run with the policies learned separately
(composition, the thesis's method) and, for comparison, trained directly.
The settling-time and steady-state-error specs (beyond the thesis) get the
overshoot's number of trials.

Writes ``docs/hyrl_results.md``, ``docs/hyrl_results.json`` and the figures in
``docs/figures/hyrl/``.  Every number in the Markdown comes from this run.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.cli.hybrid import SMALL_STEP, rollout_mode_figure  # noqa: E402
from mitlc.fileio import atomic_write  # noqa: E402
from mitlc.hybrid import compile_requirements, render_bytes  # noqa: E402
from mitlc.learn.hyrl import HANDOVER_SIGMA, HybridLearner, HyrlSettings, brake_bound, compose, evaluate, train_handover  # noqa: E402
from mitlc.learn.plots import learning_curve, png_bytes  # noqa: E402
from mitlc.spec.parse import load_spec  # noqa: E402

SPECS = ROOT / "specs" / "mass_damper"
DOCS = ROOT / "docs"
FIGS = DOCS / "figures" / "hyrl"
N_INIT = 50


def train(name: str, runs: int, trials: int, seed: int, settings: HyrlSettings, quiet: bool):
    from tqdm import tqdm

    spec = load_spec(SPECS / f"{name}.mitl")
    learner = HybridLearner(spec, settings, runs=runs, seed=seed)
    bar = tqdm(total=trials, desc=name, unit="trial", disable=quiet, dynamic_ncols=True)

    def step(trial, returns):
        bar.set_postfix_str(f"mean return {learner.returns[:, -10:].mean():8.1f}", refresh=False)
        bar.update(1)

    learner.train(trials, step)
    bar.close()
    start = time.perf_counter()
    ev = evaluate(learner, N_INIT)
    return spec, learner, ev, time.perf_counter() - start


def shown_run(ev) -> int:
    """The run whose rollouts are drawn: the first that meets every criterion, else run 0."""
    ok = np.flatnonzero(ev.run_success())
    return int(ok[0]) if ok.size else 0


def responses_figure(ev, automaton, run: int, title: str):
    """All greedy responses of one run from the 50 initial states (like Figures 3-8, 3-14 d);
    failed ones dashed red."""
    from matplotlib.figure import Figure

    n = len(ev.q0)
    ro = ev.rollout
    t = np.arange(ro.states.shape[1]) * ro.dt
    fig = Figure(figsize=(7.0, 3.2))
    ax = fig.add_subplot(1, 1, 1)
    for i in range(n):
        b = run * n + i
        ok = bool(ev.ok()[run, i])
        ax.plot(t, ro.states[b, :, 0], "-" if ok else "--", color="#1d4ed8" if ok else "#b91c1c", lw=0.8, alpha=0.8)
    ax.axhline(automaton.setpoint, color="k", lw=0.6, ls=":")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position q [m]")
    ax.set_xlim(0, min(t[-1], 3.0))
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=9)
    return fig


def row_of(label, method, spec, learner_runs, trials, ev, wall, note=""):
    step = np.abs(ev.q0 - spec.setpoint)
    big = step >= SMALL_STEP
    out = {
        "spec": f"specs/mass_damper/{label}.mitl",
        "method": method,
        "runs": learner_runs,
        "trials": trials,
        "success_rate": ev.success_rate(),
        "state_success_rate": ev.state_rate(),
        "criteria_success_rate": ev.success_rate(stable=False),
        "criteria_state_success_rate": ev.state_rate(stable=False),
        "stabilised_state_rate": float(ev.stabilised.mean()),
        "success_rate_step_ge_0.1": ev.success_rate(big),
        "state_success_rate_step_ge_0.1": ev.state_rate(big),
        "by_requirement": {k: float(p.all(axis=1).mean()) for k, p in ev.passed_each.items()},
        "wall_s": round(wall, 1),
        "note": note,
    }
    out["stabilised_state_rate"] = float(ev.stabilised.mean())
    if "rise_time" in ev.measured:
        met = ev.passed_each["rise_time"]
        rt = ev.measured["rise_time"][met]
        out["rise_time_range_when_met"] = [float(rt.min()), float(rt.max())] if rt.size else None
        by_q0 = ev.measured["rise_time"]
        out["rise_time_q0_first_last_run0"] = [float(by_q0[0, 0]), float(by_q0[0, -1])]
    for name in ("settling_time", "steady_state_error"):
        if name in ev.measured:
            m = ev.measured[name][:, big]
            finite = m[np.isfinite(m)]
            out[f"{name}_median_step_ge_0.1"] = float(np.median(finite)) if finite.size else None
            out[f"{name}_max_step_ge_0.1"] = float(finite.max()) if finite.size == m.size else None
    if "overshoot" in ev.measured:
        out["max_overshoot_step_ge_0.1"] = float(ev.measured["overshoot"][:, big].max())
        out["runs_without_overshoot_step_ge_0.1"] = float((ev.measured["overshoot"][:, big] == 0).all(axis=1).mean())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="independent runs per spec (thesis: 20 for the overshoot)")
    ap.add_argument("--trials-overshoot", type=int, default=800, help="thesis section 3-3-1: 800")
    ap.add_argument("--trials-rise", type=int, default=2000, help="thesis section 3-3-2: 2000")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-direct", action="store_true", help="skip training the combined spec directly")
    ap.add_argument(
        "--no-beyond",
        action="store_true",
        help="skip the settling-time and steady-state-error specs (beyond the thesis)",
    )
    ap.add_argument("--quick", action="store_true", help="smoke run: 2 runs, 20/40 trials, to a scratch dir")
    ap.add_argument("--out", type=Path, default=None, help="write here instead of docs/ (default for --quick: /tmp)")
    ap.add_argument("-q", "--quiet", action="store_true")
    ap.add_argument(
        "--block-only",
        action="store_true",
        help="no training: rewrite the hyrl block of docs/results.md from docs/hyrl_results.json",
    )
    args = ap.parse_args()
    if args.block_only:
        write_results_block(json.loads((DOCS / "hyrl_results.json").read_text()), DOCS / "results.md")
        print(f"wrote the hyrl block of {DOCS / 'results.md'}")
        return
    if args.quick:
        args.runs, args.trials_overshoot, args.trials_rise = 2, 20, 40
    docs = args.out or (Path("/tmp/mitlc_hyrl_quick") if args.quick else DOCS)
    figs = docs / "figures" / "hyrl"
    figs.mkdir(parents=True, exist_ok=True)
    settings = HyrlSettings()
    command = "python docs/make_hyrl_results.py" + "".join(f" {a}" for a in sys.argv[1:])
    total_start = time.perf_counter()
    rows = []
    learners = {}
    evs = {}

    for name, trials in (("overshoot", args.trials_overshoot), ("rise_time", args.trials_rise)):
        spec, learner, ev, eval_s = train(name, args.runs, trials, args.seed, settings, args.quiet)
        learners[name], evs[name] = learner, ev
        rows.append(row_of(name, "HyRL", spec, learner.runs, trials, ev, learner.wall_s + eval_s))
        atomic_write(
            figs / f"learning_{name}.png",
            png_bytes(learning_curve(learner.returns, title=f"{name}: HyRL on the mass-damper, {learner.runs} runs")),
        )

    combined = load_spec(SPECS / "overshoot_rise_time.mitl")
    start = time.perf_counter()
    ctl = compose(combined, [learners["rise_time"], learners["overshoot"]])
    ev_c = ctl.evaluate(N_INIT)
    rows.append(
        row_of(
            "overshoot_rise_time",
            "composed (3-3-3)",
            combined,
            ctl.runs,
            0,
            ev_c,
            time.perf_counter() - start,
            note="no training: " + ", ".join(f"{m} from {src}" for m, src in ctl.describe().items()),
        )
    )
    bound = brake_bound(ev_c, ctl.automaton, ctl.plant, ctl.params)
    bound_rates = {
        "brake_bound_state_rate": float(bound.mean()),
        "brake_bound_success_rate": float(bound.all(axis=1).mean()),
    }
    rows[-1].update(bound_rates)
    evs["composed"] = ev_c
    # beyond the thesis: the overshoot learner's modes retrained from the rise-time handovers
    start = time.perf_counter()
    ctl_h, _ = train_handover(ctl, learners["overshoot"], args.trials_overshoot)
    ev_h = ctl_h.evaluate(N_INIT)
    rows.append(
        row_of(
            "overshoot_rise_time",
            "composed, overshoot modes retrained on the handovers",
            combined,
            ctl_h.runs,
            args.trials_overshoot,
            ev_h,
            time.perf_counter() - start,
            note="beyond the thesis (docs/hyrl.md): E_Mp, S and P of the overshoot learner trained "
            f"on, from the states the rise-time policies hand over, exploring with {HANDOVER_SIGMA} N "
            "(`mitlc.learn.hyrl.HANDOVER_SIGMA`); I and E_tr as composed",
        )
    )
    rows[-1].update(bound_rates)  # the same handovers: the same bound
    evs["composed_handover"] = ev_h
    if not args.no_direct:
        spec, learner, ev, eval_s = train(
            "overshoot_rise_time", args.runs, args.trials_rise, args.seed, settings, args.quiet
        )
        learners["direct"], evs["direct"] = learner, ev
        rows.append(
            row_of(
                "overshoot_rise_time",
                "HyRL, trained directly",
                spec,
                learner.runs,
                args.trials_rise,
                ev,
                learner.wall_s + eval_s,
            )
        )
        atomic_write(
            figs / "learning_overshoot_rise_time.png",
            png_bytes(
                learning_curve(
                    learner.returns, title=f"overshoot_rise_time: HyRL trained directly, {learner.runs} runs"
                )
            ),
        )

    # beyond the thesis: the settling time and the steady-state error (docs/hyrl.md), as many
    # trials as the overshoot (their automata have its shape)
    beyond = () if args.no_beyond else ("settling_time", "steady_state_error")
    for name in beyond:
        spec, learner, ev, eval_s = train(name, args.runs, args.trials_overshoot, args.seed, settings, args.quiet)
        learners[name], evs[name] = learner, ev
        rows.append(
            row_of(
                name, "HyRL (beyond the thesis)", spec, learner.runs, args.trials_overshoot, ev, learner.wall_s + eval_s
            )
        )
        atomic_write(
            figs / f"learning_{name}.png",
            png_bytes(learning_curve(learner.returns, title=f"{name}: HyRL on the mass-damper, {learner.runs} runs")),
        )

    # rollouts like Figures 3-7, 3-14 and 3-15 and the responses of one run from all 50 states
    pics = {}
    for key, automaton, u_max in (
        ("overshoot", learners["overshoot"].automaton, learners["overshoot"].u_max),
        ("rise_time", learners["rise_time"].automaton, learners["rise_time"].u_max),
        ("composed", ctl.automaton, learners["overshoot"].u_max),
        ("composed_handover", ctl_h.automaton, learners["overshoot"].u_max),
    ) + tuple((name, learners[name].automaton, learners[name].u_max) for name in beyond):
        ev = evs[key]
        run = shown_run(ev)
        n = len(ev.q0)
        picks = sorted({0, n // 2, n - 1})
        fig = rollout_mode_figure(
            ev.rollout,
            automaton,
            [run * n + i for i in picks],
            u_max,
            f"{key}: greedy policy of run {run} (background: mode)",
        )
        atomic_write(figs / f"rollout_{key}.png", png_bytes(fig))
        ok = int(ev.ok()[run].sum())
        atomic_write(
            figs / f"responses_{key}.png",
            png_bytes(
                responses_figure(
                    ev, automaton, run, f"{key}, run {run}: {ok}/{n} initial states meet the criteria (failures dashed)"
                )
            ),
        )
        pics[key] = run
    for name in ("overshoot", "rise_time", "overshoot_rise_time") + beyond:
        h = compile_requirements(load_spec(SPECS / f"{name}.mitl"))
        atomic_write(figs / f"automaton_{name}.svg", render_bytes(h, "svg"))

    total = time.perf_counter() - total_start
    data = {
        "command": command,
        "settings": settings.to_dict(),
        "initial_states": N_INIT,
        "seed": args.seed,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "machine": platform.machine(),
        "total_wall_s": round(total, 1),
        "rows": rows,
        "shown_runs": pics,
    }
    atomic_write(docs / "hyrl_results.json", json.dumps(data, indent=2) + "\n")
    atomic_write(docs / "hyrl_results.md", markdown(data, args))
    if docs == DOCS:
        write_results_block(data, DOCS / "results.md")
    print(f"done in {total:.0f} s: {docs / 'hyrl_results.md'}")


BLOCK_BEGIN = "<!-- hyrl:begin -->"
BLOCK_END = "<!-- hyrl:end -->"
SECTION = "## Classical performance on the mass-damper (thesis chapter 3)"
THESIS_LINE = (
    "Thesis figures to match: no overshoot for |q0| >= 0.1 after 800 trials (section 3-3-1, Figure 3-8); "
    "rise time 0.63-0.78 s after 2000 trials (section 3-3-2, Figure 3-14). The thesis shows one learned "
    "policy per problem and reports no success rate over runs."
)


def results_block(d: dict) -> str:
    """The hyrl block of docs/results.md: the main table of hyrl_results.md, markers included."""
    lines = [
        BLOCK_BEGIN,
        SECTION,
        "",
        f"HyRL on the specs of `specs/mass_damper/`, generated by `{d['command']}` (seed {d['seed']}, "
        f"{d['initial_states']} initial states per run; total {d['total_wall_s']:.0f} s). Success rate: runs whose "
        "greedy rollouts meet every requirement and stabilise from all initial states; states: (run, initial "
        "state) pairs that do. Details, settings and per-requirement figures: [hyrl_results.md](hyrl_results.md).",
        "",
        "| spec | method | runs | trials | success rate | states | success, \\|q0\\| >= 0.1 "
        "| states, \\|q0\\| >= 0.1 | wall time |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in d["rows"]:
        lines.append(
            f"| `{Path(r['spec']).name}` | {r['method']} | {r['runs']} | {r['trials']} | {pct(r['success_rate'])} | "
            f"{pct(r['state_success_rate'])} | {pct(r['success_rate_step_ge_0.1'])} | "
            f"{pct(r['state_success_rate_step_ge_0.1'])} | {r['wall_s']:.0f} s |"
        )
    lines += [
        "",
        THESIS_LINE,
        "",
        "Learning curves: [overshoot](figures/hyrl/learning_overshoot.png), "
        "[rise time](figures/hyrl/learning_rise_time.png)"
        + (
            ", [combined, trained directly](figures/hyrl/learning_overshoot_rise_time.png)"
            if any(r["method"].startswith("HyRL, trained directly") for r in d["rows"])
            else ""
        )
        + ". Rollouts: "
        + ", ".join(f"[{k}](figures/hyrl/rollout_{k}.png)" for k in d["shown_runs"])
        + ".",
        "",
        BLOCK_END,
    ]
    return "\n".join(lines) + "\n"


def replace_block(text: str, block: str) -> str:
    """``text`` with the hyrl block replaced by ``block``: the marked block if present, else the section
    from the line ``SECTION`` up to the next ``<!-- violations:begin -->`` line; everything else unchanged."""
    if BLOCK_BEGIN in text:
        i = text.index(BLOCK_BEGIN)
        j = text.index(BLOCK_END, i) + len(BLOCK_END)
        if text[j : j + 1] == "\n":
            j += 1
        return text[:i] + block + text[j:]
    i = text.find("\n" + SECTION + "\n")
    if i < 0 and text.startswith(SECTION + "\n"):
        i = -1
    elif i < 0:
        raise SystemExit(f"results.md has neither {BLOCK_BEGIN} nor a line {SECTION!r}")
    i += 1
    j = text.find("\n<!-- violations:begin -->", i)
    j = len(text) if j < 0 else j + 1
    return text[:i] + block + ("\n" if j < len(text) else "") + text[j:]


def write_results_block(d: dict, path: Path) -> None:
    atomic_write(path, replace_block(path.read_text(), results_block(d)))


def pct(x) -> str:
    return "-" if x is None else f"{100 * x:.0f}%"


def markdown(d: dict, args) -> str:
    s = d["settings"]
    lines = [
        "# HyRL results on the mass-damper (thesis chapter 3, and beyond)",
        "",
        "Generated by",
        "",
        "```",
        d["command"],
        "```",
        "",
        f"(total {d['total_wall_s']:.0f} s, one process, Python {d['python']}, numpy {d['numpy']}, "
        f"{d['machine']}; seed {d['seed']}). Settings: Table 3-2 (gamma {s['gamma']}, lambda {s['lam']}, "
        f"alpha_c {s['alpha_c']}, RBFs {' x '.join(map(str, s['rbf']))} "
        f"(x {s['rbf_clock']} per clock), T_t = 5 s, T_s = 0.03 s), but alpha_a {s['alpha_a']} "
        "(Table 3-2: 0.08; measured); where the thesis is silent: "
        f"exploration sigma = {s['sigma']} N"
        + (f" (Ornstein-Uhlenbeck, correlation time {s['noise_tau']} s)" if s.get("noise_tau") else " (white)")
        + f", RBF width {s['rbf_width']} x spacing, "
        f"qdot grid {'+-' + str(s['qdot_grid']) + ' m/s' if s.get('qdot_grid') else 'the plant bound'}, "
        + (
            f"q centres warped towards the set-point (q_warp {s['q_warp']}), "
            if s.get("q_warp") is not None
            else "q centres warped towards the set-point (`q_warp` auto: 0.5, an even grid for the rise time alone), "
        )
        + f"critic started `{s.get('critic_init', 'zero')}`, "
        f"anti-wind-up `{s['saturation']}` (see [hyrl.md](hyrl.md)).",
        "",
        f"Every run's greedy policy is rolled out from {d['initial_states']} initial positions evenly spaced over "
        "the spec's initial range and judged by the checker (`mitlc.hybrid.criteria`: overshoot, 10-90% rise time, "
        "settling time, steady-state error). "
        "A rollout **succeeds** when it meets every requirement *and* stabilises: it ends within 10% of the "
        "step from the set-point (the width of the thesis's S band; without it, a controller that never moves "
        "has no overshoot). **Success rate**: the fraction of runs whose rollouts succeed from *all* initial "
        "states; **states**: the fraction of (run, initial state) pairs that succeed; **criteria only**: "
        "success rate without the stabilisation condition. The thesis's overshoot result is for |q0| >= 0.1, "
        "hence the last two columns.",
        "",
        "| spec | method | runs | trials | success rate | states | criteria only | success, \\|q0\\| >= 0.1 "
        "| states, \\|q0\\| >= 0.1 | wall time |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in d["rows"]:
        lines.append(
            f"| `{Path(r['spec']).name}` | {r['method']} | {r['runs']} | {r['trials']} | {pct(r['success_rate'])} | "
            f"{pct(r['state_success_rate'])} | {pct(r['criteria_success_rate'])} | "
            f"{pct(r['success_rate_step_ge_0.1'])} | {pct(r['state_success_rate_step_ge_0.1'])} | "
            f"{r['wall_s']:.0f} s |"
        )
    notes = [r for r in d["rows"] if r.get("note")]
    if notes:
        lines += [""] + [f"{r['method']}: {r['note']}." for r in notes]
    lines += ["", "Per requirement (fraction of runs meeting it from all 50 initial states, by the checker):", ""]
    for r in d["rows"]:
        parts = ", ".join(f"{k} {pct(v)}" for k, v in r["by_requirement"].items())
        extra = ""
        if r.get("rise_time_range_when_met"):
            lo, hi = r["rise_time_range_when_met"]
            a, b = r["rise_time_q0_first_last_run0"]
            extra += (
                f"; rise times where met {lo:.2f}-{hi:.2f} s (run 0: {a:.2f} s from q0 = -1, {b:.2f} s from q0 = -0.5)"
            )
        if "runs_without_overshoot_step_ge_0.1" in r:
            extra += f"; runs with no overshoot from every |q0| >= 0.1: {pct(r['runs_without_overshoot_step_ge_0.1'])}"
        for name, unit in (("settling_time", "s"), ("steady_state_error", "m")):
            if f"{name}_median_step_ge_0.1" in r:
                med, worst = r[f"{name}_median_step_ge_0.1"], r[f"{name}_max_step_ge_0.1"]
                extra += (
                    f"; {name.replace('_', ' ')} from |q0| >= 0.1: median "
                    + (f"{med:.3g} {unit}" if med is not None else "never")
                    + ", largest "
                    + (f"{worst:.3g} {unit}" if worst is not None else "unbounded (some never settle)")
                )
        extra += f"; rollouts that stabilise: {pct(r['stabilised_state_rate'])}"
        if "brake_bound_state_rate" in r:
            extra += (
                f"; braking at the bound from the state handed over to E_Mp would avoid the overshoot "
                f"from {pct(r['brake_bound_state_rate'])} of the states and from all 50 in "
                f"{pct(r['brake_bound_success_rate'])} of the runs (`mitlc.learn.hyrl.brake_bound`: the most "
                "any overshoot policy could do with these rise-time handovers)"
            )
        lines.append(f"- `{Path(r['spec']).name}`, {r['method']}: {parts}{extra}.")
    lines += [
        "",
        THESIS_LINE,
        "",
        "## Learning curves",
        "",
        "![overshoot](figures/hyrl/learning_overshoot.png)",
        "",
        "![rise time](figures/hyrl/learning_rise_time.png)",
        "",
    ]
    if any(r["method"].startswith("HyRL, trained directly") for r in d["rows"]):
        lines += ["![overshoot and rise time, trained directly](figures/hyrl/learning_overshoot_rise_time.png)", ""]
    for r in d["rows"]:
        if r["method"] == "HyRL (beyond the thesis)":
            name = Path(r["spec"]).stem
            lines += [f"![{name.replace('_', ' ')} (beyond the thesis)](figures/hyrl/learning_{name}.png)", ""]
    lines += [
        "## Greedy rollouts (background: mode, like Figure 3-7)",
        "",
        "Green I, yellow/orange the evaluating modes, blue S, red P.",
        "",
    ]
    for key, _run in d["shown_runs"].items():
        lines += [
            f"![{key} rollouts](figures/hyrl/rollout_{key}.png)",
            "",
            f"![{key} responses](figures/hyrl/responses_{key}.png)",
            "",
        ]
    lines += [
        "## The automata",
        "",
        "![B-1](figures/hyrl/automaton_overshoot.svg)",
        "",
        "![B-2](figures/hyrl/automaton_rise_time.svg)",
        "",
        "![B-3](figures/hyrl/automaton_overshoot_rise_time.svg)",
        "",
    ]
    for r in d["rows"]:
        if r["method"] == "HyRL (beyond the thesis)":
            name = Path(r["spec"]).stem
            lines += [f"![{name.replace('_', ' ')}](figures/hyrl/automaton_{name}.svg)", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
