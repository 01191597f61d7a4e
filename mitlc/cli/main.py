"""The ``mitlc`` command line: thin click commands over the library.

Every user error becomes one clear line (plus the source line and a caret when
there is one) on stderr and exit code 2; never a traceback.
"""

from __future__ import annotations

import click

from mitlc import __version__
from mitlc.cli.common import atomic_write, handle_errors
from mitlc.errors import InputError

__all__ = ["main", "handle_errors", "atomic_write"]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="mitlc")
def main() -> None:
    """Compile MITL control specs into reward Petri nets, train and check controllers."""


FORMATS = ("text", "json", "dot", "svg", "png", "pnml")


@main.command("compile")
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("--format", "fmt", type=click.Choice(FORMATS), default="text", show_default=True,
              help="What to write: a readable summary, JSON, Graphviz DOT, a rendered picture, or PNML.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="Write to this file (atomically) instead of standard output.")
@click.option("--conjunction", type=click.Choice(["literal", "active"]), default=None,
              help="How '&' combines gated terms (overrides the spec's option).")
@click.option("--violations", type=click.Choice(["off", "permanent", "counted"]), default=None,
              help="Track violations of safety and deadline parts (overrides the spec's option).")
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
    if fmt in ("svg", "png"):
        from mitlc.petri.render import render_bytes

        if output is None:
            raise InputError(f"--format {fmt} needs -o FILE", file="--output")
        atomic_write(output, render_bytes(rs, fmt))
        return
    text = {
        "text": export.to_text,
        "json": export.to_json,
        "dot": lambda r: __import__("mitlc.petri.render", fromlist=["to_digraph"]).to_digraph(r).source,
        "pnml": export.to_pnml,
    }[fmt](rs)
    if output is None:
        click.echo(text, nl=not text.endswith("\n"))
    else:
        atomic_write(output, text)


# Commands from other stages register here, one line each.
# (keep this block: helpers add `main.add_command(...)` lines below)
from mitlc.cli.check import check  # noqa: E402
from mitlc.cli.hybrid import automaton, compose_cmd  # noqa: E402
from mitlc.cli.sweep import sweep  # noqa: E402
from mitlc.cli.train import simulate, train  # noqa: E402

for command in (check, train, simulate, sweep, automaton, compose_cmd):
    main.add_command(command)
