"""The ``mitlc`` command group: the commands of every family, gathered.

Every user error becomes one clear line (plus the source line and a caret when
there is one) on stderr and exit code 2; never a traceback (:mod:`mitlc.cli.common`).

The command modules load on demand: ``mitlc check`` imports :mod:`mitlc.cli.check`
and what it needs, not the trainers' modules, and ``mitlc --help`` lists every
command from :data:`COMMANDS` without importing any of them.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any

import click

from mitlc import __version__
from mitlc.cli import interrupt

__all__ = ["main", "COMMANDS"]

COMMANDS: dict[str, tuple[str, str, str]] = {
    "automaton": (
        "hybrid",
        "automaton",
        "Compile SPEC's classical criteria (require ...) into a hybrid automaton (thesis appendix B).",
    ),
    "check": ("check", "check", "Check a recorded TRACE (.csv or .npz) against SPEC (.mitl) with the MITL monitor."),
    "compile": ("compile", "compile_cmd", "Compile SPEC (.mitl) into a reward Petri net and reward expression."),
    "compose": (
        "hybrid",
        "compose_cmd",
        "Run SPEC's combined automaton with policies learned separately (thesis section 3-3-3).",
    ),
    "docs": (
        "docs",
        "docs",
        "List the documentation pages, or print the one called PAGE (e.g. semantics, commands/train).",
    ),
    "plants": ("plants", "plants", "List the plants a spec's 'plant NAME' line can name."),
    "report": (
        "report",
        "report",
        "Write DIR/report.html: a training's, a sweep's or a verification's folder as one HTML page.",
    ),
    "simulate": (
        "train",
        "simulate",
        "Roll out a trained greedy policy from the spec's initial set and judge each rollout.",
    ),
    "specs": ("specs", "specs", "List the shipped specs, or print the one called NAME (e.g. pendulum/p2_avoid)."),
    "sweep": ("sweep", "sweep", "Train SPEC over a grid of trainer settings, weights and options, several seeds each."),
    "train": ("train", "train", "Train SACPN controllers on a spec and judge them with the monitor."),
    "verify": (
        "verify",
        "verify",
        "Check a trained policy against its spec: a sampled bound and a search for counterexamples.",
    ),
}
"""Command name -> (module under :mod:`mitlc.cli`, attribute, short help: the first sentence of the
command's docstring, which ``mitlc --help`` lists; tests/test_light_cli.py keeps them in step)."""


class _Group(click.Group):
    """click's own errors (a bad option value, a directory given as SPEC, a missing argument) in
    mitlc's one-line format, exit 2; Ctrl-C before a command's own handling (its module's import
    included), exit 130. Commands of :data:`COMMANDS` are imported when first resolved."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(super().list_commands(ctx)) | set(COMMANDS))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        cmd = super().get_command(ctx, cmd_name)
        if cmd is None and cmd_name in COMMANDS:
            module, attr, _ = COMMANDS[cmd_name]
            cmd = getattr(importlib.import_module(f"mitlc.cli.{module}"), attr)
            self.add_command(cmd, cmd_name)
        return cmd

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """click's listing, with the short help of a command not loaded yet taken from :data:`COMMANDS`."""
        names = self.list_commands(ctx)
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = []
        for name in names:
            cmd = self.commands.get(name)
            if cmd is None:
                rows.append((name, click.Command(name, help=COMMANDS[name][2]).get_short_help_str(limit)))
            elif not cmd.hidden:
                rows.append((name, cmd.get_short_help_str(limit)))
        with formatter.section("Commands"):
            formatter.write_dl(rows)

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
        try:  # numpy loads here: a Ctrl-C while it does is an interruption like any other
            from mitlc.cli.common import numeric_warnings
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            interrupt.exit_interrupted()

        with numeric_warnings() as numeric:
            try:
                rv = super().main(args, prog_name, complete_var, False, **extra)
            except click.exceptions.ClickException as exc:
                click.echo(_one_line(exc), err=True)
                sys.exit(2 if exc.exit_code in (None, 1) else exc.exit_code)
            except (click.exceptions.Abort, KeyboardInterrupt):
                click.echo("interrupted", err=True)
                interrupt.exit_interrupted()
            except SystemExit as exc:  # a command's own exit after an interrupt (its message said what was kept)
                if exc.code == 130:
                    interrupt.exit_interrupted()
                if exc.code in (0, 1, None):  # a result (check's 1: violated): the overflow behind it, once
                    _say_numeric(numeric.line())
                raise
            _say_numeric(numeric.line())
        sys.exit(rv if isinstance(rv, int) else 0)


def _say_numeric(line: str | None) -> None:
    """The one line of :class:`mitlc.cli.common.NumericWarnings`, if there is one (after an error,
    exit 2, the error's own line says what went wrong, and this one is left out)."""
    if line is not None:
        click.echo(line, err=True)


def _one_line(exc: click.exceptions.ClickException) -> str:
    """``--out: error: ...``, ``SPEC: error: ...`` or ``mitlc train: error: ...``, and where help is."""
    ctx = getattr(exc, "ctx", None)
    where = ctx.command_path if ctx is not None else "mitlc"
    message = " ".join(exc.format_message().split())
    param = getattr(exc, "param", None)
    if isinstance(exc, click.BadParameter) and param is not None and ctx is not None:
        where = param.get_error_hint(ctx).split(" / ")[0].strip("'")
        if not isinstance(exc, click.MissingParameter):  # its message is empty: keep click's "Missing ..."
            message = " ".join(exc.message.split())
    help_of = f" ({ctx.command_path} --help)" if ctx is not None and isinstance(exc, click.UsageError) else ""
    return f"{where}: error: {message}{help_of}"


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="mitlc")
def main() -> None:
    """Compile MITL control specs into reward Petri nets, train and check controllers."""
