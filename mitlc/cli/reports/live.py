"""A long training, watched as it goes: its learning curves written while it trains.

:class:`LiveCurves` is called after every trial of ``mitlc train`` (SACPN) and, at most every
:data:`EVERY_S` seconds (and after the last trial), appends the new trials' returns to
``curves.csv`` in the training's folder and rewrites ``report.html`` as a page of the training in
progress: its learning curves so far, reloaded by the browser every :data:`RELOAD_S` seconds (a
page opened from a file cannot read the folder's other files, so the page itself is what is
rewritten). When the training ends, ``mitlc train`` writes the full report over it.

A sweep's page is kept up the same way (:class:`LiveSweep`), from the ``results.json`` the sweep
writes as its tasks finish.

``curves.csv`` is a scalars file any viewer can follow (``tail -f``, a spreadsheet, pandas): a
first comment line that says what it is, a header ``trial,run_0,...,run_{R-1}``, then one line
per trial (1-based) with each run's return (``nan`` where a run diverged).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.fileio import atomic_write

__all__ = ["LiveCurves", "LiveSweep", "CURVES", "MARK", "EVERY_S", "RELOAD_S", "is_ours"]

CURVES = "curves.csv"
MARK = "# mitlc learning curves:"
"""The first line of a ``curves.csv`` mitlc writes (what :func:`is_ours` looks for)."""

EVERY_S = 10.0
"""Seconds between two writes of the curves and the page while a training runs."""

RELOAD_S = 15
"""Seconds after which the page of a training in progress reloads itself."""


def is_ours(path: Path) -> bool:
    """Whether ``path`` is a ``curves.csv`` mitlc wrote (so mitlc may replace or remove it)."""
    try:
        with path.open("rb") as f:
            return f.read(len(MARK)) == MARK.encode()
    except OSError:
        return False


def _rows(returns: np.ndarray, first: int, last: int) -> str:
    """Lines ``trial,r0,r1,...`` for the trials ``first .. last - 1`` (0-based) of ``returns`` ``(R, T)``."""
    return "".join(
        f"{t + 1}," + ",".join(f"{v:.6g}" for v in returns[:, t].tolist()) + "\n" for t in range(first, last)
    )


class LiveCurves:
    """The curves and the page of one training into ``out``, kept up as it trains.

    ``title`` names the spec on the page; ``total`` is the trials the training runs to. Failures to
    write (a full disk) are left to the training's own checkpoints to report: the curves are a view."""

    def __init__(self, out: Path, title: str, total: int, every_s: float = EVERY_S) -> None:
        self.out = Path(out)
        self.title = title
        self.total = int(total)
        self.every_s = float(every_s)
        self.written = -1
        """Trials in ``curves.csv`` so far (-1: not written yet by this training)."""
        self.last = time.monotonic()

    def __call__(self, agent: Any) -> None:
        """After a trial of ``agent`` (its ``returns`` ``(R, trials so far)``): write when it is time."""
        returns = np.asarray(agent.returns, dtype=float)
        done = returns.shape[1]
        now = time.monotonic()
        if done < self.total and now - self.last < self.every_s:
            return
        self.last = now
        try:
            self.write(returns)
        except (OSError, ValueError):  # pragma: no cover - a full disk: the checkpoint's warning says it
            pass

    def write(self, returns: np.ndarray) -> None:
        """``curves.csv`` brought up to ``returns`` ``(R, T)`` (the first time whole, then appended to),
        and the page of the training in progress."""
        from mitlc.cli.reports.page import REPORT, is_report, report_html
        from mitlc.cli.reports.training import progress_data

        path = self.out / CURVES
        runs, done = returns.shape
        if path.exists() and not is_ours(path):  # the user's file of that name: never replaced
            self.written = max(self.written, 0)
        elif self.written < 0 or not is_ours(path):
            head = f"{MARK} the return of each run per trial, as mitlc train goes\n"
            head += "trial," + ",".join(f"run_{r}" for r in range(runs)) + "\n"
            atomic_write(path, head + _rows(returns, 0, done), str(path))
        elif done > self.written:
            with path.open("a", encoding="utf-8") as f:
                f.write(_rows(returns, self.written, done))
        self.written = done
        page = self.out / REPORT
        if not page.exists() or is_report(page):
            html = report_html(progress_data(self.out, self.title, returns, self.total, RELOAD_S))
            atomic_write(page, html, str(page))


class LiveSweep:
    """The page of a sweep in progress, kept up in its folder ``out``: after a task finishes, at most
    every ``every_s`` seconds (the first time ``every_s`` after the sweep started), ``report.html`` is
    made from the ``results.json`` written so far, and reloads itself every :data:`RELOAD_S` seconds;
    ``mitlc sweep`` writes the final page over it at its end."""

    def __init__(self, out: Path, every_s: float = EVERY_S) -> None:
        self.out = Path(out)
        self.every_s = float(every_s)
        self.last = time.monotonic()

    def __call__(self) -> None:
        from mitlc.cli.reports.page import REPORT, is_report, report_html
        from mitlc.cli.reports.sweep import sweep_data
        from mitlc.errors import MitlError

        now = time.monotonic()
        if now - self.last < self.every_s:
            return
        self.last = now
        page = self.out / REPORT
        if not (self.out / "results.json").is_file() or (page.exists() and not is_report(page)):
            return
        try:
            data = sweep_data(self.out)
            data["reload_s"] = RELOAD_S
            atomic_write(page, report_html(data), str(page))
        except (OSError, ValueError, MitlError):  # pragma: no cover - a full disk: the sweep's own writes say it
            pass


def read_curves(path: Path) -> np.ndarray:
    """The returns ``(R, T)`` a ``curves.csv`` holds (what a viewer reads back)."""
    lines = [ln for ln in path.read_text(encoding="utf-8").splitlines() if ln and not ln.startswith("#")]
    rows = [[float(v) for v in ln.split(",")[1:]] for ln in lines[1:]]
    return np.array(rows, dtype=float).T if rows else np.zeros((0, 0))
