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
import math
from typing import Any, Iterable, Mapping, TypeVar

import numpy as np

from mitlc.errors import TrainingError

__all__ = ["to_dict", "from_dict", "check_fraction", "check_non_negative", "json_default"]

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


def json_default(o: Any) -> Any:
    """``json.dumps(default=...)`` for numpy integers."""
    if isinstance(o, np.integer):
        return int(o)
    raise TypeError(type(o).__name__)
