"""Plants from the user's own code: a Python file or module named on the command line, or an
installed package's ``mitlc.plants`` entry point.

A spec stays data: its ``plant NAME`` line only names a registered plant, and code is
imported only from what the user passes explicitly (``--plant-file cart.py``,
``--plant-file mypkg.plants:CART``) or installs (an entry point).

What a source may hold: :class:`~mitlc.plants.base.Plant` objects at module level (all
are registered), or, with ``:ATTR``, one attribute that is a Plant, a sequence of them,
or a function returning either.  A module that calls :func:`~mitlc.plants.base.register`
itself is fine too.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import sys
from collections.abc import Iterable
from importlib import metadata
from pathlib import Path
from typing import Any

from mitlc.errors import InputError
from mitlc.plants.base import PLANTS, Plant, register

__all__ = ["ENTRY_POINT_GROUP", "SOURCES", "load_plants", "discover"]

ENTRY_POINT_GROUP = "mitlc.plants"
SOURCES: list[str] = []
"""Every source loaded in this process, as given to :func:`load_plants` (paths made absolute),
so that worker processes (``mitlc sweep``) can load the same plants."""

_discovered = False


def _plants_in(value: Any, where: str) -> list[Plant]:
    if callable(value) and not isinstance(value, Plant):
        value = value()
    if isinstance(value, Plant):
        return [value]
    if isinstance(value, Iterable) and not isinstance(value, (str, bytes)):
        items = list(value)
        if items and all(isinstance(v, Plant) for v in items):
            return items
    raise InputError(f"{where} is not a mitlc Plant (nor a list of them, nor a function returning one)")


def _import_file(path: Path, option: str) -> Any:
    if not path.is_file():
        raise InputError("no such plant file (give a .py file or module:attribute)", file=f"{option} {path}")
    name = "mitlc_user_plant_" + hashlib.sha1(str(path).encode()).hexdigest()[:12]
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise InputError("cannot import this file as Python", file=f"{option} {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # the user's code: any failure becomes one line
        del sys.modules[name]
        line = ""
        tb = exc.__traceback__
        while tb is not None:
            if tb.tb_frame.f_code.co_filename == str(path):
                line = f":{tb.tb_lineno}"
            tb = tb.tb_next
        raise InputError(
            f"importing the plant file failed: {type(exc).__name__}: {exc}", file=f"{path}{line}"
        ) from None
    return module


def load_plants(source: str, option: str = "--plant-file") -> tuple[Plant, ...]:
    """Import the plants of ``source`` (``FILE.py``, ``FILE.py:ATTR`` or ``MODULE:ATTR``) and register them."""
    text = source.strip()
    path_part, _, attr = text.partition(":") if not Path(text).is_file() else (text, "", "")
    if path_part.endswith(".py") or Path(path_part).is_file():
        path = Path(path_part).expanduser().resolve()
        module = _import_file(path, option)
        where = str(path)
        recorded = f"{path}:{attr}" if attr else str(path)
    else:
        if not attr:
            raise InputError("give a .py file, FILE.py:ATTR or module:attribute", file=f"{option} {source}")
        try:
            module = importlib.import_module(path_part)
        except Exception as exc:
            raise InputError(f"cannot import module '{path_part}': {type(exc).__name__}: {exc}", file=option) from None
        where, recorded = path_part, text
    before = dict(PLANTS)
    if attr:
        if not hasattr(module, attr):
            raise InputError(f"{where} has no attribute '{attr}'", file=option)
        plants = _plants_in(getattr(module, attr), f"{where}:{attr}")
    else:
        plants = [v for v in vars(module).values() if isinstance(v, Plant)]
        plants += [p for n, p in PLANTS.items() if before.get(n) is not p]  # the module's register() calls
        if not plants:
            raise InputError(f"{where} defines no Plant (build one with mitlc.plants.Plant)", file=option)
    for p in plants:
        register(p)
    if recorded not in SOURCES:
        SOURCES.append(recorded)
    return tuple({p.name: p for p in plants}.values())


def discover() -> list[str]:
    """Register the plants of every installed ``mitlc.plants`` entry point (once per process).

    Returns one line per entry point that failed to load (the others still load).
    """
    global _discovered
    if _discovered:
        return []
    _discovered = True
    problems = []
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            for p in _plants_in(ep.load(), f"entry point {ep.name} = {ep.value}"):
                register(p)
        except Exception as exc:  # an installed package's failure must not stop mitlc
            problems.append(f"entry point {ep.name} = {ep.value}: {type(exc).__name__}: {exc}")
    return problems
