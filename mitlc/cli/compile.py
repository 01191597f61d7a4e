"""``mitlc compile SPEC``: the reward net and reward of a spec, as text, JSON, DOT, a
picture or PNML."""

from __future__ import annotations

import click

from mitlc.cli.common import atomic_write, handle_errors
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
    "-o",
    "--output",
    type=click.Path(dir_okay=False),
    default=None,
    help="Write to this file (atomically) instead of standard output.",
)
@click.option(
    "--conjunction",
    type=click.Choice(["literal", "active"]),
    default=None,
    help="How '&' combines gated terms (overrides the spec's option).",
)
@click.option(
    "--violations",
    type=click.Choice(["off", "permanent", "counted"]),
    default=None,
    help="Track violations of safety and deadline parts (overrides the spec's option).",
)
@handle_errors
def compile_cmd(spec: str, fmt: str, output: str | None, conjunction: str | None, violations: str | None) -> None:
    """Compile SPEC (.mitl) into a reward Petri net and reward expression."""
    from mitlc.petri import export
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.spec.parse import load_spec

    s = load_spec(spec)
    for w in s.warnings:
        click.echo(w, err=True)
    rs = compile_spec(s, CompileOptions.from_spec(s, conjunction=conjunction, violations=violations))
    from mitlc.petri.render import render_bytes, to_digraph

    if fmt in ("svg", "png"):
        if output is None:
            raise InputError(f"--format {fmt} needs -o FILE", file="--output")
        atomic_write(output, render_bytes(rs, fmt))
        return
    text = {
        "text": export.to_text,
        "json": export.to_json,
        "dot": lambda r: to_digraph(r).source,
        "pnml": export.to_pnml,
    }[fmt](rs)
    if output is None:
        click.echo(text, nl=not text.endswith("\n"))
    else:
        atomic_write(output, text)
