"""``mitlc check SPEC TRACE``: judge one recorded trajectory with the monitor.

TRACE is a ``.csv`` file or a ``.npz`` archive, read by :mod:`mitlc.monitor.trace`.

Exit codes: 0 satisfied, 1 violated, 2 bad input (one clear line naming the
file, never a traceback).
"""

from __future__ import annotations

import click

from mitlc.cli.common import handle_errors, plant_file_option
from mitlc.errors import InputError, MitlError
from mitlc.fileio import json_text

__all__ = ["check"]


MAX_STEPPED_SAMPLES = 10_000
"""Most samples ``check --net`` steps one at a time: a net with timed obligations (nested intervals;
each step reads the whole trial so far, :class:`mitlc.runtime.obligations.TimedState`, so time grows with
the square of the trace's length) or one too large to tabulate (each step evaluates every guard).
10,000 samples take seconds; a tabulated net steps any trace (one look-up per sample)."""

MAX_STEPPED_WORK = 5_000_000
"""... and at most this much work: samples x (transitions + 10 x obligation nodes x (1 + samples /
3000)), what stepping costs (a transition a few microseconds a sample, an obligation node some 30,
and more as the trial it reads grows). 10,000 samples of ``pendulum/n3_bounded_response`` are 2.3
million (about 6 s); 101 samples of a net of 73,000 transitions and 22,000 obligation nodes would be
31 million (two and a half minutes)."""


def _stepping_work(rs, n: int) -> int:
    nodes = sum(len(tn.tree.nodes) for tn in rs.timed)
    return n * (len(rs.net.transitions) + 10 * nodes * (3000 + n) // 3000)


def _refuse_stepping(rs, n: int, why: str) -> None:
    """One line, if ``n`` samples of the net ``rs`` are more than --net steps one at a time."""
    if n <= MAX_STEPPED_SAMPLES and _stepping_work(rs, n) <= MAX_STEPPED_WORK:
        return
    if n > MAX_STEPPED_SAMPLES:
        most = f"at most {MAX_STEPPED_SAMPLES:,} samples"
    else:
        size = f"{len(rs.net.transitions):,} transitions"
        if rs.timed:
            size += f", {sum(len(tn.tree.nodes) for tn in rs.timed):,} obligation nodes"
        fits = next(m for m in range(n, 0, -1) if _stepping_work(rs, m) <= MAX_STEPPED_WORK or m == 1)
        most = f"at most {fits:,} samples of this net ({size})"
    raise InputError(
        f"the spec's net {why}: --net steps such a net one sample at a time, {most}, and the trace has {n:,} "
        "(check without --net, or a shorter trace)",
        file="--net",
    )


def _net_view(spec, tr, dt: float) -> dict:
    """Step the spec's net (violations recorded: the spec's mode, or permanent) over the trace."""
    import numpy as np

    from mitlc.monitor.offline import state_columns
    from mitlc.petri import reward as R
    from mitlc.petri import timed as T
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.plants.base import wrap_angle
    from mitlc.runtime import NetRuntime

    mode = None if spec.option("violations") != "off" else "permanent"
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=mode))
    cols = state_columns(spec)
    n = len(tr.t)
    timed = "has timed obligations (nested intervals), whose steps grow with the trace's length"
    if rs.timed:  # stepped one sample at a time whatever the tables: refused before they are built
        _refuse_stepping(rs, n, timed)
    x = np.stack([np.asarray(tr.columns.get(c, np.zeros(n)), dtype=float) for c in cols], axis=1)
    plant = spec.plant
    for i, c in enumerate(cols):
        if plant is not None and plant.var(c).periodic:
            x[:, i] = wrap_angle(x[:, i])
    rt = NetRuntime(rs, cols, dt=dt, steps=n - 1, tables_cache=True)  # kept on disk: built once per net
    watched: list[str] = []
    stack = [rs.charge] if rs.charge is not None else []
    while stack:
        e = stack.pop()
        if isinstance(e, R.Tokens):
            watched.extend(e.names)
        stack.extend(e.children)
    idx = [rs.net.place_index(p) for p in dict.fromkeys(watched)]
    first, violated = None, []
    codes = rt.trace_codes(x, np.arange(n) * dt)
    if codes is not None:  # every sample's propositions at once, a table look-up per sample
        k = _first_marked(rt, codes, idx)
        if k is not None:
            M = _marking_at(rt, codes, k)
            first, violated = float(tr.t[k]), [rs.net.places[i].name for i in idx if M[i]]
    else:  # the rule, sample by sample
        if not rs.timed:
            why = f"is too large to tabulate ({len(rs.net.places):,} places, {len(rt.atoms)} propositions)"
            _refuse_stepping(rs, n, why)
        M = rt.reset(x[:1])
        for k in range(n):
            if k:
                M = rt.step(M, x[k : k + 1], k * dt)
            marked = [rs.net.places[i].name for i in idx if M[0, i]]
            if marked and first is None:
                first, violated = float(tr.t[k]), marked
                if not rs.timed:  # nothing more to report (obligations' verdicts need the whole trace)
                    break
    words = {T.TRUE: "met", T.FALSE: "failed", T.PENDING: "pending"}
    verdicts = rt.verdicts()[0] if rs.timed else []
    return {
        "violation_time": first,
        "violated": violated,
        "obligations": [
            {"formula": str(tn.tree.formula), "verdict": words[int(v)]}
            for tn, v in zip(rs.timed, verdicts, strict=True)
        ],
    }


