"""``mitlc report DIR``: a training's, a sweep's or a verification's folder as one self-contained HTML page.

``mitlc report runs/p2_avoid_1`` writes ``runs/p2_avoid_1/report.html``: the spec and its compiled
reward, the net with its marking along a run's greedy rollout (a slider and play), the state,
input and propositions beside it, every run's learning curve and their mean, the monitor's verdict
per run and the settings (:mod:`mitlc.cli.reports`). A sweep's folder gets its grid as a table and
a heat map of success; a verification's (``mitlc verify --out DIR``) its verdict, bound, search and
counterexamples with their figures. ``mitlc train``, ``mitlc sweep`` and ``mitlc verify`` write it at
their end (:func:`after_training`, :func:`after_sweep`, :func:`after_verification`) unless ``--no-report``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from mitlc.cli.common import handle_errors, plant_file_option
from mitlc.errors import InputError, MitlError
from mitlc.fileio import atomic_write

__all__ = [
    "report",
    "write_report",
    "after_command",
    "after_failed_training",
    "after_training",
    "after_sweep",
    "after_verification",
    "live_curves",
    "live_sweep",
    "folder_kind",
    "KINDS",
]


def _training(folder: Path) -> dict[str, Any]:
    from mitlc.cli.reports.training import training_data

    return training_data(folder)


def _sweep(folder: Path) -> dict[str, Any]:
    from mitlc.cli.reports.sweep import sweep_data

    return sweep_data(folder)


def _verification(folder: Path) -> dict[str, Any]:
    from mitlc.cli.reports.verification import verification_data

    return verification_data(folder)


def _is_verification(folder: Path) -> bool:
    from mitlc.cli.reports.verification import is_verification

    return is_verification(folder)


KINDS: dict[str, tuple[str, Callable[[Path], dict[str, Any]]]] = {
    "training": ("metrics.json", _training),
    "sweep": ("results.json", _sweep),
    "verification": ("report.json", _verification),
}
"""The folders a report is made of: kind -> (the file that marks such a folder, what gathers its page's
data, a dict whose ``kind`` picks the page's body in :data:`mitlc.cli.reports.page.BODIES`). Another
command's folder is an entry here and one there, and :func:`after_command` at its end. A marker of a
common name (``report.json``) marks the folder only when :data:`RECOGNISE` says its content is mitlc's."""

RECOGNISE: dict[str, Callable[[Path], bool]] = {"verification": _is_verification}
"""kind -> whether the folder's marker is really that command's (a user's ``report.json`` is not a
verification's)."""


def folder_kind(folder: Path) -> str:
    """What ``folder`` holds (a key of :data:`KINDS`); one line naming it otherwise."""
    if not folder.exists():
        raise InputError("no such folder", file=str(folder))
    if not folder.is_dir():
        raise InputError(
            "a file, not a folder: give the folder mitlc train, mitlc sweep or mitlc verify wrote", file=str(folder)
        )
    for kind, (marker, _) in KINDS.items():
        if (folder / marker).is_file() and RECOGNISE.get(kind, lambda _: True)(folder):
            return kind
    markers = [marker for marker, _ in KINDS.values()]
    raise InputError(
        "not a mitlc training, sweep or verification folder: it has neither "
        f"{', '.join(markers[:-1])} nor a {markers[-1]} of mitlc verify",
        file=str(folder),
    )


def write_report(folder: str | Path, kind: str | None = None) -> Path:
    """Write ``folder/report.html`` (atomically) and return its path: the page of the folder's kind
    (:func:`folder_kind`), or of ``kind``."""
    from mitlc.cli.reports import REPORT, report_html
    from mitlc.cli.reports.page import is_report

    folder = Path(folder)
    path = folder / REPORT
    kind = kind or folder_kind(folder)
    if path.exists() and not is_report(path):  # the user's file of that name: never replaced
        raise InputError(
            f"{REPORT} there is not a report mitlc wrote, and mitlc replaces only its own: move it away",
            file=str(path),
        )
    data = KINDS[kind][1](folder)
    atomic_write(path, report_html(data), str(path))
    return path


def after_training(out: Path | str | None, enabled: bool) -> None:
    """The end of ``mitlc train``: the folder's report written, or (``--no-report``) an earlier
    report of ours removed, since it shows a training the folder no longer holds. A report that
    cannot be made is a warning: the training's results are written already."""
    if out is None:
        return
    after_command(Path(out), enabled)


def after_sweep(out: Path | str, enabled: bool) -> None:
    """The end of ``mitlc sweep`` (or its interruption): as :func:`after_training`, for the sweep's
    folder; nothing when it holds no results yet (interrupted before the first task)."""
    if enabled and not (Path(out) / "results.json").is_file():
        return
    after_command(Path(out), enabled)


def after_verification(out: Path | str | None, enabled: bool) -> None:
    """The end of ``mitlc verify --out DIR``: the verification's page written in ``DIR``, or
    (``--no-report``) a page of an earlier verification there removed. A folder that holds a training's
    or a sweep's results too keeps its page (a warning says so); a ``report.html`` mitlc did not write
    is never touched; a report that cannot be made is a warning (report.json is written already)."""
    from mitlc.cli.reports import REPORT
    from mitlc.cli.reports.verification import is_verification_page

    if out is None:
        return
    out = Path(out)
    if not enabled:
        if is_verification_page(out / REPORT):
            (out / REPORT).unlink(missing_ok=True)
        return
    try:
        kind = folder_kind(out)
    except MitlError:
        kind = None
    if kind not in (None, "verification"):
        click.echo(
            f"warning: no report: {out} holds a {kind}'s results, whose page it keeps "
            "(give the verification a folder of its own)",
            err=True,
        )
        return
    after_command(out, True)


def live_sweep(out: Path, enabled: bool):
    """What ``mitlc sweep`` calls after each finished task (:class:`mitlc.cli.reports.live.LiveSweep`):
    the page of the sweep so far, kept up in ``out``; None without a report."""
    if not enabled:
        return None
    from mitlc.cli.reports.live import LiveSweep

    return LiveSweep(out)


def live_curves(out: Path, spec: object, total: int, enabled: bool):
    """What ``mitlc train`` calls after each trial (:class:`mitlc.cli.reports.live.LiveCurves`):
    ``curves.csv`` and the page of the training in progress, kept up in ``out``; None without a report."""
    if not enabled:
        return None
    from mitlc.cli.reports.live import LiveCurves

    return LiveCurves(out, Path(str(getattr(spec, "path", None) or "spec")).name, total)


def after_failed_training(out: Path, live: Any) -> None:
    """A training that wrote no set into ``out`` (it failed, or its set went to a rescue folder): what
    its :func:`live_curves` wrote there is put right. The folder's report is made again from what the
    folder holds (an earlier training's set), or removed when it holds none; the curves, this
    training's, go."""
    from mitlc.cli.reports import REPORT
    from mitlc.cli.reports.live import CURVES, is_ours
    from mitlc.cli.reports.page import is_report

    if live is None or live.written < 0:  # it wrote nothing there
        return
    if is_ours(out / CURVES):
        (out / CURVES).unlink(missing_ok=True)
    try:
        write_report(out)
    except Exception:  # no earlier training there (or none a report can be made of): no report
        if is_report(out / REPORT):
            (out / REPORT).unlink(missing_ok=True)


def after_command(out: Path, enabled: bool) -> None:
    """The end of a command that wrote the folder ``out`` (of a kind in :data:`KINDS`): its report
    written, or, ``enabled`` false, what an earlier run left of ours removed."""
    from mitlc.cli.reports import REPORT
    from mitlc.cli.reports.live import CURVES, is_ours
    from mitlc.cli.reports.page import is_report

    path = out / REPORT
    if not enabled:  # what an earlier training of the folder left shows a training it no longer holds
        if is_report(path):
            path.unlink(missing_ok=True)
        if is_ours(out / CURVES):
            (out / CURVES).unlink(missing_ok=True)
        return
    try:
        write_report(out)
    except Exception as exc:  # the results are written: say it, and leave no report of another training
        if isinstance(exc, MitlError):
            click.echo(f"warning: no report: {exc.render()}", err=True)
        else:  # a bug of the report's
            click.echo(
                f"warning: no report: {type(exc).__name__}: {exc} (please report it; mitlc report {out} tries again)",
                err=True,
            )
        try:
            if is_report(path):
                path.unlink()
        except OSError:
            pass


@click.command("report")
@click.argument("folder", metavar="DIR", type=click.Path(file_okay=True, dir_okay=True))
@plant_file_option
@handle_errors
def report(folder: str) -> None:
    """Write DIR/report.html: a training's, a sweep's or a verification's folder as one HTML page.

    A training's page shows the spec and its compiled reward, the net with its marking along a
    run's greedy rollout (slider and play), the state, input and propositions, the learning curves,
    the monitor's verdict per run and the settings; a sweep's shows its grid and a heat map of
    success; a verification's (mitlc verify --out DIR) its verdict, bound, search and counterexamples
    with their figures. One file, opened by double-click: no network."""
    start = time.perf_counter()
    path = write_report(folder)
    click.echo(f"wrote {path} in {time.perf_counter() - start:.1f} s")
