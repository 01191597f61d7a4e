"""``mitlc check SPEC TRACE``: judge one recorded trajectory with the monitor.

TRACE is a ``.csv`` file or a ``.npz`` archive, read by :mod:`mitlc.monitor.trace`.

Exit codes: 0 satisfied, 1 violated, 2 bad input (one clear line naming the
file, never a traceback).
"""

from __future__ import annotations

import json
import math

import click

from mitlc.cli.common import handle_errors
from mitlc.errors import InputError, MitlError

__all__ = ["check"]


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@click.command("check")
@click.argument("spec", type=click.Path(dir_okay=False))
@click.argument("trace", type=click.Path(dir_okay=False))
@click.option(
    "--formula",
    "formula_text",
    default=None,
    metavar="TEXT",
    help="Check this formula (over the spec's propositions) instead of the spec's.",
)
@click.option("--json", "as_json", is_flag=True, help="Print the result as one JSON object.")
@handle_errors
def check(spec: str, trace: str, formula_text: str | None, as_json: bool) -> None:
    """Check a recorded TRACE (.csv or .npz) against SPEC (.mitl) with the MITL monitor.

    Prints the verdict, the robustness, the first time of violation and the
    failing subformula. Exit code 0 if satisfied, 1 if violated, 2 on bad input.
    """
    from mitlc.monitor.offline import judged_formula, monitor, needed_variables, state_columns
    from mitlc.monitor.trace import read_trace
    from mitlc.spec.parse import load_spec, parse_formula

    s = load_spec(spec)
    if formula_text is not None:
        try:
            formula = parse_formula(formula_text)
            needed = needed_variables(s, formula)
        except MitlError as exc:
            raise exc.located("--formula", formula_text) from None
    else:
        formula = judged_formula(s)
        needed = needed_variables(s, formula)
    tr, dt = read_trace(trace, needed, state_columns(s))
    try:
        result = monitor(s, tr.columns, dt, formula)
    except InputError as exc:
        raise exc.located(trace) from None
    ok = bool(result.satisfied[0])
    rob = float(result.robustness[0])
    # the time column's own value at the violating sample
    when = float(tr.t[int(round(result.violation_time[0] / dt))]) if not ok else None
    if as_json:
        click.echo(
            json.dumps(
                {
                    "spec": spec,
                    "trace": trace,
                    "formula": str(formula),
                    "satisfied": ok,
                    "robustness": _finite_or_none(rob),
                    "violation_time": when,
                    "failing": result.failing[0],
                    "samples": int(len(tr.t)),
                    "dt": dt,
                }
            )
        )
    else:
        click.echo(f"{trace}: {'satisfied' if ok else 'VIOLATED'}")
        click.echo(f"  formula: {formula}")
        click.echo(f"  robustness: {rob:.6g}")
        if not ok:
            click.echo(f"  violated at: t = {when:g} s")
            click.echo(f"  failing: {result.failing[0]}")
    if not ok:
        click.get_current_context().exit(1)
