"""Command-line pieces for classical-performance specs: ``mitlc automaton`` and HyRL training.

:func:`train_hybrid_cli` is what ``mitlc train --spec SPEC`` does for a spec
with ``require`` statements (no formula).  It trains HyRL
(:mod:`mitlc.learn.hyrl`), judges every run's greedy policy from 50 initial positions
with the classical-criteria checker (:mod:`mitlc.hybrid.criteria`) and writes, to
``out``, atomically:

* ``metrics.json``: ``returns`` (runs x trials), ``success_rate`` (fraction of
  runs meeting every requirement and ending near the set-point from all 50
  initial states; ``criteria_success_rate`` without the second condition),
  ``state_success_rate``, per-requirement rates, measured criteria, ``wall_s``,
  the settings;
* ``params.npz``: the learner (parameters, generator states, the spec's text);
* ``learning_curve.png`` and ``rollout.png`` (position and input with the
  mode as background colour, like Figure 3-7).

:func:`automaton` is the ``mitlc automaton SPEC`` click command; :func:`compose_cmd`
(``mitlc compose SPEC --policy DIR --policy DIR``) runs a combined automaton
with policies trained separately (section 3-3-3).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import click
import numpy as np

from mitlc.cli import interrupt
from mitlc.cli.common import atomic_write, handle_errors, output_option, plant_file_option, write_result
from mitlc.errors import InputError, TrainingError
from mitlc.fileio import json_text
from mitlc.spec.model import Spec

__all__ = [
    "train_hybrid_cli",
    "automaton",
    "compose_cmd",
    "rollout_mode_figure",
    "metrics_of",
    "AUTOMATON_FORMATS",
    "PARAMS",
]

PARAMS = "params.npz"
AUTOMATON_FORMATS = ("text", "json", "dot", "svg", "png")
SMALL_STEP = 0.1
"""Steps smaller than this (|q0 - setpoint|) are reported apart: the thesis's overshoot
result holds for |q0| >= 0.1 only (section 3-3-1)."""


def _load_spec(spec: Any) -> Spec:
    from mitlc.spec.parse import load_spec

    if isinstance(spec, Spec):
        return spec
    return load_spec(str(spec))


# ---------------------------------------------------------------- figures


def rollout_mode_figure(ro, automaton, rows: Sequence[int], u_max: float | None = None, title: str = ""):
    """Position and input of a few greedy rollouts, one column each, the mode of the
    automaton as background colour (Figure 3-7: I green, E yellow, S blue, P red)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    rows = list(rows)
    n = len(rows)
    fig = Figure(figsize=(3.6 * n + 0.6, 4.6))
    axes = fig.subplots(2, n, sharex=True, squeeze=False)
    N1 = ro.states.shape[1]
    t = np.arange(N1) * ro.dt
    # the evaluating modes get shades of yellow/orange to tell them apart
    e_shades = ["#fef08a", "#fed7aa", "#fde68a", "#fdba74"]
    colour = {}
    e_count = 0
    for m in automaton.modes:
        if m.kind == "E":
            colour[m.name] = e_shades[e_count % len(e_shades)]
            e_count += 1
        else:
            colour[m.name] = {"I": "#bbf7d0", "S": "#bfdbfe", "P": "#fecaca"}[m.kind]
    used: list[str] = []
    for col, b in enumerate(rows):
        modes = ro.modes[b]
        starts = np.flatnonzero(np.r_[True, modes[1:] != modes[:-1]])
        ends = np.r_[starts[1:], N1 - 1]
        for ax in axes[:, col]:
            for s, e in zip(starts, ends, strict=True):
                name = automaton.names[int(modes[s])]
                if name not in used:
                    used.append(name)
                ax.axvspan(t[s], t[e] if e > s else t[s] + ro.dt, color=colour[name], lw=0)
            ax.grid(alpha=0.3)
            ax.set_xlim(t[0], t[-1])
        q = ro.states[b, :, 0]
        axes[0, col].plot(t, q, "k", lw=1.3)
        axes[0, col].axhline(automaton.setpoint, color="k", lw=0.6, ls=":")
        axes[0, col].set_title(f"q0 = {q[0]:.2f}", fontsize=9)
        axes[1, col].step(t[:-1], ro.actions[b], where="post", color="k", lw=1.0)
        if u_max is not None:
            axes[1, col].set_ylim(-1.1 * u_max, 1.1 * u_max)
        axes[1, col].set_xlabel("time [s]")
    axes[0, 0].set_ylabel("position q [m]")
    axes[1, 0].set_ylabel("input u [N]")
    handles = [Patch(color=colour[m], label=m) for m in automaton.names if m in used]
    fig.legend(handles=handles, loc="upper right", fontsize=8, title="mode", title_fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0, 0.92 if n > 1 else 0.85, 1))
    return fig


