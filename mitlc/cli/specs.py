"""``mitlc specs``: the specs that ship with mitlc, by name.

Every command that takes a spec takes one of these names (``pendulum/p2_avoid``) as
well as a path; ``mitlc specs NAME`` prints the spec, to copy and edit.
"""

from __future__ import annotations

import click

from mitlc.cli.common import handle_errors
from mitlc.errors import InputError

__all__ = ["specs"]


@click.command("specs")
@click.argument("name", required=False)
@handle_errors
def specs(name: str | None) -> None:
    """List the shipped specs, or print the one called NAME (e.g. pendulum/p2_avoid).

    Every command that takes a SPEC accepts these names as well as a path to a
    .mitl file; a file of that name wins.
    """
    from mitlc.spec.library import find, shipped_specs

    if name is not None:
        shipped = find(name)
        if shipped is None:
            raise InputError(f"no shipped spec '{name}' (known: {', '.join(shipped_specs())})", file="mitlc specs")
        click.echo(shipped.read_text(), nl=False)
        return
    table = shipped_specs()
    width = max((len(n) for n in table), default=0)
    for n, s in table.items():
        click.echo(f"{n.ljust(width)}  {s.summary()}")
