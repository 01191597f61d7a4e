"""The ``mitlc`` command line: the edge to the shell.

In: argv. Out: files and one line per result; every user error becomes one line
(file:line:col or the option), the offending source line with a caret, exit code 2
(:mod:`mitlc.cli.common`). One module per command family; :mod:`mitlc.cli.main` is
the click group that gathers them.

May import: every stage.
"""

import sys

from mitlc.cli import interrupt

interrupt.install()  # a Ctrl-C swallowed while modules load is raised again (mitlc.cli.interrupt)

try:  # Ctrl-C while the command line loads: a clean exit 130, not a traceback
    from mitlc.cli.main import main
except KeyboardInterrupt:  # pragma: no cover - timing; tests/test_reliability.py sends SIGINT at start-up
    sys.stderr.write("interrupted\n")
    interrupt.exit_interrupted(force=True)


def run() -> None:
    """The ``mitlc`` program (console script and ``python -m mitlc``): :func:`main` in a
    process of its own (:data:`mitlc.cli.interrupt.PROGRAM`)."""
    interrupt.PROGRAM = True
    main()


__all__ = ["main", "run"]
