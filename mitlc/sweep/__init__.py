"""Many trainings: a spec trained over a grid of settings, weights and options.

In: a :class:`mitlc.spec.Spec`, grid axes (``NAME=V1,V2``), seeds. Out: one record per
task in a :class:`ResultStore` (``results.json``, ``results.csv``), summaries and a
heat map.

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`, :mod:`mitlc.plants`,
:mod:`mitlc.spec`, :mod:`mitlc.petri`, :mod:`mitlc.hybrid`, :mod:`mitlc.monitor`,
:mod:`mitlc.learn`.

A sweep is a set of **tasks**, one per configuration of the grid and seed.  A
task is a pure function of ``(spec text, configuration, seed, runs, trials)``:
:func:`run_task` parses the spec, rewrites its weights, compiles it, trains
``runs`` SACPN runs for ``trials`` trials and judges the final greedy policies
with the monitor.  The same task gives the same metrics on any backend.

One module a step: :mod:`~mitlc.sweep.grid` (axes, weights, the plan),
:mod:`~mitlc.sweep.task` (one task), :mod:`~mitlc.sweep.store` (results on disk),
:mod:`~mitlc.sweep.backends` (where tasks run), :mod:`~mitlc.sweep.run` (the sweep),
:mod:`~mitlc.sweep.summary` (tables and the heat map).
"""

from mitlc.sweep.backends import Backend, LocalBackend, RayBackend, WorkerLost, default_workers
from mitlc.sweep.grid import (
    Axis,
    SweepPlan,
    Task,
    WeightSite,
    format_value,
    parse_grid,
    plan_sweep,
    set_weights,
    sweepable_settings,
    weight_sites,
    with_weights,
)
from mitlc.sweep.run import SweepOutcome, run_sweep
from mitlc.sweep.store import ResultStore
from mitlc.sweep.summary import format_table, heatmap_figure, heatmap_grid, summarize
from mitlc.sweep.task import run_task

__all__ = [
    "Backend",
    "WeightSite",
    "weight_sites",
    "set_weights",
    "with_weights",
    "Axis",
    "parse_grid",
    "sweepable_settings",
    "Task",
    "SweepPlan",
    "plan_sweep",
    "run_task",
    "ResultStore",
    "LocalBackend",
    "RayBackend",
    "WorkerLost",
    "SweepOutcome",
    "run_sweep",
    "summarize",
    "format_table",
    "heatmap_grid",
    "heatmap_figure",
    "format_value",
    "default_workers",
]
