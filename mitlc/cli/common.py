"""What every command shares: clean error reporting and atomic file writes.

Command modules import these from here; :mod:`mitlc.cli.main` imports the command
modules to register them, so nothing here may import :mod:`mitlc.cli.main`.
"""

from __future__ import annotations

import contextlib
import functools
import re
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TextIO

import click

from mitlc.errors import InputError, MitlError
from mitlc.fileio import atomic_write, check_writable

__all__ = [
    "handle_errors",
    "numeric_warnings",
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


_NUMERIC = re.compile(r"(overflow|underflow|invalid value|divide by zero) encountered|discards the imaginary part")
"""numpy's floating-point warnings (and its complex-to-real cast): the numbers, not the code, went wrong."""


class NumericWarnings:
    """numpy's floating-point warnings of one command, kept back and said in one line at its end
    (:func:`numeric_warnings`): each is raised where it happens, by the million in a loop; what
    the user needs is that it happened, once. Where an overflow is legitimate arithmetic (a
    predicate's ``exp(exp(q))`` is inf, and inf > 5), the code says so with ``np.errstate``
    and nothing is recorded."""

    def __init__(self) -> None:
        self.count = 0
        self.first: tuple[str, str, int] | None = None
        self.places: set[tuple[str, int]] = set()

    def line(self) -> str | None:
        """``warning: numbers overflowed ...`` or None when nothing was recorded."""
        if self.first is None:
            return None
        text, filename, lineno = self.first
        where = Path(filename)
        try:
            where = where.relative_to(Path(__file__).resolve().parents[2])
        except ValueError:
            pass
        more = len(self.places) - 1
        others = f" and {more} other place{'s' if more != 1 else ''}" if more else ""
        if "imaginary" in text:
            what = "complex numbers were read as real ones, their imaginary parts dropped"
        else:
            what = "numbers left float64's range on the way; what was computed from them rests on inf or nan"
        return f"mitlc: warning: {what} ({text}, at {where}:{lineno}{others})"


@contextlib.contextmanager
def numeric_warnings() -> Iterator[NumericWarnings]:
    """Keep numpy's floating-point warnings back for the block (every occurrence counted, none
    printed); other warnings show as usual."""
    seen = NumericWarnings()
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def show(
            message: Warning | str,
            category: type[Warning],
            filename: str,
            lineno: int,
            file: TextIO | None = None,
            line: str | None = None,
        ) -> None:
            text = str(message)
            if issubclass(category, RuntimeWarning) and _NUMERIC.search(text):
                seen.count += 1
                seen.places.add((filename, lineno))
                if seen.first is None:
                    seen.first = (text, filename, lineno)
                return
            shown(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        warnings.simplefilter("always", RuntimeWarning)  # every command sees its own (no registry across calls)
        yield seen


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
