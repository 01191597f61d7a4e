"""``mitlc sweep``: a thin click command over :mod:`mitlc.sweep`.

``mitlc sweep SPEC --grid sigma=1,2,3 --grid weight.psi=1,3,10 --seeds 3``
trains every configuration of the grid with every seed, one task each, on a
local process pool (default) or on Ray, and writes to ``--out`` (default
``runs/sweep_<spec name>``) ``results.csv`` and ``results.json`` after every
finished task, then ``sweep.png`` (success rate over the first two swept axes)
and a summary table.  Running the same command again skips finished tasks.
``mitlc sweep SPEC --list`` prints every name the grid accepts.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from mitlc.cli.common import atomic_write, handle_errors, plant_file_option
from mitlc.errors import InputError
from mitlc.spec.model import OPTIONS

__all__ = ["sweep"]


def _list(spec) -> str:
    """Every grid name: weights with their subformulas, options, trainer settings; current values."""
    from mitlc.learn.sacpn import SacpnSettings
    from mitlc.spec.model import OPTIONS
    from mitlc.sweep import format_value, sweepable_settings, weight_sites

    lines = [f"{spec.path}: formula {spec.formula}", "", "weights (value: the weighted subformula):"]
    sites = weight_sites(spec.formula)
    width = max([len(s.axis) for s in sites] + [len("option.conjunction")])
    lines += [f"  {s.axis.ljust(width)}  {format_value(s.value):>6}: {s.text}" for s in sites] or [
        "  none (write 'w * phi' in the formula to make a weight sweepable)"
    ]
    lines += ["", "compile options (value: allowed values):"]
    lines += [f"  {('option.' + k).ljust(width)}  {spec.option(k):>6}: {', '.join(v)}" for k, v in OPTIONS.items()]
    lines += ["", "trainer settings (SacpnSettings; value):"]
    defaults = SacpnSettings() if spec.plant is None else SacpnSettings().resolved(spec.plant)  # rbf: this plant's
    meaning = {
        "sigma": ("sigma_frac x u_max", lambda: defaults.sigma_frac * spec.param("u_max")),
        "trial_s": ("the spec's horizon", lambda: spec.horizon if spec.horizon is not None else 3.0),
        "dt": ("the plant's dt", lambda: spec.param("dt")),
        "gamma": ("1 - 3 / the trial's steps", lambda: _gamma(spec)),
    }
    if spec.plant is not None and spec.plant.inputs is not None:  # one sigma per input, none to show here
        meaning["sigma"] = ("sigma_frac x each input's half-range; one sigma per input", _no_value)
    for name in sweepable_settings():
        value = getattr(defaults, name)
        note = ""
        if value is None and name in meaning:
            try:
                note = f" ({meaning[name][0]}: {format_value(meaning[name][1]())})"
            except KeyError:
                note = f" ({meaning[name][0]})"
        shown = "none" if value == () else format_value(value)
        lines.append(f"  {name.ljust(width)}  {shown}{note}")
    return "\n".join(lines)


def _gamma(spec) -> float:
    """The discount SACPN takes by default on ``spec``: ``1 - 3 / N`` for its trial of N steps."""
    from mitlc.learn.sacpn.sacpn import default_gamma
    from mitlc.limits import check_steps

    horizon = spec.horizon if spec.horizon is not None else 3.0
    return default_gamma(check_steps(horizon, spec.param("dt"), "a trial"))


def _no_value() -> float:
    """A default that is no one number (:func:`_list` then shows only what it means)."""
    raise KeyError("none")


@click.command("sweep")
@click.argument("spec_path", metavar="SPEC", type=click.Path(dir_okay=False))
@click.option(
    "--grid",
    "grid",
    multiple=True,
    metavar="NAME=V1,V2,...",
    help="An axis of the grid: a trainer setting (sigma=1,2,3), a weight (weight.psi=1,3,10) or a "
    "compile option (option.violations=off,permanent). Repeat for more axes; --list shows the names.",
)
@click.option(
    "--seeds", type=click.IntRange(1, 10000), default=3, show_default=True, help="Seeds 0..N-1 for every configuration."
)
@click.option(
    "--runs",
    type=click.IntRange(1, 10000),
    default=30,
    show_default=True,
    help="Runs per task (trained together, as in mitlc train).",
)
@click.option("--trials", type=click.IntRange(1, 10**7), default=500, show_default=True, help="Trials per run.")
@click.option(
    "--backend",
    type=click.Choice(["local", "ray"]),
    default="local",
    show_default=True,
    help="local: a process pool on this machine. ray: Ray tasks (pip install 'mitlc[ray]').",
)
@click.option(
    "--address",
    default=None,
    help="Ray cluster to use (auto, HOST:6379, ray://HOST:10001); default RAY_ADDRESS, else a local "
    "Ray for this command.",
)
@click.option(
    "--workers",
    type=click.IntRange(1, 4096),
    default=None,
    help="Processes (local) or CPUs of the local Ray; default min(2, cores).",
)
@click.option(
    "--max-retries",
    type=click.IntRange(0, 100),
    default=3,
    show_default=True,
    help="Times a task is run again when its worker dies.",
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(file_okay=False),
    default=None,
    help="Output directory (default runs/sweep_<spec name>); re-running skips the tasks done there.",
)
@click.option(
    "--clock",
    type=click.Choice(OPTIONS["clock"]),
    default=None,
    help="standard or trial reading of nested intervals for every task (the same as --grid option.clock=VALUE).",
)
@click.option("--list", "list_only", is_flag=True, help="Print every grid name with its current value and exit.")
@click.option("--no-plot", is_flag=True, help="Skip sweep.png (and the report).")
@click.option("--no-report", is_flag=True, help="Skip report.html, the sweep as one HTML page (mitlc docs report).")
@click.option(
    "-q", "--quiet", is_flag=True, help="No progress on stderr (a bar on a terminal, else a line per 5 % of the tasks)."
)
@plant_file_option
@handle_errors
def sweep(
    spec_path,
    grid,
    seeds,
    runs,
    trials,
    backend,
    address,
    workers,
    max_retries,
    out_dir,
    clock,
    list_only,
    no_plot,
    quiet,
    no_report,
) -> None:
    """Train SPEC over a grid of trainer settings, weights and options, several seeds each.

    SPEC is a .mitl file or the name of a shipped spec (pendulum/p2_avoid; mitlc specs lists them).
    """
    from mitlc.cli.memory import keep_freed_memory

    keep_freed_memory()
    from mitlc.cli.progress import Progress
    from mitlc.learn.plots import png_bytes
    from mitlc.spec.parse import load_spec
    from mitlc.sweep import (
        LocalBackend,
        RayBackend,
        format_table,
        heatmap_figure,
        plan_sweep,
        run_sweep,
        summarize,
    )

    spec = load_spec(spec_path)
    for w in spec.warnings:
        click.echo(w, err=True)
    if clock is not None:
        grid = (*grid, f"option.clock={clock}")
    if list_only:
        click.echo(_list(spec))
        return
    if address and backend != "ray":
        raise InputError("--address is for --backend ray", file="--address")
    plan = plan_sweep(spec, grid, range(seeds), runs, trials)
    out = Path(out_dir or Path("runs") / f"sweep_{Path(spec_path).stem}")

    def on_retry(payload: dict, attempt: int) -> None:
        click.echo(
            f"a worker died; running task {payload['key']} again (attempt {attempt} of {max_retries + 1})", err=True
        )

    engine = (
        RayBackend(address, workers, max_retries)
        if backend == "ray"
        else LocalBackend(workers, max_retries, on_retry=on_retry)
    )
    if isinstance(engine, RayBackend):
        engine.check()  # a clear error before anything runs: Ray installed, and an address where it answers

    bar: dict[str, Any] = {}
    from mitlc.cli.report import after_sweep, live_sweep

    report = not (no_report or no_plot)
    live = live_sweep(out, report)  # the page of the tasks finished so far (mitlc docs report)

    def on_start(total: int, done: int) -> None:
        click.echo(
            f"{total} tasks ({plan.n_configs} configurations x {len(plan.seeds)} seeds, "
            f"{runs} runs x {trials} trials each); {done} already in {out}; running on {engine.describe()}",
            err=True,
        )
        bar["bar"] = Progress(total, done, desc=Path(spec_path).stem, unit="task", quiet=quiet)

    def on_result(task, record) -> None:
        shown = " ".join(f"{a.name}={v}" for a, v in zip(plan.axes, task.labels, strict=True))
        rate = record["success_rate"]
        bar["bar"].update(f"{shown} seed {task.seed}: " + (f"success {rate:.2f}" if rate is not None else "diverged"))
        if live is not None:
            live()

    try:
        outcome = run_sweep(plan, out, engine, on_result=on_result, on_start=on_start)
    except KeyboardInterrupt:
        if "bar" in bar:
            bar["bar"].close()
        after_sweep(out, report)  # the page of the finished tasks, not one that reloads
        click.echo(
            f"interrupted; finished tasks are in {out / 'results.csv'}; run the same command to continue", err=True
        )
        sys.exit(130)
    finally:
        if "bar" in bar:
            bar["bar"].close()

    rows = summarize(plan, outcome.records)
    click.echo(format_table(plan, rows))
    if not no_plot:
        fig = heatmap_figure(plan, outcome.records)
        if fig is not None:
            atomic_write(out / "sweep.png", png_bytes(fig))
    after_sweep(out, report)
    click.echo(
        f"{outcome.finished} tasks run in {outcome.wall_s:.1f} s, {outcome.skipped} done earlier; results in {out}"
    )
    if outcome.failed:
        for task, exc in outcome.failed:
            shown = " ".join(f"{a.name}={v}" for a, v in zip(plan.axes, task.labels, strict=True))
            click.echo(
                f"error: task {task.key} ({shown} seed {task.seed}) failed: {type(exc).__name__}: {exc}", err=True
            )
        click.echo(f"{len(outcome.failed)} task(s) failed; run the same command to retry them", err=True)
        sys.exit(1)
