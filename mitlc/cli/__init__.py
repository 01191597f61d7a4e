"""The ``mitlc`` command line: the edge to the shell.

In: argv. Out: files and one line per result; every user error becomes one line
(file:line:col or the option), the offending source line with a caret, exit code 2
(:mod:`mitlc.cli.common`). One module per command family; :mod:`mitlc.cli.main` is
the click group that gathers them.

May import: every stage.
"""

from mitlc.cli.main import main

__all__ = ["main"]