def _counter_tokens(rt, codes):
    """The counting places' tokens after each step, ``(N, C)`` (row ``k - 1``: at sample ``k``)."""
    import numpy as np

    assert rt.tables is not None
    return np.cumsum(rt.tables.counter_inc[codes[:-1], codes[1:]], axis=0)


def _first_marked(rt, codes, places: list[int]) -> int | None:
    """The first sample at which one of ``places`` holds a token, from the trace's marking codes."""
    import numpy as np

    if not places:
        return None
    counters = {int(p): j for j, p in enumerate(rt.counters.tolist())}
    one = [p for p in places if p not in counters]
    hit = np.zeros(len(codes), dtype=bool)
    if one:
        seen, where = np.unique(codes, return_inverse=True)
        hit |= np.asarray(np.isin(rt.marked_places(seen), one).any(axis=1))[where.reshape(-1)]
    counted = [counters[p] for p in places if p in counters]
    if counted and len(codes) > 1:
        hit[1:] |= (_counter_tokens(rt, codes)[:, counted] > 0).any(axis=1)
    return int(np.argmax(hit)) if hit.any() else None


def _marking_at(rt, codes, k: int):
    """The full marking ``(P,)`` at sample ``k`` (counting places: what the steps so far added)."""
    M = rt.decode(codes[k : k + 1])[0]
    if rt.counters.size and k:
        M[rt.counters] = _counter_tokens(rt, codes[: k + 1])[-1]
    return M


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
@click.option(
    "--net",
    "with_net",
    is_flag=True,
    help="Also step the spec's compiled reward net over the trace (the runtime the trainers and the Gymnasium "
    "wrapper use) and report what it recorded: the first violation of a watched part (as with --violations "
    "permanent) and the verdict of each timed obligation.",
)
@plant_file_option
@handle_errors
def check(spec: str, trace: str, formula_text: str | None, as_json: bool, with_net: bool) -> None:
    """Check a recorded TRACE (.csv or .npz) against SPEC (.mitl) with the MITL monitor.

    SPEC is a .mitl file or the name of a shipped spec (pendulum/p2_avoid; mitlc specs lists them).

    Prints the verdict, the robustness, the first time of violation and the
    failing subformula. Exit code 0 if satisfied, 1 if violated, 2 on bad input.
    """
    from mitlc.monitor.offline import judged_formula, monitor, needed_variables, state_columns
    from mitlc.monitor.trace import read_trace
    from mitlc.spec.parse import load_spec, parse_formula, with_inline_props

    s = load_spec(spec)
    judge = s  # the spec the monitor reads: with the inline predicates of --formula as propositions
    if formula_text is not None:
        try:
            formula = parse_formula(formula_text)
            judge = with_inline_props(s, formula)
            needed = needed_variables(judge, formula)
        except MitlError as exc:
            raise exc.located("--formula", formula_text) from None
    else:
        formula = judged_formula(s)
        needed = needed_variables(s, formula)
    if with_net:
        if s.formula is None:
            raise InputError("--net needs a spec with a 'formula' (its net is what the option runs)", file="--net")
        needed = tuple(dict.fromkeys((*needed, *needed_variables(s, s.formula))))
    tr, dt = read_trace(trace, needed, state_columns(s))
    # the time column too: a formula of constants reads no state, and the trace's length is still its length
    states = {"<time>": tr.t, **tr.columns}
    try:
        result = monitor(judge, states, dt, formula)
    except InputError as exc:
        raise exc.located(trace) from None
    ok = bool(result.satisfied[0])
    rob = float(result.robustness[0])
    # the time column's own value at the violating sample
    when = float(tr.t[int(round(result.violation_time[0] / dt))]) if not ok else None
    net = _net_view(s, tr, dt) if with_net else None
    if as_json:
        out = {
            "spec": spec,
            "trace": trace,
            "formula": str(formula),
            "satisfied": ok,
            "robustness": rob,  # null when infinite (no sample decides it)
            "violation_time": when,
            "failing": result.failing[0],
            "samples": int(len(tr.t)),
            "dt": dt,
        }
        if net is not None:
            out["net"] = net
        click.echo(json_text(out), nl=False)
    else:
        click.echo(f"{trace}: {'satisfied' if ok else 'VIOLATED'}")
        click.echo(f"  formula: {formula}")
        click.echo(f"  robustness: {rob:.6g}")
        if not ok:
            click.echo(f"  violated at: t = {when:g} s")
            click.echo(f"  failing: {result.failing[0]}")
        if net is not None:
            if net["violation_time"] is None:
                click.echo("  net: no violation recorded")
            else:
                where = ", ".join(net["violated"])
                click.echo(f"  net: violation recorded at t = {net['violation_time']:g} s in {where}")
            for o in net["obligations"]:
                click.echo(f"  net: {o['verdict']}: {o['formula']}")
    if not ok:
        click.get_current_context().exit(1)
