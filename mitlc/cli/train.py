"""``mitlc train`` and ``mitlc simulate``: thin click commands over :mod:`mitlc.learn.sacpn`.

``mitlc train --plant pendulum`` trains the plant's default spec (problem 2
of the thesis) with 30 runs and writes, to ``--out`` (default: a new folder
``runs/<spec>_<N>``, N the next free number):

* ``metrics.json``: ``returns`` (runs x trials), ``success_rate`` (fraction of
  runs whose final greedy rollout, from the run's evaluation start
  ``evaluation_starts``, satisfies the spec, by :mod:`mitlc.monitor`),
  ``satisfied`` and ``robustness`` per run, ``wall_s``, the settings;
* ``params.npz``: the learner's full state (parameters, random generator
  states, trial counter), also the checkpoint ``--resume`` continues from;
* ``learning_curve.png`` and ``rollout.png``;
* ``plants/FILE.py``: a copy of the plant file the spec's plant came from
  (``--plant-file``), so that the folder is used again without it;
* ``manifest.json``: the set's files with their SHA-256, the spec and its plant
  (:mod:`mitlc.cli.outputs`).

Every file is written atomically.  Ctrl-C stops after rolling back to the last
complete trial and writes the checkpoint; ``--resume DIR`` then continues to
``--trials`` (a total) and gives the same parameters, to the bit, as a run that
was never interrupted.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import click
import numpy as np

from mitlc.cli import interrupt
from mitlc.cli.common import atomic_write, check_writable, compile_options, handle_errors, plant_file_option
from mitlc.cli.outputs import OutputSet
from mitlc.errors import InputError, MitlError, TrainingError
from mitlc.fileio import json_text

__all__ = ["train", "simulate", "find_default_spec"]

PARAMS = "params.npz"
TRIALS = 500
"""Trials per run when ``--trials`` is not given, for SACPN and HyRL (SAC counts samples instead)."""


def find_default_spec(plant_name: str) -> Path:
    """The file of a plant's default spec, a shipped spec (:mod:`mitlc.spec.library`)."""
    from mitlc.plants.base import PLANTS
    from mitlc.spec.library import find

    plant = PLANTS.get(plant_name)
    if plant is None:
        raise InputError(f"unknown plant '{plant_name}' (known: {', '.join(sorted(PLANTS))})", file="--plant")
    if not plant.default_spec:
        raise InputError(f"plant '{plant_name}' has no default spec: pass --spec", file="--plant")
    shipped = find(plant.default_spec)
    if shipped is None:
        raise InputError(
            f"default spec '{plant.default_spec}' is not among the shipped specs (mitlc specs lists them)",
            file="--spec",
            hint="pass --spec FILE",
        )
    return shipped.path


def _load(spec_path: str | None, source: str | None = None, origin: str | None = None):
    from mitlc.spec.parse import load_spec, parse_spec

    if spec_path is not None:
        return load_spec(spec_path)
    return parse_spec(source or "", origin)


def _settings_from_options(base, **opts):
    import dataclasses

    values = {k: v for k, v in opts.items() if v is not None}
    return dataclasses.replace(base, **values)


def _checked(settings, assignments, options, plant=None):
    """``settings`` after their own range checks (and resolved for ``plant``: SACPN's
    default grid); a failure names the option that set the value (``--sigma``, ... from
    ``options``, else ``--set``)."""
    from mitlc.errors import TrainingError

    try:
        settings.check()
        if plant is not None:
            settings = settings.resolved(plant)
    except TrainingError as exc:
        name = exc.message.split(" ", 1)[0].strip("'")
        given = {k for k, v in options.items() if v is not None}
        where = f"--{name.replace('_', '-')}" if name in given else "--set" if assignments else "mitlc train"
        raise InputError(exc.message, file=where, hint=exc.hint) from None
    return settings


