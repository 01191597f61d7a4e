"""``mitlc compile SPEC``: the reward net and reward of a spec, as text, JSON, DOT, a
picture or PNML."""

from __future__ import annotations

from collections.abc import Callable

import click

from mitlc.cli.common import compile_options, handle_errors, output_option, plant_file_option, write_result
from mitlc.errors import InputError

__all__ = ["compile_cmd", "FORMATS"]

FORMATS = ("text", "json", "dot", "svg", "png", "pnml")


@click.command("compile")
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option(
    "--format",
    "fmt",
    type=click.Choice(FORMATS),
    default="text",
    show_default=True,
    help="What to write: a readable summary, JSON, Graphviz DOT, a rendered picture, or PNML.",
)
@click.option(
    "--matrices",
    type=click.Choice(["auto", "dense", "arcs"]),
    default=None,
    help="With --format json: the incidence as arcs only, or the dense D-, D+ and D matrices too "
    "(default auto: dense up to 50,000 entries each, transitions x places).",
)
@output_option
@compile_options
@plant_file_option
@handle_errors
def compile_cmd(
    spec: str,
    fmt: str,
    matrices: str | None,
    output: str | None,
    conjunction: str | None,
    violations: str | None,
    clock: str | None,
    reward: str | None,
) -> None:
    """Compile SPEC (.mitl) into a reward Petri net and reward expression.

    SPEC is a .mitl file or the name of a shipped spec (pendulum/p2_avoid; mitlc specs lists them).
    """
    from mitlc.petri import export
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.spec.parse import load_spec

    if matrices is not None and fmt != "json":
        raise InputError(f"--matrices applies to --format json, not {fmt}", file="--matrices")
    s = load_spec(spec)
    for w in s.warnings:
        click.echo(w, err=True)
    options = CompileOptions.from_spec(s, conjunction=conjunction, violations=violations, clock=clock, reward=reward)
    rs = compile_spec(s, options)
    for w in rs.warnings:
        click.echo(w, err=True)
    from mitlc.petri.render import render_bytes, to_digraph

    makers: dict[str, Callable[[], str | bytes]] = {
        "text": lambda: export.to_text(rs),
        "json": lambda: export.to_json(rs, matrices or "auto"),
        "dot": lambda: to_digraph(rs).source,
        "pnml": lambda: export.to_pnml(rs),
        "svg": lambda: render_bytes(rs, "svg"),
        "png": lambda: render_bytes(rs, "png"),
    }
    write_result(output, fmt, makers[fmt])
