"""The ``mitlc`` command group: the commands of every family, gathered.

Every user error becomes one clear line (plus the source line and a caret when
there is one) on stderr and exit code 2; never a traceback (:mod:`mitlc.cli.common`).
"""

from __future__ import annotations

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


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="mitlc")
def main() -> None:
    """Compile MITL control specs into reward Petri nets, train and check controllers."""


for command in (compile_cmd, check, train, simulate, sweep, automaton, compose_cmd, specs, plants):
    main.add_command(command)
