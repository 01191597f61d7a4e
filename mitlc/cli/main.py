"""The ``mitlc`` command group: the commands of every family, gathered.

Every user error becomes one clear line (plus the source line and a caret when
there is one) on stderr and exit code 2; never a traceback (:mod:`mitlc.cli.common`).
"""

from __future__ import annotations

import sys
from typing import Any

import click

from mitlc import __version__
from mitlc.cli.check import check
from mitlc.cli.compile import compile_cmd
from mitlc.cli.hybrid import automaton, compose_cmd
from mitlc.cli.plants import plants
from mitlc.cli.specs import specs
from mitlc.cli.sweep import sweep
from mitlc.cli.train import simulate, train

__all__ = ["main"]


class _Group(click.Group):
    """click's own errors (a bad option value, a directory given as SPEC, a missing argument) in
    mitlc's one-line format, exit 2; Ctrl-C before a command's own handling, exit 130."""

    def main(
        self,
        args: Any = None,
        prog_name: Any = None,
        complete_var: Any = None,
        standalone_mode: bool = True,
        **extra: Any,
    ) -> Any:
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode, **extra)
        try:
            rv = super().main(args, prog_name, complete_var, False, **extra)
        except click.exceptions.ClickException as exc:
            click.echo(_one_line(exc), err=True)
            sys.exit(2 if exc.exit_code in (None, 1) else exc.exit_code)
        except (click.exceptions.Abort, KeyboardInterrupt):
            click.echo("interrupted", err=True)
            sys.exit(130)
        sys.exit(rv if isinstance(rv, int) else 0)


def _one_line(exc: click.exceptions.ClickException) -> str:
    """``--out: error: ...``, ``SPEC: error: ...`` or ``mitlc train: error: ...``, and where help is."""
    ctx = getattr(exc, "ctx", None)
    where = ctx.command_path if ctx is not None else "mitlc"
    message = " ".join(exc.format_message().split())
    param = getattr(exc, "param", None)
    if isinstance(exc, click.BadParameter) and param is not None and ctx is not None:
        where = param.get_error_hint(ctx).strip("'").split(" / ")[0]
        if not isinstance(exc, click.MissingParameter):  # its message is empty: keep click's "Missing ..."
            message = " ".join(exc.message.split())
    help_of = f" ({ctx.command_path} --help)" if ctx is not None and isinstance(exc, click.UsageError) else ""
    return f"{where}: error: {message}{help_of}"


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="mitlc")
def main() -> None:
    """Compile MITL control specs into reward Petri nets, train and check controllers."""


for command in (compile_cmd, check, train, simulate, sweep, automaton, compose_cmd, specs, plants):
    main.add_command(command)
