"""What the learners' settings dataclasses share: JSON round trips and range checks.

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class S:
...     gamma: float = 0.9
...     grid: tuple = (2, 3)
>>> to_dict(S())
{'gamma': 0.9, 'grid': [2, 3]}
>>> from_dict(S, {"gamma": 0.5, "grid": [4, 4], "unknown": 1})
S(gamma=0.5, grid=(4, 4))
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import typing
from collections.abc import Callable, Iterable, Mapping
from typing import Any, TypeVar

import numpy as np

from mitlc.errors import InputError, TrainingError

__all__ = [
    "Settings",
    "to_dict",
    "from_dict",
    "check_fraction",
    "check_non_negative",
    "check_positive",
    "check_range",
    "check_grid",
    "json_default",
    "parse_finite",
    "parser_for",
    "setting_parsers",
    "parse_assignments",
    "did_you_mean",
    "close_names",
]

T = TypeVar("T")


def _lists(v: Any) -> Any:
    return [_lists(x) for x in v] if isinstance(v, (tuple, list)) else v


def _tuples(v: Any) -> Any:
    return tuple(_tuples(x) for x in v) if isinstance(v, (tuple, list)) else v


def to_dict(settings: Any) -> dict:
    """The settings as JSON-able data (tuples become lists)."""
    return {k: _lists(v) for k, v in dataclasses.asdict(settings).items()}


def from_dict(cls: type[T], d: Mapping[str, Any]) -> T:
    """Settings of ``cls`` from :func:`to_dict` data; unknown keys (older or newer files) are ignored."""
    known = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    return cls(**{k: _tuples(v) for k, v in d.items() if k in known})


S = TypeVar("S", bound="Settings")


class Settings:
    """Base of the learners' settings dataclasses: their JSON form and back."""

    def to_dict(self) -> dict:
        return to_dict(self)

    @classmethod
    def from_dict(cls: type[S], d: Mapping[str, Any]) -> S:
        return from_dict(cls, d)


def check_fraction(settings: Any, names: Iterable[str]) -> None:
    """Each named setting is in [0, 1]."""
    for name in names:
        v = getattr(settings, name)
        if not 0.0 <= v <= 1.0:
            raise TrainingError(f"{name} must be in [0, 1], got {v}")


def check_non_negative(settings: Any, names: Iterable[str]) -> None:
    """Each named setting is a finite number >= 0."""
    for name in names:
        v = getattr(settings, name)
        if not (math.isfinite(v) and v >= 0):
            raise TrainingError(f"{name} must be a non-negative number, got {v}")


def check_positive(settings: Any, names: Iterable[str]) -> None:
    """Each named setting is a finite number > 0."""
    for name in names:
        v = getattr(settings, name)
        if not (math.isfinite(v) and v > 0):
            raise TrainingError(f"{name} must be a positive number, got {v}")


def check_range(settings: Any, names: Iterable[str], lo: float, hi: float, optional: bool = False) -> None:
    """Each named setting is a number in ``[lo, hi]`` (or None, when ``optional``): values past the
    range would overflow or underflow where the learner uses them."""
    for name in names:
        v = getattr(settings, name)
        if optional and v is None:
            continue
        if not (isinstance(v, int | float) and lo <= v <= hi):
            raise TrainingError(f"{name} must be a number in [{lo:g}, {hi:g}], got {v}")


def check_grid(counts: Iterable[int], name: str = "rbf") -> None:
    """An RBF grid of at least one centre per axis and at most :data:`~mitlc.limits.MAX_FEATURES` in all."""
    from mitlc.limits import MAX_FEATURES

    counts = [int(n) for n in counts]
    if any(n < 1 for n in counts):
        raise TrainingError(f"{name} needs at least one centre per variable, got {'x'.join(map(str, counts))}")
    total = math.prod(counts)
    if total > MAX_FEATURES:
        raise TrainingError(
            f"{name} = {'x'.join(map(str, counts))} is {total:,} features, more than the {MAX_FEATURES:,} supported"
        )


def json_default(o: Any) -> Any:
    """``json.dumps(default=...)`` for numpy integers."""
    if isinstance(o, np.integer):
        return int(o)
    raise TypeError(type(o).__name__)


# ---------------------------------------------------------------- settings written as text


