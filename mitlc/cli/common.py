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

from mitlc.errors import InputError, MitlError
from mitlc.fileio import atomic_write

__all__ = ["handle_errors", "atomic_write", "output_option", "write_result", "PICTURES"]

PICTURES = ("svg", "png")
"""Formats that are rendered pictures (need ``-o FILE``)."""


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


def output_option(fn: Callable[..., Any]) -> Callable[..., Any]:
    """The ``-o/--output FILE`` option of the commands that print a result."""
    return click.option(
        "-o",
        "--output",
        type=click.Path(dir_okay=False),
        default=None,
        help="Write to this file (atomically) instead of standard output.",
    )(fn)


def write_result(output: str | None, fmt: str, make: Callable[[], str | bytes]) -> None:
    """Write what ``--format fmt`` made: to ``output`` atomically, else text to standard output
    (a picture format needs ``-o FILE``, checked before anything is made)."""
    if fmt in PICTURES and output is None:
        raise InputError(f"--format {fmt} needs -o FILE", file="--output")
    data = make()
    if output is not None:
        atomic_write(output, data)
        return
    assert isinstance(data, str)  # only pictures are bytes, and they were refused above without -o
    click.echo(data, nl=not data.endswith("\n"))