def _region_track(agent, codes: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Index of the marked place of the first state sub-net per sample, and the place names."""
    rt = agent.runtime
    net = rt.net
    s = next((i for i, sub in enumerate(net.subnets) if sub.kind == "state"), 0)
    places = rt.subnet_places[s]
    marked = rt.tables.marked[codes][..., s]
    local = np.searchsorted(places, marked)
    return local, [net.places[p].name for p in places]


def _input_boxes(policy) -> list[tuple[str, float, float]]:
    """``(name, lo, hi)`` of each input of the plant ``policy`` (a SACPN agent or an SB3 policy) drives."""
    lo, hi = policy.plant.input_box(policy.params)
    return [(n, float(a), float(b)) for n, a, b in zip(policy.plant.input_names, lo, hi, strict=True)]


def _rollout_png(agent, ro, verdicts, title: str) -> bytes:
    from mitlc.learn.plots import png_bytes, rollout_figure

    show = min(5, ro.states.shape[0])
    regions, names = _region_track(agent, ro.codes[:show])
    fig = rollout_figure(
        ro.states[:show],
        ro.actions[:show],
        regions,
        names,
        ro.dt,
        agent.plant.state_names,
        None,
        title,
        None if verdicts is None else list(verdicts[:show]),
        _input_boxes(agent),
    )
    return png_bytes(fig)


def _mean(a: np.ndarray) -> float:
    """The mean of the finite entries (a diverged run's returns are NaN), nan when there are none."""
    a = np.asarray(a, dtype=float)
    ok = np.isfinite(a)
    return float(a[ok].mean()) if ok.any() else float("nan")


def _judge(spec, ro):
    from mitlc.monitor.offline import monitor

    try:
        return monitor(spec, ro.states, ro.dt, spec.monitor_formula)
    except InputError as exc:  # the states the rollouts reached (a plant that blew up): say so, not "<spec>"
        raise exc.located("the rollouts") from None


def _judge_greedy(agent, spec, metrics: dict, files: dict, plots: bool) -> None:
    """Each run's greedy rollout from its evaluation start (mitlc simulate --starts train) judged by the
    monitor, into ``metrics`` (success_rate, satisfied, ...) and, with ``plots``, ``files``'s rollout.png."""
    x0 = agent.evaluation_states()
    ro = agent.rollout(x0)
    res = _judge(spec, ro)
    metrics.update(
        evaluation_starts=x0.round(12),
        success_rate=float(np.mean(res.satisfied)),
        satisfied=[bool(v) for v in res.satisfied],
        robustness=[float(v) for v in res.robustness],
        greedy_returns=ro.returns.round(6),
    )
    if plots:
        files["rollout.png"] = _rollout_png(
            agent, ro, res.satisfied, f"greedy rollouts, {int(res.satisfied.sum())}/{agent.runs} satisfy"
        )


def _outputs(
    agent, spec, wall_s: float, interrupted: bool, plots: bool = True, raced: dict | None = None
) -> tuple[dict[str, bytes | str], dict]:
    """The output set of a training, in memory: ``{file name: content}`` and the metrics (``raced``:
    the exploration race that chose the settings, :meth:`mitlc.sweep.race.Race.record`)."""
    from mitlc.learn.plots import learning_curve, png_bytes

    files: dict[str, bytes | str] = {PARAMS: agent.to_bytes()}
    diverged = [{"run": int(r), "trial": int(t)} for r, t in enumerate(agent.diverged) if t >= 0]
    metrics: dict = {
        "spec": spec.path,
        "formula": str(spec.formula),
        "check": str(spec.monitor_formula),
        "conjunction": agent.rs.options.conjunction,
        "violations": agent.rs.options.violations,
        "clock": agent.rs.options.clock,
        "reward": agent.rs.options.reward,
        "runs": agent.runs,
        "trials": agent.trial,
        "seed": agent.seed,
        "settings": agent.settings.to_dict(),
        "sigma": agent.sigma,
        "wall_s": round(wall_s, 3),
        "run_steps": int(agent.runs * agent.trial * agent.n_steps),
        "interrupted": interrupted,
        "diverged": diverged,
        "returns": agent.returns.round(6),
    }
    if raced is not None:
        metrics["race"] = raced
    if not interrupted and agent.trial > 0:
        _judge_greedy(agent, spec, metrics, files, plots)
    if plots and agent.trial > 0:
        fig = learning_curve(agent.returns, title=f"{Path(spec.path or 'spec').stem}: {agent.runs} runs")
        files["learning_curve.png"] = png_bytes(fig)
    files["metrics.json"] = json_text(metrics)
    return files, metrics


@click.command("train")
@click.option("--plant", "plant_name", default=None, help="Plant to train (must match the spec's plant).")
@click.option(
    "--spec",
    "spec_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Spec file (.mitl) or a shipped spec's name (pendulum/p2_avoid; mitlc specs lists them); "
    "default: the plant's default spec.",
)
@click.option("--runs", type=click.IntRange(1, 10000), default=30, show_default=True, help="Independent runs.")
@click.option(
    "--trials",
    type=click.IntRange(0, 10**7),
    default=None,
    help=f"Trials per run (in total, counting trials done before --resume); default {TRIALS} (the policy search "
    "runs a fifth of them as generations: 100), for --learner sac about 20,000 samples per run.",
)
@click.option(
    "--learner",
    type=click.Choice(["sacpn", "sac", "search"]),
    default=None,
    help="Default: SACPN's exploration designs and the policy search race and the winner trains "
    "(mitlc docs training). sacpn: SACPN only; search: the policy search only (CMA-ES over a time-varying "
    "linear feedback judged by the monitor); sac: Stable-Baselines3's SAC on the same reward, one network per "
    "run (needs the sb3 extra); --set takes their settings then.",
)
@click.option(
    "--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True, help="Seed of all random numbers."
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(file_okay=False),
    default=None,
    help="Output directory (default: a new runs/<spec name>_<N>, or the --resume directory). A folder "
    "holding other files, or a training of another spec, is refused.",
)
@click.option(
    "--resume",
    "resume_dir",
    type=click.Path(file_okay=False, exists=True),
    default=None,
    help="Continue the training saved in this directory.",
)
@compile_options
@click.option(
    "--penalty-ramp",
    type=click.FloatRange(0, 1),
    default=None,
    help="With --violations: the fraction of the trials over which the penalty c grows from 0 "
    "(default 0.75; 0 = full from the start).",
)
@click.option(
    "--sigma",
    type=float,
    default=None,
    help="Exploration std of the input (default 0.3 u_max; 1 N for HyRL; a plant with several inputs takes "
    "--set sigma_frac=F instead).",
)
@click.option(
    "--mask",
    type=click.Choice(["current", "next"]),
    default=None,
    help="Update masking: current = M_k (gradient, default), next = M_k+1 (Algorithm 1 as printed).",
)
@click.option(
    "--saturation",
    type=click.Choice(["applied", "none"]),
    default=None,
    help="Actor anti-wind-up: applied (default) or none (the thesis's update).",
)
@click.option(
    "--set",
    "assignments",
    multiple=True,
    metavar="NAME=VALUE",
    help="Any trainer setting (repeat), e.g. --set alpha_a=0.08 --set rbf=10x10x5: SacpnSettings "
    "for a formula spec, HyrlSettings for a 'require' spec (mitlc docs training, mitlc docs hyrl).",
)
@click.option(
    "--preset",
    type=click.Choice(["default", "thesis"]),
    default="default",
    show_default=True,
    help="thesis: Table 4-4's settings as chapter 4 trained (gamma 0.97, the plant's grid, width 1, "
    "sigma_frac 0.3), no race; --set changes either.",
)
@click.option(
    "--no-race",
    is_flag=True,
    help="Train sigma_frac 0.3 and rbf_width 0.5 straight away, without first racing the exploration designs "
    "(mitlc docs training; --sigma, --set sigma_frac=... or --set rbf_width=... leave that setting out of the race).",
)
@click.option("--no-plots", is_flag=True, help="Skip the PNG figures (and the report).")
@click.option("--no-report", is_flag=True, help="Skip report.html, the training as one HTML page (mitlc docs report).")
@click.option(
    "--starts",
    "starts_path",
    type=click.Path(exists=True, dir_okay=False),
    default=None,
    help="With --resume: start each run's trial from one of these states (x0 of the counterexamples.npz "
    "'mitlc verify --out' writes) half the time, from the init box otherwise (mitlc docs verify).",
)
@click.option(
    "--checkpoint-every",
    type=click.FloatRange(0, 1e9),
    default=60.0,
    show_default=True,
    metavar="SECONDS",
    help="Replace the checkpoint params.npz in --out this often while training (0: only at the end), "
    "so that a killed training resumes from it (--resume).",
)
@click.option(
    "-q",
    "--quiet",
    is_flag=True,
    help="No progress on stderr (a bar on a terminal, else a line per 5 % of the trials).",
)
@click.option(
    "--workers",
    type=click.IntRange(1, 256),
    default=None,
    help="Processes the race's designs and the policy search's runs are trained in (default: the cores "
    "this process may use, at most 8). The results do not depend on it.",
)
@plant_file_option
@handle_errors
def train(
    plant_name,
    spec_path,
    runs,
    trials,
    learner,
    seed,
    out_dir,
    resume_dir,
    conjunction,
    violations,
    clock,
    reward,
    penalty_ramp,
    sigma,
    mask,
    saturation,
    assignments,
    preset,
    no_race,
    no_plots,
    starts_path,
    checkpoint_every,
    quiet,
    no_report,
    workers,
) -> None:
    """Train SACPN controllers on a spec and judge them with the monitor."""
    from mitlc.cli.memory import keep_freed_memory

    keep_freed_memory()
    from mitlc.cli.report import after_failed_training, after_training, live_curves
    from mitlc.learn.checkpoint import check_against, recorded_spec
    from mitlc.learn.sacpn import SacpnSettings, read_meta
    from mitlc.learn.settings import parse_assignments
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.sweep.race import greedy_verdicts, race, search_designs_for, search_generations
    from mitlc.sweep.task import sacpn_learner

    meta = None
    if learner in ("sac", "search"):
        stray = {"--resume": resume_dir, "--sigma": sigma, "--mask": mask, "--saturation": saturation}
        stray.update({"--penalty-ramp": penalty_ramp, "--no-race": no_race or None})
        stray["--preset"] = None if preset == "default" else preset
        for option, value in stray.items():
            if value is not None:
                what = f"{learner.upper()} trainings keep no checkpoint" if option == "--resume" else "it is SACPN's"
                raise InputError(f"{option} does not go with --learner {learner}: {what}", file=option)
    if starts_path is not None and resume_dir is None:
        raise InputError("--starts guides a resumed training: give --resume DIR too", file="--starts")
    if workers is not None and learner == "sac":
        raise InputError(
            "--workers trains the race's designs and the policy search's runs; SAC steps its own vector of "
            "environments",
            file="--workers",
        )
    from mitlc.learn.search import usable_cores

    processes = usable_cores() if workers is None else workers  # the race's and the policy search's
    if resume_dir is not None:
        ckpt = Path(resume_dir) / PARAMS
        if not ckpt.is_file():
            raise InputError(f"no checkpoint {PARAMS} in {resume_dir}", file=str(resume_dir))
        meta = read_meta(ckpt)
        _restore_plant(meta, ckpt)
        spec = _load(spec_path) if spec_path is not None else recorded_spec(meta, ckpt)
        check_against(meta, spec, ckpt)
        runs, seed = int(meta["runs"]), int(meta["seed"])
        conjunction = conjunction or meta.get("conjunction")
        violations = violations or meta.get("violations")
        clock = clock or meta.get("clock")
        reward = reward or meta.get("reward")
        base = SacpnSettings.from_dict(meta["settings"])
        out: Path | None = Path(out_dir or resume_dir)
    else:
        if spec_path is None:
            if plant_name is None:
                raise InputError("give --plant or --spec", file="mitlc train")
            spec_path = str(find_default_spec(plant_name))
        spec = _load(spec_path)
        base = SacpnSettings.thesis() if preset == "thesis" else SacpnSettings()
        out = Path(out_dir) if out_dir else None  # None: a new runs/<spec>_<N> (output_set)
    if plant_name is not None and spec.plant_name != plant_name:
        raise InputError(f"the spec is for plant '{spec.plant_name}', not '{plant_name}'", file=spec.path)
    for w in spec.warnings:
        click.echo(w, err=True)
    if spec.formula is None and spec.requirements:  # classical criteria: HyRL (docs/hyrl.md)
        if learner in ("sac", "search"):
            raise InputError(
                f"a spec of 'require' criteria trains HyRL; --learner {learner} takes a formula", file="--learner"
            )
        trials = TRIALS if trials is None else trials
        if starts_path is not None:
            raise InputError("--starts guides SACPN trainings; this spec trains HyRL", file="--starts")
        if workers is not None:
            raise InputError(
                "--workers trains the race's designs and the policy search's runs; this spec trains HyRL",
                file="--workers",
            )
        from mitlc.cli.hybrid import train_hybrid_cli
        from mitlc.learn.hyrl import HyrlSettings

        overrides = {k: v for k, v in (("sigma", sigma), ("saturation", saturation)) if v is not None}
        overrides.update(parse_assignments(HyrlSettings, assignments))
        hyrl_settings = _checked(HyrlSettings(**overrides), assignments, {"sigma": sigma, "saturation": saturation})
        train_hybrid_cli(
            spec,
            runs,
            trials,
            seed,
            out,
            progress=not quiet,
            settings=hyrl_settings,
            plots=not no_plots,
            resume=resume_dir,
            report=not (no_report or no_plots),
        )
        return
    if learner in ("sac", "search"):
        options = CompileOptions.from_spec(
            spec, conjunction=conjunction, violations=violations, clock=clock, reward=reward
        )
        rs_given = compile_spec(spec, options)
        if learner == "sac":
            out = _train_sac(spec, rs_given, runs, trials, seed, out, assignments, quiet, no_plots)
        else:
            out = _train_search(spec, rs_given, runs, trials, seed, out, assignments, quiet, no_plots, processes)
        after_training(out, not (no_report or no_plots))
        return
    trials = TRIALS if trials is None else trials
    settings = _settings_from_options(base, sigma=sigma, mask=mask, saturation=saturation, penalty_ramp=penalty_ramp)
    settings = _checked(
        _settings_from_options(settings, **parse_assignments(SacpnSettings, assignments)),
        assignments,
        {"sigma": sigma, "mask": mask, "saturation": saturation, "penalty_ramp": penalty_ramp},
        spec.plant,
    )
    options = CompileOptions.from_spec(spec, conjunction=conjunction, violations=violations, clock=clock, reward=reward)
    rs = compile_spec(spec, options)
    for w in rs.warnings:
        click.echo(w, err=True)

    def build(st, r: int, s: int):
        return sacpn_learner(rs, st, r, s)

    from mitlc.learn.search import SearchRuns, SearchSettings

    given_sacpn = bool(assignments) or any(v is not None for v in (sigma, mask, saturation, penalty_ramp))
    searcher = None
    if learner is None and not given_sacpn and spec.plant is not None:

        def searcher(r: int, changes: dict):  # the race's search: runs 0 .. r - 1 of the training's own seed
            return SearchRuns(rs, r, seed, SearchSettings(**changes), _monitor_judge(spec), workers=processes)

    wall_before = 0.0
    raced: dict | None = None
    continuing = resume_dir is not None and out is not None and _same_folder(out, Path(resume_dir))
    if meta is not None:
        agent = build(settings, runs, seed)
        agent.load(Path(resume_dir) / PARAMS)
        if starts_path is not None:  # falsification-guided training (mitlc.cli.guided)
            from mitlc.cli.guided import guide_starts, read_starts

            guide_starts(agent, read_starts(starts_path, agent.plant.state_names))
        wall_before = _wall_before(Path(resume_dir))
        raced = _read_json(Path(resume_dir) / "metrics.json").get("race")
        outset = output_set(out, spec, continuing).open()
    else:
        outset = output_set(out, spec, continuing).open()  # before training: a folder that cannot be written fails now
        try:
            chosen = {a.split("=", 1)[0].strip() for a in assignments} | ({"sigma"} if sigma is not None else set())
            stem = Path(spec.path or "spec").stem
            agent = build(settings, runs, seed)  # the full training's learner: what it refuses (its size) fails now
            if preset == "default" and not no_race:
                from mitlc.cli.progress import compile_notice

                t0 = time.perf_counter()
                with compile_notice(quiet):  # the race's first design compiles the kernel
                    result = race(
                        build,
                        greedy_verdicts,
                        settings,
                        runs,
                        trials,
                        seed,
                        None
                        if quiet
                        else lambda i, n, text: click.echo(
                            f"{stem}: race {i + 1}/{n} ({100 * (i + 1) // n}%), {text}", err=True
                        ),
                        given=chosen,
                        search=searcher,
                        generations=search_generations(trials),
                        search_designs=search_designs_for(spec.monitor_formula),
                        workers=processes,
                        tick=interrupt.check,  # a Ctrl-C dropped while modules loaded stops the race
                    )
                if result is not None:
                    built, (settings, raced) = settings, (result.settings, result.record())
                    wall_before = time.perf_counter() - t0
                    if not quiet:
                        click.echo(result.line(), err=True)
                    if result.learner == "search":  # the search won: its race runs kept, the others searched now
                        kept = result.searched
                        rest = (
                            SearchRuns(
                                rs,
                                runs - kept.runs,
                                seed,
                                kept.settings,
                                kept.judge,
                                first=kept.runs,
                                workers=processes,
                            )
                            if runs > kept.runs
                            else None
                        )
                        out = _search_into(
                            outset, rest, spec, result.generations, quiet, no_plots, kept, raced, wall_before
                        )
                        outset.close()
                        after_training(out, not (no_report or no_plots))
                        return
                    if settings != built:  # the winner is not the design the learner was built with
                        agent = build(settings, runs, seed)
        except KeyboardInterrupt:
            outset.close()
            click.echo(
                "interrupted during the race of exploration designs, before the training: nothing saved", err=True
            )
            sys.exit(130)
        except BaseException:
            outset.close()
            raise
    report, live = not (no_report or no_plots), None
    try:
        live = live_curves(outset.out, spec, trials, report)
        _train_into(outset, agent, spec, trials, wall_before, checkpoint_every, quiet, no_plots, raced, live)
    except SystemExit:  # interrupted, the checkpoint written: the report shows it as interrupted
        after_training(outset.out, report)
        raise
    except BaseException:  # no set of this training written here: the pages it kept up are put right
        after_failed_training(outset.out, live)
        raise
    finally:
        outset.close()
    after_training(outset.out, report)


def _train_sac(spec, rs, runs, trials, seed, out, assignments, quiet, no_plots) -> Path:
    """``mitlc train --learner sac``: :class:`mitlc.gym.sac.SacRuns` into an output set (the models,
    metrics.json as SACPN's, the plots); Ctrl-C saves nothing (no checkpoint to resume)."""
    from mitlc.cli.progress import Progress
    from mitlc.learn.settings import parse_assignments

    for w in rs.warnings:
        click.echo(w, err=True)
    try:
        from mitlc.gym.sac import SacRuns, SacSettings, default_trials, model_name
    except ImportError:  # no Gymnasium
        raise InputError(
            "--learner sac trains Stable-Baselines3's SAC through mitlc.gym: pip install 'mitlc[sb3]'",
            file="--learner",
        ) from None
    settings = SacSettings(**parse_assignments(SacSettings, assignments))
    try:
        settings.check()
    except TrainingError as exc:
        raise InputError(exc.message, file="--set") from None
    agent = SacRuns(rs, runs, seed, settings)
    trials = default_trials(agent.n_steps) if trials is None else trials
    stem = Path(spec.path or "spec").stem
    outset = output_set(out, spec).open()
    try:
        bar = Progress(runs * trials, 0, desc=stem, quiet=quiet)
        start = time.perf_counter()

        def progress(done: int, total: int) -> None:
            interrupt.check()
            bar.update(f"run {min(done // max(trials, 1), runs - 1) + 1}/{runs}")

        try:
            interrupt.check()
            agent.train(trials, progress)
        except KeyboardInterrupt:
            bar.close()
            click.echo("interrupted: a SAC training keeps no checkpoint, nothing saved", err=True)
            sys.exit(130)
        bar.close()
        wall = time.perf_counter() - start
        files = {model_name(r): agent.model_bytes(r) for r in range(agent.runs)}
        metrics = _runs_outputs(agent, spec, wall, "sac", files, plots=not no_plots)
        out = outset.write(files, trial=agent.trial, seed=seed, runs=runs, wall_s=round(wall, 3))
    finally:
        outset.close()
    rate = metrics.get("success_rate")
    click.echo(
        f"{runs} SAC runs x {agent.trial} trials in {wall:.1f} s; "
        f"final mean return {_mean(agent.returns[:, -10:]):.1f}; "
        f"success rate {rate:.2f} (one evaluation start per run; monitor: {spec.monitor_formula}); results in {out}"
        if rate is not None
        else f"no trials run; results in {out}"
    )
    return out


def _monitor_judge(spec):
    """The policy search's judge: the monitor's verdict on rollouts of ``spec``'s monitor formula."""

    def judge(states: np.ndarray, dt: float, mean: bool = False):
        from mitlc.monitor.offline import monitor

        # the search reads no failing part; with score=mean it asks for the averaged robustness
        return monitor(spec, states, dt, spec.monitor_formula, blame=False, mean=mean)

    def credit(states: np.ndarray, dt: float):  # score=credit: the credit and the non-vacuous robustness
        from mitlc.monitor.offline import credit_score

        return credit_score(spec, states, dt, spec.monitor_formula)

    judge.credit = credit  # type: ignore[attr-defined]
    return judge


def _train_search(spec, rs, runs, trials, seed, out, assignments, quiet, no_plots, workers=1) -> Path:
    """``mitlc train --learner search``: :class:`mitlc.learn.search.SearchRuns` into an output set
    (search.npz, metrics.json as SACPN's, the plots); Ctrl-C saves nothing (no checkpoint to resume)."""
    from mitlc.learn.search import SearchRuns, SearchSettings, default_generations
    from mitlc.learn.settings import parse_assignments

    for w in rs.warnings:
        click.echo(w, err=True)
    try:
        from mitlc.cmaes import load

        load()  # the search's optimiser: say so before anything is written
    except ImportError:
        raise InputError(
            "the policy search runs CMA-ES from the cma package, a dependency of mitlc: pip install cma",
            file="--learner",
        ) from None
    settings = SearchSettings(**parse_assignments(SearchSettings, assignments))
    agent = SearchRuns(rs, runs, seed, settings, _monitor_judge(spec), workers=workers)
    trials = default_generations(agent.n_steps) if trials is None else trials
    outset = output_set(out, spec).open()
    try:
        return _search_into(outset, agent, spec, trials, quiet, no_plots)
    finally:
        outset.close()


def _search_into(outset, agent, spec, generations, quiet, no_plots, kept=None, raced=None, wall_before=0.0) -> Path:
    """Train the search ``agent`` for ``generations`` into the open ``outset``; the folder written.

    After a race the search won (``raced``: its record), ``kept`` are the race's trained runs
    ``0 .. r - 1`` and ``agent`` the runs after them (None: none left), joined once searched: the
    numbers of ``mitlc train --learner search`` with the same seed, to the bit. ``wall_before``: the
    race's time."""
    from mitlc.cli.progress import Progress
    from mitlc.learn.search import FILE

    runs = (0 if agent is None else agent.runs) + (0 if kept is None else kept.runs)
    stem = Path(spec.path or "spec").stem
    todo = generations if agent is not None else 0
    bar = Progress(todo, 0, desc=stem, unit="generation", quiet=quiet)
    start = time.perf_counter()

    def progress(done: int, total: int) -> None:
        interrupt.check()
        bar.update()

    def restarting(done: int, total: int) -> None:
        interrupt.check()
        if done == 1:  # the restarts' generations were not in the bar's total: they are now
            bar.extend(total)
        bar.update(f"restarts: generation {done}/{total}")

    try:
        interrupt.check()
        if agent is not None:
            agent.train(generations, progress)
        if kept is not None:
            agent = kept if agent is None else kept.joined(agent)
        agent.restart_failed(generations, restarting)  # the runs that failed their check, searched again
    except KeyboardInterrupt:
        bar.close()
        click.echo("interrupted: a search keeps no checkpoint, nothing saved", err=True)
        sys.exit(130)
    bar.close()
    wall = wall_before + time.perf_counter() - start
    files: dict[str, bytes | str] = {FILE: agent.file_bytes()}
    metrics = _runs_outputs(agent, spec, wall, "search", files, plots=not no_plots, raced=raced)
    out = outset.write(files, trial=agent.trial, seed=agent.seed, runs=runs, wall_s=round(wall, 3))
    rate = metrics.get("success_rate")
    restarted, took = sum(map(len, agent.restarted)), sum(map(len, agent.kept_restarts))
    again = f" ({restarted} restarted, {took} of them kept the restart)" if restarted else ""
    click.echo(
        f"{runs} searches x {agent.trial} generations{again} in {wall:.1f} s; "
        f"success rate {rate:.2f} (one evaluation start per run; monitor: {spec.monitor_formula}); results in {out}"
        if rate is not None
        else f"no generations run; results in {out}"
    )
    return out


def _runs_outputs(
    agent, spec, wall_s: float, learner: str, files: dict, plots: bool = True, raced: dict | None = None
) -> dict:
    """Add a SAC or search training's metrics.json (SACPN's keys where they mean the same) and plots
    to its output set ``files`` (its models or search file already in it); the metrics."""
    from mitlc.learn.plots import learning_curve, png_bytes

    metrics: dict = {
        "learner": learner,
        "spec": spec.path,
        "spec_source": spec.source or "",
        "formula": str(spec.formula),
        "check": str(spec.monitor_formula),
        "conjunction": agent.rs.options.conjunction,
        "violations": agent.rs.options.violations,
        "clock": agent.rs.options.clock,
        "reward": agent.rs.options.reward,
        "runs": agent.runs,
        "trials": agent.trial,
        "seed": agent.seed,
        "settings": agent.settings.to_dict(),
        "gamma": getattr(agent, "gamma", None),
        "wall_s": round(wall_s, 3),
        "run_steps": int(agent.runs * agent.trial * agent.n_steps),
        "interrupted": False,
        "diverged": [],
        "returns": agent.returns.round(6),
    }
    if learner == "search":  # its returns are each generation's best fitness (mitlc.learn.search.scores)
        metrics["returns_are"] = "the best candidate's fitness per generation"
        # per round, the runs that failed their check after the training and were searched again, and those
        # that took the restart's gains
        metrics["restarted"] = {"runs": agent.restarted, "kept": agent.kept_restarts}
    if raced is not None:
        metrics["race"] = raced
    if agent.trial > 0:
        _judge_greedy(agent, spec, metrics, files, plots)
        if plots:
            what = "SAC runs" if learner == "sac" else "searches (best fitness per generation)"
            fig = learning_curve(agent.returns, title=f"{Path(spec.path or 'spec').stem}: {agent.runs} {what}")
            files["learning_curve.png"] = png_bytes(fig)
    files["metrics.json"] = json_text(metrics)
    return metrics


def _same_folder(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve()
    except OSError:
        return False


def output_set(out: Path | None, spec, continuing: bool = False) -> OutputSet:
    """The output set of a training of ``spec`` into ``out`` (None: a new folder ``runs/<spec>_<N>``);
    its manifest names the spec and its plant, and a plant file's copy goes with it. ``continuing``:
    ``out`` is the folder whose checkpoint is resumed (see :class:`OutputSet`)."""
    from mitlc.cli.outputs import spec_record
    from mitlc.plants.user import plant_files, plant_record

    record = {**spec_record(spec), "plant": plant_record(spec.plant_name or "")}
    keep = plant_files(spec.plant_name or "")
    if out is None:
        return OutputSet.numbered(Path("runs"), Path(spec.path or "spec").stem, record=record, keep=keep)
    return OutputSet(out, record=record, keep=keep, continuing=continuing)


def _restore_plant(meta: dict, ckpt: Path) -> None:
    """Before a checkpoint's spec is parsed: its plant, from the run folder's copy of a plant file."""
    from mitlc.learn.checkpoint import restore_plant

    for note in restore_plant(meta, ckpt):
        click.echo(note, err=True)


def _wall_before(folder: Path) -> float:
    """Training seconds already spent on a checkpoint: its manifest's, else its metrics'."""
    from mitlc.cli.outputs import read_manifest

    manifest = read_manifest(folder) or {}
    for source in (manifest, _read_json(folder / "metrics.json")):
        value = source.get("wall_s")
        if isinstance(value, int | float) and np.isfinite(value) and value >= 0:
            return float(value)
    return 0.0


def _read_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):  # missing, not JSON, or nested past the parser's depth
        return {}
    return data if isinstance(data, dict) else {}


def _train_into(
    outset, agent, spec, trials, wall_before, checkpoint_every, quiet, no_plots, raced=None, live=None
) -> None:
    from mitlc.cli.progress import Progress, compile_notice

    out = outset.out
    todo = max(0, trials - agent.trial)
    bar = Progress(trials, agent.trial, desc=Path(spec.path or "spec").stem, quiet=quiet)

    start = time.perf_counter()
    saved = [start]
    warned: list[OSError] = []

    def progress(trial: int, returns: np.ndarray) -> None:
        interrupt.check()
        bar.update(f"mean return {_mean(agent.returns[:, -10:]):.1f}")
        if live is not None:  # curves.csv and the page of the training so far (mitlc.cli.reports.live)
            live(agent)
        now = time.perf_counter()
        if checkpoint_every and now - saved[0] >= checkpoint_every:  # kill -9 loses at most this much
            try:
                outset.checkpoint(
                    PARAMS,
                    agent.to_bytes(),
                    trial=agent.trial,
                    seed=agent.seed,
                    runs=agent.runs,
                    wall_s=round(wall_before + now - start, 3),
                )
            except OSError as exc:  # the folder keeps its last checkpoint; the results still go somewhere
                if not warned:
                    warned.append(exc)
                    click.echo(
                        f"warning: cannot write a checkpoint into {out} ({exc.strerror or exc}); training goes "
                        "on, and its results go to a fallback folder if the folder stays unwritable",
                        err=True,
                    )
            saved[0] = time.perf_counter()

    interrupted = False
    failed: TrainingError | None = None
    try:
        interrupt.check()  # a Ctrl-C during start-up that Python dropped
        with compile_notice(quiet):
            agent.train(todo, progress, total=trials)
    except KeyboardInterrupt:
        interrupted = True
    except TrainingError as exc:
        bar.close()
        if not (agent.diverged >= 0).all():
            raise
        failed = exc  # every run diverged: the set still records where, with their last finite parameters
    bar.close()
    wall = wall_before + time.perf_counter() - start
    try:
        files, metrics = _outputs(agent, spec, wall, interrupted, plots=not no_plots, raced=raced)
        out = outset.write(
            files, first=PARAMS, trial=agent.trial, seed=agent.seed, runs=agent.runs, wall_s=round(wall, 3)
        )
    except KeyboardInterrupt:  # while writing: the checkpoint goes first, so the training resumes from it
        try:
            outset.checkpoint(
                PARAMS, agent.to_bytes(), trial=agent.trial, seed=agent.seed, runs=agent.runs, wall_s=round(wall, 3)
            )
        except OSError as exc:
            raise InputError(
                f"interrupted after trial {agent.trial}, and the checkpoint cannot be written into {outset.out} "
                f"({exc.strerror or exc})",
                file="--out",
            ) from None
        interrupted, out = True, outset.out
    if interrupted:
        click.echo(
            f"interrupted after trial {agent.trial}; checkpoint in {out / PARAMS}\n"
            f"continue with: mitlc train --resume {out} --trials {trials}",
            err=True,
        )
        sys.exit(130)
    if failed is not None:
        raise TrainingError(
            f"{failed.message}; {out} keeps each run's last finite parameters and where it diverged",
            file=failed.file,
            hint=failed.hint,
        )
    if metrics["diverged"]:
        which = ", ".join(f"{d['run']} (trial {d['trial']})" for d in metrics["diverged"])
        click.echo(
            f"warning: {len(metrics['diverged'])} of {agent.runs} runs diverged (NaN or inf) and kept their last "
            f"finite parameters: run {which}; the others trained on (metrics.json: diverged). Lower the learning "
            "rates (alpha_a, alpha_c) or the exploration sigma",
            err=True,
        )
    rate = metrics.get("success_rate")
    click.echo(
        f"{agent.runs} runs x {agent.trial} trials in {wall:.1f} s; "
        f"final mean return {_mean(agent.returns[:, -10:]):.1f}; "
        f"success rate {rate:.2f} (one evaluation start per run; monitor: {spec.monitor_formula}); results in {out}"
        if rate is not None
        else f"no trials run; results in {out}"
    )


@click.command("simulate")
@click.option(
    "--policy",
    "policy_dirs",
    type=click.Path(exists=True),
    required=True,
    multiple=True,
    help="Directory written by 'mitlc train', or a Stable-Baselines3 model .zip trained on a mitlc "
    "environment (with --spec; needs the sb3 extra); repeat to run HyRL policies learned separately "
    "composed on --spec's combined automaton.",
)
@click.option(
    "--spec",
    "spec_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Spec (file or shipped name) to judge by and start from (default: the training spec; "
    "an SB3 model: the spec it was trained on, required).",
)
@click.option(
    "--rollouts",
    type=click.IntRange(1, 100000),
    default=None,
    help="Number of rollouts (default: one per trained run); rollout i uses run i mod runs.",
)
@click.option(
    "--seed",
    type=click.IntRange(0, 2**63 - 1),
    default=0,
    show_default=True,
    help="Seed of the fresh initial states (--starts fresh).",
)
@click.option(
    "--starts",
    type=click.Choice(["fresh", "train"]),
    default="fresh",
    show_default=True,
    help="fresh: --rollouts initial states drawn anew from the spec's initial set with --seed; train: the "
    "states 'mitlc train' judged its success rate on (each run's evaluation start; for HyRL, the evenly "
    "spaced initial states), which reproduces its number.",
)
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(),
    default=None,
    help="Write a figure of the first rollouts here (PNG); without it no figure is written.",
)
@click.option(
    "--trace",
    "trace_path",
    type=click.Path(),
    default=None,
    help="Also write each rollout as a trace that 'mitlc check' reads: FILE.csv or FILE.npz for one "
    "rollout, FILE_000.csv, FILE_001.csv, ... for several (.npz traces carry the inputs too: u, or u_NAME per input).",
)
@plant_file_option
@handle_errors
def simulate(policy_dirs, spec_path, rollouts, seed, starts, plot_path, trace_path) -> None:
    """Roll out a trained greedy policy from the spec's initial set and judge each rollout.

    By default from fresh initial states (--seed); --starts train judges on the states
    'mitlc train' judged its success rate on. HyRL policies (classical criteria) are judged
    by the checker; several of them run composed on --spec's combined automaton (thesis
    section 3-3-3)."""
    from mitlc.learn.checkpoint import recorded_spec
    from mitlc.learn.policy import load_sacpn
    from mitlc.learn.sacpn import read_meta

    _check_outputs(plot_path, trace_path)
    if any(Path(p).is_file() for p in policy_dirs):  # a Stable-Baselines3 model (mitlc.gym.Sb3Policy)
        _simulate_sb3(policy_dirs, spec_path, rollouts, seed, starts, plot_path, trace_path)
        return
    policy_dir = policy_dirs[0]
    ckpt = Path(policy_dir) / PARAMS
    kind = _read_json(Path(policy_dir) / "metrics.json").get("learner") if not ckpt.is_file() else None
    if kind in ("sac", "search"):
        if len(policy_dirs) > 1:
            raise InputError("only HyRL policies (classical criteria) run composed; give one policy", file="--policy")
        _simulate_sac(policy_dir, spec_path, rollouts, seed, starts, plot_path, trace_path, kind)
        return
    if not ckpt.is_file():
        raise InputError(
            f"no {PARAMS} in {policy_dir} (train first with 'mitlc train --out DIR')", file=str(policy_dir)
        )
    meta = read_meta(ckpt)
    if trace_path is not None and Path(trace_path).suffix.lower() not in (".csv", ".npz"):
        raise InputError("a trace is written as .csv or .npz", file=f"--trace {trace_path}")
    if meta.get("kind") == "hyrl":
        from mitlc.cli.hybrid import simulate_hybrid

        if trace_path is not None:
            raise InputError("--trace writes SACPN rollouts; a HyRL rollout is judged by criteria", file="--trace")
        simulate_hybrid(policy_dirs, spec_path, rollouts, seed, plot_path, starts)
        return
    if len(policy_dirs) > 1:
        raise InputError("only HyRL policies (classical criteria) run composed; give one SACPN policy", file="--policy")
    _restore_plant(meta, ckpt)
    spec = _load(spec_path) if spec_path is not None else recorded_spec(meta, ckpt)
    agent = load_sacpn(ckpt, meta, spec)
    if starts == "train" and rollouts not in (None, agent.runs):
        raise InputError(
            f"--starts train judges each of the {agent.runs} runs from its own evaluation start: "
            f"--rollouts must be {agent.runs} (or left out)",
            file="--rollouts",
        )
    n = rollouts or agent.runs
    if starts == "train":  # the states mitlc train judged on: the checkpoint's evaluation streams
        x0 = agent.evaluation_states()
        where = "each run's evaluation start, as mitlc train judged" + _trained_on(meta, spec)
    else:
        x0, where = _fresh_starts(agent, agent.sim.settable, n, seed)
    ro = agent.rollout(x0)
    res = _print_rollouts(spec, ro, x0, agent)
    k = int(res.satisfied.sum())
    click.echo(f"{k}/{n} rollouts satisfy {spec.monitor_formula} ({where})")
    if starts == "fresh" and spec.source == meta["spec_source"] and agent.trial > 0:
        judged = _judge(spec, agent.rollout(agent.evaluation_states())).satisfied
        if judged.mean() != k / n:  # mitlc train's number differs: say both, and on which starts
            click.echo(
                f"from each run's evaluation start, as mitlc train judged: {int(judged.sum())}/{agent.runs} "
                f"(success rate {judged.mean():.2f}; --starts train shows them)"
            )
    _write_traces(ro, agent.plant.state_names, trace_path, agent.plant)
    if plot_path is not None:
        atomic_write(plot_path, _rollout_png(agent, ro, res.satisfied, f"{k}/{n} satisfy"), f"--plot {plot_path}")


def _check_outputs(plot_path: str | None, trace_path: str | None) -> None:
    """Before any rollout: ``--plot`` and ``--trace`` can be written (a trace's suffix, its folder,
    the files themselves); one line naming the option and file otherwise."""
    if trace_path is not None and Path(trace_path).suffix.lower() not in (".csv", ".npz"):
        raise InputError("a trace is written as .csv or .npz", file=f"--trace {trace_path}")
    for option, path in (("--plot", plot_path), ("--trace", trace_path)):
        if path is not None:
            check_writable(path, f"{option} {path}")


def _trained_on(meta: dict, spec) -> str:
    """``''`` when ``spec`` is the one the policy was trained on, else a note that the verdicts are ``spec``'s."""
    return "" if spec.source == meta["spec_source"] else ", here by --spec"


def _runs_learner(folder, kind: str):
    """The learner of a ``--learner sac`` or ``--learner search`` training folder."""
    if kind == "search":
        from mitlc.learn.search import load_search

        return load_search(folder)
    try:
        from mitlc.gym import load_policy
    except ImportError:  # no Gymnasium
        raise InputError(
            "a --learner sac training is loaded by Stable-Baselines3: pip install 'mitlc[sb3]'", file=str(folder)
        ) from None
    agent = getattr(load_policy(folder), "learner", None)
    if agent is None:  # pragma: no cover - the caller saw metrics.json say sac; a folder changed since
        raise InputError("not a --learner sac training", file=str(folder))
    return agent


def _fresh_starts(agent, settable: bool, n: int, seed: int) -> tuple[np.ndarray, str]:
    """``n`` fresh starts for ``mitlc simulate`` and how they were drawn: from the init box, or (a plant that
    cannot be set, a Gymnasium environment) where its reset puts it, one seeded stream per rollout."""
    if settable:
        return _draw_starts(agent.init_ranges, n, seed), f"fresh starts drawn from the initial set, seed {seed}"
    x0 = agent.sample_init([np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(n)])
    return x0, f"fresh resets of the environment, seed {seed}"


def _draw_starts(init_ranges, n: int, seed: int) -> np.ndarray:
    """``n`` initial states ``(n, vars)`` drawn uniformly from the init box, seeded."""
    rng = np.random.default_rng(seed)
    x0 = np.empty((n, len(init_ranges)))
    for i, (lo, hi) in enumerate(init_ranges):
        x0[:, i] = rng.uniform(lo, hi, n)
    return x0


def _print_rollouts(spec, ro, x0: np.ndarray, policy):
    """Judge rollouts by the monitor and print a line per rollout; ``policy`` is what rolled them out
    (its ``plant``, ``runs`` and ``runtime``: a SACPN agent or a :class:`mitlc.gym.Sb3Policy`). The
    monitor's result."""
    res = _judge(spec, ro)
    names = policy.plant.state_names
    net = policy.runtime.net
    # the net's own record of violations (violations = permanent | counted): final tokens
    watched = [
        i
        for i, p in enumerate(net.places)
        if p.kind == "counter" or p.name.startswith(("p_violated_", "p_late_", "p_failed_"))
    ]
    final = policy.runtime.trace_markings(ro.codes)[:, -1] if watched else None
    for i in range(ro.states.shape[0]):
        start = ", ".join(f"{v}={x0[i, j]:.3f}" for j, v in enumerate(names))
        verdict = "satisfied" if res.satisfied[i] else f"VIOLATED at t={res.violation_time[i]:.2f} s ({res.failing[i]})"
        record = ""
        if final is not None:
            marked = [f"{net.places[j].name}={int(final[i, j])}" for j in watched if final[i, j]]
            record = f"; net records {', '.join(marked) if marked else 'no violation'}"
        click.echo(
            f"rollout {i:3d} (run {i % policy.runs:3d}, {start}): {verdict}; "
            f"robustness {res.robustness[i]:+.3f}; return {ro.returns[i]:.1f}{record}"
        )
    return res


def _write_traces(ro, names, trace_path, plant=None) -> None:
    """Each rollout as a trace ``mitlc check`` reads (``--trace``), and a line saying where. A ``.npz``
    trace carries the inputs too: ``u`` for a plant with one input bounded by ``u_max``, else
    ``u_NAME`` per input (``u_v``, ``u_omega``)."""
    if trace_path is None:
        return

    def inputs_of(actions: np.ndarray) -> dict[str, np.ndarray]:
        if plant is None or plant.inputs is None:
            return {"u": actions}
        cols = actions[:, None] if actions.ndim == 1 else actions
        return {f"u_{n}": cols[:, j] for j, n in enumerate(plant.input_names)}

    from mitlc.monitor.trace import write_trace

    n = ro.states.shape[0]
    base = Path(trace_path)
    paths = [base] if n == 1 else [base.with_name(f"{base.stem}_{i:03d}{base.suffix}") for i in range(n)]
    t = np.arange(ro.states.shape[1]) * ro.dt
    new = [p for p in paths if not p.exists()]
    written: list[Path] = []
    try:
        for i, p in enumerate(paths):
            cols = {v: ro.states[i, :, j] for j, v in enumerate(names)}
            write_trace(p, t, cols, inputs_of(ro.actions[i]))
            written.append(p)
    except MitlError:  # a failed write (a full disk): none of this command's new traces is left behind
        for p in written:
            if p in new:
                p.unlink(missing_ok=True)
        raise
    click.echo(f"wrote {n} trace{'s' if n > 1 else ''}: {paths[0]}{f' .. {paths[-1]}' if n > 1 else ''}")


def _simulate_sac(folder, spec_path, rollouts, seed, starts, plot_path, trace_path, kind: str = "sac") -> None:
    """``simulate`` of a ``mitlc train --learner sac`` (or ``search``) folder: its runs on the spec they
    were trained on (:func:`mitlc.gym.load_policy`, :func:`mitlc.learn.search.load_search`), judged and
    printed as a SACPN policy is."""
    agent = _runs_learner(folder, kind)
    trained = agent.spec
    spec = _load(spec_path) if spec_path is not None else trained
    if starts == "train" and rollouts not in (None, agent.runs):
        raise InputError(
            f"--starts train judges each of the {agent.runs} runs from its own evaluation start: "
            f"--rollouts must be {agent.runs} (or left out)",
            file="--rollouts",
        )
    n = rollouts or agent.runs
    if starts == "train":
        x0 = agent.evaluation_states()
        where = "each run's evaluation start, as mitlc train judged" + (
            "" if spec.source == trained.source else ", here by --spec"
        )
    else:  # a search on a Gymnasium environment starts where its reset puts it (SAC's runs are settable)
        x0, where = _fresh_starts(agent, getattr(agent, "settable", True), n, seed)
    ro = agent.rollout(x0)
    res = _print_rollouts(spec, ro, x0, agent)
    k = int(res.satisfied.sum())
    click.echo(f"{k}/{n} rollouts satisfy {spec.monitor_formula} ({where})")
    _write_traces(ro, agent.plant.state_names, trace_path, agent.plant)
    if plot_path is not None:
        atomic_write(plot_path, _rollout_png(agent, ro, res.satisfied, f"{k}/{n} satisfy"), f"--plot {plot_path}")


def _simulate_sb3(paths, spec_path, rollouts, seed, starts, plot_path, trace_path) -> None:
    """``simulate`` of a Stable-Baselines3 model: rolled out on --spec's plant by :class:`mitlc.gym.Sb3Policy`,
    judged, printed and written as traces by the same functions as a SACPN policy."""
    path = paths[0]
    if len(paths) > 1:
        raise InputError("only HyRL policies (classical criteria) run composed; give one policy", file="--policy")
    if Path(path).suffix.lower() != ".zip":
        raise InputError(
            "a policy is a directory written by 'mitlc train' or a Stable-Baselines3 model .zip",
            file=f"--policy {path}",
        )
    if trace_path is not None and Path(trace_path).suffix.lower() not in (".csv", ".npz"):
        raise InputError("a trace is written as .csv or .npz", file=f"--trace {trace_path}")
    if starts == "train":
        raise InputError(
            "a Stable-Baselines3 model keeps no training starts: judge it on fresh ones (--starts fresh)",
            file="--starts",
        )
    if spec_path is None:
        raise InputError(
            "a Stable-Baselines3 model does not record its spec: give the one it was trained on", file="--spec"
        )
    try:
        from mitlc.gym import load_sb3
    except ImportError:  # no Gymnasium
        raise InputError(
            "loading a Stable-Baselines3 model needs Stable-Baselines3: pip install 'mitlc[sb3]'", file=path
        ) from None
    spec = _load(spec_path)
    for w in spec.warnings:
        click.echo(w, err=True)
    policy = load_sb3(path, spec)
    n = rollouts or policy.runs
    x0 = _draw_starts(policy.init_ranges, n, seed)
    ro = policy.rollout(x0)
    res = _print_rollouts(spec, ro, x0, policy)
    k = int(res.satisfied.sum())
    where = f"fresh starts drawn from the initial set, seed {seed}"
    click.echo(f"{k}/{n} rollouts satisfy {spec.monitor_formula} ({where})")
    _write_traces(ro, policy.plant.state_names, trace_path, policy.plant)
    if plot_path is not None:
        atomic_write(plot_path, _rollout_png(policy, ro, res.satisfied, f"{k}/{n} satisfy"), f"--plot {plot_path}")
