"""What every command shares: clean error reporting and atomic file writes.

Command modules import these from here; :mod:`mitlc.cli.main` imports the command
modules to register them, so nothing here may import :mod:`mitlc.cli.main`.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import Any

import click

from mitlc.errors import MitlError
from mitlc.fileio import atomic_write

__all__ = ["handle_errors", "atomic_write"]


def handle_errors(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Turn :class:`MitlError` into a clean message on stderr and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except MitlError as exc:
            click.echo(exc.render(), err=True)
            sys.exit(2)

    return wrapper
