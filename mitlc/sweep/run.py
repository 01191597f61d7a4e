"""A whole sweep: the plan's tasks not yet in the store, run on a backend, each record stored as it arrives."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mitlc.sweep.backends import Backend, LocalBackend
from mitlc.sweep.grid import SweepPlan, Task
from mitlc.sweep.store import ResultStore

WRITE_BUDGET = 0.1
"""Largest fraction of a sweep's time spent rewriting the result files (see :func:`run_sweep`)."""


# ---------------------------------------------------------------- the sweep


@dataclass
class SweepOutcome:
    """What :func:`run_sweep` did."""

    total: int
    skipped: int
    """Tasks found already finished in the output directory."""
    finished: int
    """Tasks finished by this call."""
    failed: list[tuple[Task, BaseException]]
    records: dict[str, dict]
    """Every record of the plan's tasks, by task key."""
    wall_s: float


def run_sweep(
    plan: SweepPlan,
    out_dir: str | Path,
    backend: Backend | None = None,
    on_result: Callable[[Task, dict], None] | None = None,
    on_start: Callable[[int, int], None] | None = None,
) -> SweepOutcome:
    """Run every task of ``plan`` not yet recorded in ``out_dir``, recording each result as it arrives.

    ``on_start(total, already_done)`` is called once before any task runs,
    ``on_result(task, record)`` after each new record.  The files are
    rewritten after each new record, except that rewriting never takes more
    than :data:`WRITE_BUDGET` of the time: when results arrive faster than the
    files can be rewritten (thousands of records on a cluster), the records
    that arrive while waiting go into the next rewrite together, and any left
    are written before returning (also on an interrupt).  A task that raises
    (other than a diverging trainer, which is a result) is reported in
    ``failed`` and not recorded; running the sweep again retries it.
    """
    backend = backend or LocalBackend()
    by_key = {t.key: t for t in plan.tasks}
    start = time.perf_counter()
    with ResultStore(out_dir, plan.header, plan.axes) as store:
        store.write()  # the CSV follows the JSON even if an earlier sweep died between the two
        todo = [t for t in plan.tasks if t.key not in store]
        skipped = len(plan.tasks) - len(todo)
        if on_start is not None:
            on_start(len(plan.tasks), skipped)
        finished = 0
        failed: list[tuple[Task, BaseException]] = []
        next_write, cost = 0.0, 0.0
        try:
            if todo:
                for payload, result in backend.run([t.payload for t in todo]):
                    task = by_key[payload["key"]]
                    if isinstance(result, BaseException):
                        failed.append((task, result))
                        continue
                    if not store.add(result, write=False):
                        continue
                    finished += 1
                    now = time.monotonic()
                    if now >= next_write:
                        store.write()
                        cost = time.monotonic() - now
                        next_write = now + cost / WRITE_BUDGET
                    if on_result is not None:
                        on_result(task, result)
        finally:
            if store.dirty:
                store.write()
        records = {k: store.records[k] for k in by_key if k in store}
    return SweepOutcome(len(plan.tasks), skipped, finished, failed, records, time.perf_counter() - start)