def parse_finite(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"'{text}' is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"'{text}' is not a finite number")
    return v


def _parse_bool(text: str) -> bool:
    t = text.lower()
    if t in ("true", "yes", "on", "1"):
        return True
    if t in ("false", "no", "off", "0"):
        return False
    raise ValueError(f"'{text}' is not true or false")


def _parse_counts(text: str) -> tuple[int, ...]:
    try:
        counts = tuple(int(p) for p in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"'{text}' is not a grid size such as 10x10") from None
    return counts


def _parse_bounds(text: str) -> tuple[tuple[str, float, float], ...]:
    if text.lower() == "none":
        return ()
    out = []
    for part in text.split("+"):
        bits = part.split(":")
        if len(bits) != 3 or not bits[0]:
            raise ValueError(f"'{part}' is not a range such as qdot:-20:20")
        out.append((bits[0], parse_finite(bits[1]), parse_finite(bits[2])))
    return tuple(out)


def _fixed_counts(n: int) -> Callable[[str], tuple[int, ...]]:
    def p(text: str) -> tuple[int, ...]:
        counts = _parse_counts(text)
        if len(counts) != n:
            raise ValueError(f"'{text}' is not {n} counts such as {'x'.join(['10'] * n)}")
        return counts

    return p


def _optional(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    def p(text: str) -> Any:
        return None if text.lower() in ("none", "default", "auto") else parse(text)

    return p


def parser_for(hint: Any) -> Callable[[str], Any] | None:
    """A value parser for a settings field of type ``hint``, or None if it cannot be swept."""
    if hint is float:
        return parse_finite
    if hint is int:
        return int
    if hint is bool:
        return _parse_bool
    if hint is str:
        return str
    args = typing.get_args(hint)
    if type(None) in args and len(args) == 2:
        inner = parser_for(next(a for a in args if a is not type(None)))
        return _optional(inner) if inner else None
    if typing.get_origin(hint) is tuple:
        if args == (int, Ellipsis):
            return _parse_counts
        if args and all(a is int for a in args):  # a fixed number of counts, e.g. tuple[int, int, int]
            return _fixed_counts(len(args))
        if len(args) == 2 and args[1] is Ellipsis and typing.get_args(args[0]) == (str, float, float):
            return _parse_bounds
    return None


def setting_parsers(cls: type) -> dict[str, Callable[[str], Any]]:
    """Every field of the settings dataclass ``cls`` and the parser of its values written as text
    (``mitlc sweep --grid``, ``mitlc train --set``)."""
    hints = typing.get_type_hints(cls)
    out = {}
    for f in dataclasses.fields(cls):
        parse = parser_for(hints[f.name])
        if parse is None:  # pragma: no cover - a new field of a type this module does not know
            raise TypeError(f"{cls.__name__}.{f.name}: no parser for {hints[f.name]}")
        out[f.name] = parse
    return out


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """``: did you mean 'gamma'?`` for a name close to one of ``known``, else the list of them.

    >>> did_you_mean("gama", ["alpha_a", "gamma", "sigma"])
    " (did you mean 'gamma'?)"
    >>> did_you_mean("zzz", ["alpha_a", "gamma"])
    ' (known: alpha_a, gamma)'
    """
    known = list(known)
    close = close_names(name, known)
    return f" (did you mean {close}?)" if close else f" (known: {', '.join(known)})"


def close_names(name: str, known: Iterable[str]) -> str:
    """The names of ``known`` close to ``name`` (a typo of them), quoted, best first: ``'alpha_a' or 'alpha_c'``.

    >>> close_names("alpha", ["alpha_a", "alpha_c", "gamma"]), close_names("zzz", ["gamma"])
    ("'alpha_a' or 'alpha_c'", '')
    """
    score = {k: difflib.SequenceMatcher(None, name, k).ratio() for k in known}
    close = sorted((k for k, r in score.items() if r >= 0.75), key=lambda k: (-score[k], k))[:3]
    return " or ".join(f"'{k}'" for k in close)


def parse_assignments(cls: type[T], items: Iterable[str], option: str = "--set") -> dict[str, Any]:
    """``NAME=VALUE`` texts as typed values of ``cls``'s fields; a bad name or value is an
    :class:`InputError` naming ``option`` (never ``eval``: each field has its parser)."""
    parsers = setting_parsers(cls)
    out: dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name, text = name.strip(), text.strip()
        if not sep or not name:
            raise InputError(f"'{item}' is not NAME=VALUE", file=option)
        if name not in parsers:
            raise InputError(f"unknown setting '{name}'{did_you_mean(name, parsers)}", file=option)
        try:
            out[name] = parsers[name](text)
        except ValueError as exc:
            raise InputError(f"{name}: {exc}", file=option) from None
    return out