def _example_rows(ev, run: int = 0) -> list[int]:
    """Rows of the evaluation rollout for run ``run``: the first, middle and last initial state."""
    n = len(ev.q0)
    picks = sorted({0, n // 2, n - 1})
    return [run * n + i for i in picks]


# ---------------------------------------------------------------- metrics


def metrics_of(learner, ev, wall_s: float) -> dict:
    """What ``metrics.json`` holds for a trained learner and its evaluation.

    ``success_rate``: fraction of runs whose greedy policy, from every initial state,
    meets every requirement (by the checker) *and* stabilises (ends within
    ``stable_fraction`` of the step from the set-point); ``criteria_success_rate``
    without the second condition.
    """
    from mitlc.learn.hyrl import STABLE_FRACTION

    A = learner.automaton
    step = np.abs(ev.q0 - A.setpoint)
    big = step >= SMALL_STEP
    measured = {}
    for name, m in ev.measured.items():
        finite = m[np.isfinite(m)]
        measured[name] = {
            "median": float(np.median(m)) if m.size else None,
            "min": float(finite.min()) if finite.size else None,
            "max": float(finite.max()) if finite.size else None,
            "non_finite": int((~np.isfinite(m)).sum()),
        }
    out = {
        "spec": learner.spec.path,
        "requirements": [{"name": r.name, "lo": r.lo, "hi": r.hi, "band": r.band} for r in A.requirements],
        "setpoint": A.setpoint,
        "modes": list(A.names),
        "runs": learner.runs,
        "trials": learner.trial,
        "seed": learner.seed,
        "settings": learner.settings.to_dict(),
        "n_features": learner.n_features,
        "feature_vars": list(learner.features.names),
        "wall_s": round(float(wall_s), 3),
        "run_steps": int(learner.runs * learner.trial * learner.n_steps),
        "initial_states": len(ev.q0),
        "success_rate": ev.success_rate(),
        "state_success_rate": ev.state_rate(),
        "criteria_success_rate": ev.success_rate(stable=False),
        "criteria_state_success_rate": ev.state_rate(stable=False),
        "stabilised_state_rate": float(ev.stabilised.mean()),
        "stable_fraction": STABLE_FRACTION,
        "success_rate_by_requirement": {k: float(p.all(axis=1).mean()) for k, p in ev.passed_each.items()},
        f"success_rate_step_ge_{SMALL_STEP}": ev.success_rate(big) if big.any() else None,
        f"state_success_rate_step_ge_{SMALL_STEP}": ev.state_rate(big) if big.any() else None,
        f"initial_states_step_ge_{SMALL_STEP}": int(big.sum()),
        "runs_succeeding": [bool(v) for v in ev.run_success()],
        "visited_p_rate": float(ev.visited_p.mean()),
        "measured": measured,
        "final_mean_return": float(learner.returns[:, -min(10, learner.returns.shape[1]) :].mean())
        if learner.returns.size
        else None,
        "returns": learner.returns.round(6).tolist(),
    }
    return out


# ---------------------------------------------------------------- training


def train_hybrid_cli(
    spec: Any,
    runs: int,
    trials: int,
    seed: int,
    out: str | Path | None,
    progress: bool = True,
    settings=None,
    n_init: int = 50,
    plots: bool = True,
    resume: str | Path | None = None,
    report: bool = False,
) -> dict:
    """Train HyRL on a classical-performance spec (a path or a parsed spec) and write
    ``metrics.json``, ``params.npz``, ``learning_curve.png`` and ``rollout.png`` to ``out``
    (and, with ``report``, ``report.html``: :mod:`mitlc.cli.report`).

    ``trials`` counts all trials, those of a ``resume`` directory's checkpoint
    included (its spec, runs, seed and settings are used); ``out`` None is a new
    folder ``runs/<spec>_<N>``.  Returns the metrics.
    Ctrl-C stops after the last complete trial, writes everything so far
    (``interrupted: true``) and exits with status 130.
    """
    from mitlc.learn.hyrl import HybridLearner, HyrlSettings, load_learner

    if resume is not None:
        ckpt = Path(resume) / PARAMS
        if not ckpt.is_file():
            raise InputError(f"no checkpoint {PARAMS} in {resume}", file=str(resume))
        learner = load_learner(ckpt, spec if isinstance(spec, Spec) else None)
        s = learner.spec
    else:
        s = _load_spec(spec)
        if not s.requirements:
            raise InputError("the spec has no 'require' statement: train it with SACPN (mitlc train)", file=s.path)
        learner = HybridLearner(s, settings or HyrlSettings(), runs=runs, seed=seed)
    from mitlc.cli.report import after_training
    from mitlc.cli.train import _same_folder, output_set

    continuing = resume is not None and out is not None and _same_folder(Path(out), Path(resume))
    outset = output_set(None if out is None else Path(out), s, continuing).open()  # an unwritable folder fails now
    try:
        metrics = _train_hybrid_into(outset, learner, s, runs, trials, progress, n_init, plots)
    except SystemExit:  # interrupted, the set written: its report says so
        after_training(outset.out, report)
        raise
    finally:
        outset.close()
    after_training(outset.out, report)
    return metrics


def _train_hybrid_into(outset, learner, s, runs, trials, progress, n_init, plots) -> dict:
    from mitlc.cli.progress import Progress
    from mitlc.learn.hyrl import evaluate
    from mitlc.learn.plots import learning_curve, png_bytes

    out = outset.out
    done_before = learner.trial
    bar = Progress(trials, done_before, desc=Path(s.path or "spec").stem, quiet=not progress)

    def step(trial: int, returns: np.ndarray) -> None:
        interrupt.check()
        bar.update(f"mean return {learner.returns[:, -10:].mean():.1f}")

    interrupted = False
    try:
        interrupt.check()  # a Ctrl-C during start-up that Python dropped
        learner.train(max(0, trials - done_before), step)
    except KeyboardInterrupt:
        interrupted = True
    except TrainingError:
        bar.close()
        raise
    finally:
        bar.close()
    wall = learner.wall_s  # training time, summed over resumed sessions
    files: dict[str, bytes | str] = {PARAMS: learner.to_bytes()}
    name = Path(s.path or "spec").stem
    if learner.trial > 0:
        ev = evaluate(learner, n_init)
        metrics = metrics_of(learner, ev, wall)
        if plots:
            files["learning_curve.png"] = png_bytes(
                learning_curve(learner.returns, title=f"{name}: HyRL, {learner.runs} runs")
            )
            fig = rollout_mode_figure(
                ev.rollout,
                learner.automaton,
                _example_rows(ev),
                learner.u_max,
                f"{name}: greedy policy of run 0 (background: mode)",
            )
            files["rollout.png"] = png_bytes(fig)
    else:
        metrics = {"spec": s.path, "runs": runs, "trials": 0, "wall_s": round(wall, 3), "returns": []}
    metrics["interrupted"] = interrupted
    files["metrics.json"] = json_text(metrics)
    out = outset.write(
        files, first=PARAMS, trial=learner.trial, seed=learner.seed, runs=learner.runs, wall_s=round(wall, 3)
    )
    if interrupted:
        click.echo(
            f"interrupted after trial {learner.trial}; checkpoint in {out / PARAMS}\n"
            f"continue with: mitlc train --resume {out} --trials {trials}",
            err=True,
        )
        sys.exit(130)
    # the summary line, like SACPN's (also under -q: only the progress bar is quiet)
    big = metrics.get(f"success_rate_step_ge_{SMALL_STEP}")
    n_big = metrics.get(f"initial_states_step_ge_{SMALL_STEP}")
    small = (
        ""
        if big is None or n_big == metrics.get("initial_states", 0)
        else f"; {big:.2f} from the {n_big} at least {SMALL_STEP} from the set-point"
    )
    click.echo(
        f"{learner.runs} runs x {learner.trial} trials in {wall:.1f} s; "
        f"final mean return {metrics.get('final_mean_return', float('nan')):.1f}; "
        f"success rate {metrics.get('success_rate', float('nan')):.2f} "
        f"({metrics.get('initial_states', 0)} initial states per run{small}); results in {out}"
    )
    return metrics


# ---------------------------------------------------------------- mitlc automaton


@click.command("automaton")
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option(
    "--format",
    "fmt",
    type=click.Choice(AUTOMATON_FORMATS),
    default="text",
    show_default=True,
    help="What to write: a readable summary, JSON, Graphviz DOT or a rendered picture.",
)
@output_option
@plant_file_option
@handle_errors
def automaton(spec: str, fmt: str, output: str | None) -> None:
    """Compile SPEC's classical criteria (require ...) into a hybrid automaton (thesis appendix B).

    SPEC is a .mitl file or the name of a shipped spec (pendulum/p2_avoid; mitlc specs lists them).
    """
    from mitlc.hybrid import compile_requirements, render_bytes
    from mitlc.spec.parse import load_spec

    s = load_spec(spec)
    for w in s.warnings:
        click.echo(w, err=True)
    h = compile_requirements(s)
    makers: dict[str, Callable[[], str | bytes]] = {
        "text": lambda: str(h) + "\n",
        "json": lambda: h.to_json() + "\n",
        "dot": lambda: h.to_digraph().source,
        "svg": lambda: render_bytes(h, "svg"),
        "png": lambda: render_bytes(h, "png"),
    }
    write_result(output, fmt, makers[fmt])


# ---------------------------------------------------------------- mitlc simulate (HyRL policies)


def _load_learners(policy_dirs: Sequence[str]) -> list:
    """The HyRL learners of ``policy_dirs``, each folder's plant restored first (a plant file's copy)."""
    from mitlc.learn.checkpoint import read_meta, restore_plant
    from mitlc.learn.hyrl import load_learner

    learners = []
    for d in policy_dirs:
        ckpt = Path(d) / PARAMS
        if not ckpt.is_file():
            raise InputError(f"no {PARAMS} in {d} (train first with 'mitlc train --out DIR')", file=str(d))
        for note in restore_plant(read_meta(ckpt), ckpt):
            click.echo(note, err=True)
        learners.append(load_learner(ckpt))
    return learners


def simulate_hybrid(
    policy_dirs: Sequence[str],
    spec_path: str | None,
    rollouts: int | None,
    seed: int,
    plot_path: str | None,
    starts: str = "fresh",
) -> None:
    """``mitlc simulate`` for HyRL policies: greedy rollouts from random initial states of the
    spec's set (``starts="fresh"``), or every run from the evenly spaced initial states ``mitlc
    train`` judged it on (``"train"``), judged by the checker.  One policy runs on its own automaton
    (or on ``--spec``'s); several run composed on ``--spec``'s combined automaton (section 3-3-3)."""
    from mitlc.learn.hyrl.evaluation import _judge, compose, evaluate, stabilised
    from mitlc.learn.plots import png_bytes

    learners = _load_learners(policy_dirs)
    if spec_path is None and len(learners) > 1:
        raise InputError("name the combined spec to run several HyRL policies on", file="--spec")
    ctl = None
    if spec_path is None:
        runner, automaton = learners[0], learners[0].automaton
    else:
        ctl = compose(_load_spec(spec_path), learners)
        runner, automaton = ctl, ctl.automaton
    runs = runner.runs
    reqs = ", ".join(r.name for r in automaton.requirements)
    if starts == "train":
        n_init = _trained_initial_states(policy_dirs[0])
        if rollouts is not None:
            raise InputError(
                f"--starts train judges every run from the {n_init} initial states its training was judged on: "
                "leave out --rollouts",
                file="--rollouts",
            )
        ev = evaluate(learners[0], n_init) if ctl is None else ctl.evaluate(n_init)
        for r in range(runs):
            click.echo(
                f"run {r:3d}: {int(ev.ok()[r].sum())}/{n_init} initial states succeed "
                f"(criteria met: {int(ev.passed[r].sum())}, stabilised: {int(ev.stabilised[r].sum())})"
            )
        click.echo(
            f"success rate {ev.success_rate():.2f} ({n_init} initial states per run, as mitlc train judged: "
            f"runs that meet {reqs} and stabilise from all of them)"
        )
        if plot_path is not None:
            fig = rollout_mode_figure(ev.rollout, automaton, _example_rows(ev), float(learners[0].u_max), "run 0")
            atomic_write(plot_path, png_bytes(fig))
        return
    n = rollouts or runs
    rng = np.random.default_rng(seed)
    (qlo, qhi), (vlo, vhi) = automaton.q0_range, automaton.qdot0_range
    x0 = np.stack([rng.uniform(qlo, qhi, n), rng.uniform(vlo, vhi, n)], axis=1)
    run = np.arange(n) % runs
    ro = runner.rollout(x0, run)
    verdict = _judge(automaton, ro)
    stable = stabilised(automaton, ro)
    ok = verdict.all & stable
    for i in range(n):
        parts = []
        for name, passed in verdict.passed.items():
            parts.append(f"{name} {verdict.measured[name][i]:.3g} {'ok' if passed[i] else 'FAILED'}")
        parts.append("stabilised" if stable[i] else "NOT stabilised")
        click.echo(
            f"rollout {i:3d} (run {run[i]:3d}, q0={x0[i, 0]:.3f}, qdot0={x0[i, 1]:.3f}): "
            f"{'; '.join(parts)}; return {ro.returns[i]:.1f}"
        )
    click.echo(
        f"{int(ok.sum())}/{n} rollouts meet {reqs} and stabilise (fresh starts drawn from the initial set, seed {seed})"
    )
    if plot_path is not None:
        rows = list(range(min(n, 3)))
        fig = rollout_mode_figure(
            ro, automaton, rows, float(learners[0].u_max), f"{int(ok.sum())}/{n} rollouts succeed"
        )
        atomic_write(plot_path, png_bytes(fig))


def _trained_initial_states(folder: str, default: int = 50) -> int:
    """How many initial states per run the training in ``folder`` was judged from (its metrics.json)."""
    import json

    try:
        n = json.loads((Path(folder) / "metrics.json").read_text(encoding="utf-8")).get("initial_states")
    except (OSError, ValueError, AttributeError, RecursionError):
        return default
    return n if isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= 10000 else default


# ---------------------------------------------------------------- mitlc compose


@click.command("compose")
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option(
    "--policy",
    "policy_dirs",
    type=click.Path(file_okay=False, exists=True),
    multiple=True,
    required=True,
    help="Directory written by 'mitlc train' on a spec with one of SPEC's criteria (repeat).",
)
@click.option(
    "--initial-states",
    "n_init",
    type=click.IntRange(1, 10000),
    default=50,
    show_default=True,
    help="Initial positions, evenly spaced over SPEC's initial range.",
)
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Write rollouts of run 0 with the mode as background colour here (PNG).",
)
@click.option(
    "--handover-sigma",
    type=click.FloatRange(0, None),
    default=None,
    help="Exploration (N) of the --handover-trials retraining (default 2, twice the learners').",
)
@click.option(
    "--handover-trials",
    type=click.IntRange(0, 1_000_000),
    default=0,
    show_default=True,
    help="Beyond the thesis: first retrain the policies of S, P and the last evaluating mode "
    "for this many trials from the states the earlier modes hand over (0: plain composition).",
)
@plant_file_option
@handle_errors
def compose_cmd(
    spec: str,
    policy_dirs: tuple[str, ...],
    n_init: int,
    plot_path: str | None,
    handover_trials: int = 0,
    handover_sigma: float | None = None,
) -> None:
    """Run SPEC's combined automaton with policies learned separately (thesis section 3-3-3)."""
    from mitlc.learn.hyrl import HANDOVER_SIGMA, brake_bound, compose, train_handover
    from mitlc.learn.plots import png_bytes
    from mitlc.spec.parse import load_spec

    learners = _load_learners(policy_dirs)  # first: their folders make a plant file's plant known to SPEC
    s = load_spec(spec)
    ctl = compose(s, learners)
    for mode, src in ctl.describe().items():
        click.echo(f"mode {mode:<5} policy {src}")
    if handover_trials:
        last = ctl.assignment["S"][0]
        sigma = HANDOVER_SIGMA if handover_sigma is None else handover_sigma
        ctl, _ = train_handover(ctl, last, handover_trials, sigma=sigma)
        click.echo(
            f"retrained {Path(last.spec.path or 'spec').stem}'s modes for {handover_trials} trials "
            f"from the handed-over states, exploring with {sigma:g} N"
        )
    ev = ctl.evaluate(n_init)
    for r in range(ctl.runs):
        click.echo(
            f"run {r:3d}: {int(ev.ok()[r].sum())}/{n_init} initial states succeed "
            f"(criteria met: {int(ev.passed[r].sum())}, stabilised: {int(ev.stabilised[r].sum())})"
        )
    click.echo(
        f"success rate {ev.success_rate():.2f} ({ctl.runs} runs, all of {n_init} initial states); "
        f"states {ev.state_rate():.2f}"
    )
    if "E_Mp" in ctl.automaton.names:
        b = brake_bound(ev, ctl.automaton, ctl.plant, ctl.params)
        click.echo(
            f"braking at the bound from the states handed over to E_Mp avoids the overshoot from "
            f"{b.mean():.2f} of the states"
        )
    if plot_path is not None:
        rows = _example_rows(ev)
        fig = rollout_mode_figure(
            ev.rollout, ctl.automaton, rows, float(ctl.params["u_max"]), f"{Path(spec).stem}: composed policies, run 0"
        )
        atomic_write(plot_path, png_bytes(fig))
