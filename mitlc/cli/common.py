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
from mitlc.fileio import atomic_write, check_writable

__all__ = [
    "handle_errors",
    "atomic_write",
    "check_writable",
    "compile_options",
    "output_option",
    "plant_file_option",
    "write_result",
    "PICTURES",
]

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


def _load_plant_files(ctx: click.Context, param: click.Parameter, values: tuple[str, ...]) -> None:
    if not values:  # click calls back without the option too: no import (importlib.metadata) then
        return
    from mitlc.plants.user import load_plants

    for v in values:
        try:
            load_plants(v)
        except MitlError as exc:
            click.echo(exc.located(f"--plant-file {v}").render(), err=True)
            ctx.exit(2)


def _import_gym_modules(ctx: click.Context, param: click.Parameter, values: tuple[str, ...]) -> None:
    if not values:  # without the option: nothing imported (not even Gymnasium)
        return
    from mitlc.plants.gym_env import import_gym_module

    for v in values:
        try:
            import_gym_module(v)
        except MitlError as exc:
            click.echo(exc.render(), err=True)
            ctx.exit(2)


def plant_file_option(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``--plant-file FILE.py|MODULE:ATTR`` and ``--gym-module MODULE`` (each repeatable): register the user's
    plants, and the Gymnasium environments of the user's modules, before the spec is read. The only ways
    code of the user's is imported: a spec (or a run folder) never imports anything."""
    fn = click.option(
        "--gym-module",
        multiple=True,
        metavar="MODULE",
        expose_value=False,
        is_eager=True,
        callback=_import_gym_modules,
        help="Import this Python module first, so that it registers its Gymnasium environments for a spec's "
        "'plant gym:ID' (a spec names registered ids only: 'gym:module:ID' is refused); repeat for more. "
        "A training records it; a run folder asks for it again rather than importing it.",
    )(fn)
    return click.option(
        "--plant-file",
        multiple=True,
        metavar="FILE.py|MODULE:ATTR",
        expose_value=False,
        is_eager=True,
        callback=_load_plant_files,
        help="Your own plant: a Python file (every Plant in it) or module:attribute (a Plant, a list of "
        "them, or a function returning one); repeat for more. Installed packages add plants through "
        "the 'mitlc.plants' entry point; a spec's 'plant gym:ID' names a registered Gymnasium environment "
        "(--gym-module registers those of a module of yours). "
        "mitlc plants lists them (mitlc docs plants).",
    )(fn)


def compile_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``--conjunction``, ``--violations``, ``--clock`` and ``--reward``: the compile options, each overriding the
    spec's ``option`` line (``None`` when not given)."""
    from mitlc.spec.model import OPTIONS

    helps = {
        "conjunction": "How '&' combines gated terms (overrides the spec's option).",
        "violations": "Track violations of safety and deadline parts: a violation-aware reward (overrides the "
        "spec's option; mitlc docs semantics, section 6).",
        "clock": "standard: nested intervals count from their obligation's start (MITL); trial: every "
        "interval on the trial clock, the thesis's reading (overrides the spec's option).",
        "reward": "net: Table 4-2's reward, each proposition +1 / -1; graded: each proposition's robustness over "
        "the state bounds, clipped to [-1, 1]; shaped: the mean of the two; sparse, robustness, "
        "robustness-window: the field's rewards, paid by the monitor (overrides the spec's option; "
        "mitlc docs semantics).",
    }
    for name in reversed(list(helps)):
        fn = click.option(f"--{name}", type=click.Choice(OPTIONS[name]), default=None, help=helps[name])(fn)
    return fn


def output_option(fn: Callable[..., Any]) -> Callable[..., Any]:
    """The ``-o/--output FILE`` option of the commands that print a result (checked by
    :func:`write_result`, which names it ``-o FILE`` in its errors)."""
    return click.option(
        "-o",
        "--output",
        type=click.Path(),
        default=None,
        help="Write to this file (atomically) instead of standard output.",
    )(fn)


def write_result(output: str | None, fmt: str, make: Callable[[], str | bytes]) -> None:
    """Write what ``--format fmt`` made: to ``output`` atomically, else text to standard output
    (a picture format needs ``-o FILE``; a file that cannot be written, a folder given as the file,
    a read-only or full disk, is refused before anything is made: one line, ``-o FILE: error: ...``)."""
    if fmt in PICTURES and output is None:
        raise InputError(f"--format {fmt} needs -o FILE", file="--output")
    label = f"-o {output}"
    if output is not None:
        if output == "":
            raise InputError("an empty file name", file="-o ''")
        check_writable(output, label)
    data = make()
    if output is not None:
        atomic_write(output, data, label)
        return
    assert isinstance(data, str)  # only pictures are bytes, and they were refused above without -o
    click.echo(data, nl=not data.endswith("\n"))
