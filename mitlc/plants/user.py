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
import re
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

from mitlc.errors import InputError
from mitlc.plants.base import PLANTS, Plant, register

__all__ = [
    "ENTRY_POINT_GROUP",
    "SOURCES",
    "load_plants",
    "discover",
    "plant_record",
    "plant_files",
    "restore_plant",
]

ENTRY_POINT_GROUP = "mitlc.plants"
SOURCES: list[str] = []
"""Every source loaded in this process, as given to :func:`load_plants` (paths made absolute),
so that worker processes (``mitlc sweep``) can load the same plants."""

_discovered = False


@dataclass(frozen=True)
class _Origin:
    """Where a registered plant came from: what a training records to be used again without it."""

    plant: Plant
    """The plant object registered from this source (a later registration under the name replaces it)."""
    kind: str
    """``file`` (``--plant-file FILE.py``), ``module`` (``module:attribute``) or ``entry_point``."""
    source: str
    """The file's absolute path, ``module:attribute``, or ``name = value`` of the entry point."""
    attr: str = ""
    content: bytes = b""
    """A file's text as it was run."""


_ORIGINS: dict[str, _Origin] = {}
PLANT_COPIES = "plants"
"""The folder of a training (``--out``) that keeps a copy of its plant file."""
_SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*\.py")
_MODULE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")


def _plants_in(value: Any, where: str, option: str | None = None) -> list[Plant]:
    if callable(value) and not isinstance(value, Plant):
        try:
            value = value()
        except Exception as exc:  # the user's code (a Plant it builds may be refused): one line
            raise InputError(f"calling it failed: {type(exc).__name__}: {exc}", file=where) from None
    if isinstance(value, Plant):
        return [value]
    if isinstance(value, Iterable) and not isinstance(value, (str, bytes)):
        items = list(value)
        if items and all(isinstance(v, Plant) for v in items):
            return items
    raise InputError(f"{where} is not a mitlc Plant (nor a list of them, nor a function returning one)", file=option)


def _import_file(path: Path, option: str) -> Any:
    """The module of the plant file ``path``, imported once per path and content (its text, as run, is
    kept as ``__mitlc_source__``, so that a training can copy exactly the code it ran)."""
    if not path.is_file():
        raise InputError("no such plant file (give a .py file or module:attribute)", file=f"{option} {path}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read the plant file: {exc.strerror or exc}", file=f"{option} {path}") from None
    name = "mitlc_user_plant_" + hashlib.sha1(str(path).encode() + b"\0" + data).hexdigest()[:12]
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise InputError("cannot import this file as Python", file=f"{option} {path}")
    module = importlib.util.module_from_spec(spec)
    setattr(module, "__mitlc_source__", data)  # noqa: B010  (a name mypy does not know on a module)
    sys.modules[name] = module
    try:
        exec(compile(data, str(path), "exec"), module.__dict__)  # the bytes read above, not a second read
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


def load_plants(source: str, option: str = "--plant-file", _recorded_as: str | None = None) -> tuple[Plant, ...]:
    """Import the plants of ``source`` (``FILE.py``, ``FILE.py:ATTR`` or ``MODULE:ATTR``) and register them."""
    text = source.strip()
    path_part, _, attr = text.partition(":") if not Path(text).is_file() else (text, "", "")
    file_path: Path | None = None
    if path_part.endswith(".py") or Path(path_part).is_file():
        file_path = path = Path(path_part).expanduser().resolve()
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
        plants = _plants_in(getattr(module, attr), f"{where}:{attr}", option)
    else:
        plants = [v for v in vars(module).values() if isinstance(v, Plant)]
        plants += [p for n, p in PLANTS.items() if before.get(n) is not p]  # the module's register() calls
        if not plants:
            raise InputError(f"{where} defines no Plant (build one with mitlc.plants.Plant)", file=option)
    for p in plants:
        register(p)
        if file_path is not None:
            _ORIGINS[p.name] = _Origin(p, "file", _recorded_as or str(file_path), attr, module.__mitlc_source__)
        else:
            _ORIGINS[p.name] = _Origin(p, "module", recorded)
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
                _ORIGINS[p.name] = _Origin(p, "entry_point", f"{ep.name} = {ep.value}")
        except Exception as exc:  # an installed package's failure must not stop mitlc
            problems.append(f"entry point {ep.name} = {ep.value}: {type(exc).__name__}: {exc}")
    return problems


# ---------------------------------------------------------------- a training remembers its plant


def _origin(name: str) -> _Origin | None:
    """Where the plant registered as ``name`` now came from (None: a shipped plant, or one registered in code)."""
    o = _ORIGINS.get(name)
    return o if o is not None and PLANTS.get(name) is o.plant else None


def _copy_name(path: str) -> str:
    """The name of a plant file's copy in a training folder: ``plants/<its file name>``."""
    base = Path(path).name
    return f"{PLANT_COPIES}/{base if _SAFE_NAME.fullmatch(base) else 'plant.py'}"


def plant_record(name: str) -> dict[str, str]:
    """What a training records of its plant ``name`` (a spec's ``plant`` line), as plain data.

    ``kind`` is ``file`` (with the file's original ``path``, its ``sha256``, ``attr`` and the
    training folder's copy ``file``; :func:`plant_files` gives the copy), ``module``, ``entry_point``
    (``source`` says which), ``gym`` (the id is the spec's; ``gym_modules``: the ``--gym-module`` modules
    imported, space-separated, when any), ``builtin`` or ``registered`` (in code).
    """
    if name.startswith("gym:"):
        from mitlc.plants.gym_env import GYM_MODULES

        record = {"name": name, "kind": "gym"}
        if GYM_MODULES:  # what registered the environment; named again by the user, never imported from a record
            record["gym_modules"] = " ".join(GYM_MODULES)
        return record
    o = _origin(name)
    if o is None:
        plant = PLANTS.get(name)
        shipped = plant is not None and getattr(plant.dynamics, "__module__", "").startswith("mitlc.")
        return {"name": name, "kind": "builtin" if shipped else "registered"}
    if o.kind != "file":
        return {"name": name, "kind": o.kind, "source": o.source}
    return {
        "name": name,
        "kind": "file",
        "path": o.source,
        "attr": o.attr,
        "sha256": hashlib.sha256(o.content).hexdigest(),
        "file": _copy_name(o.source),
    }


def plant_files(name: str) -> dict[str, bytes]:
    """The files a training folder keeps for its plant ``name``: ``{plants/FILE.py: the text it ran}``,
    or nothing for a plant that is not from a plant file."""
    o = _origin(name)
    return {_copy_name(o.source): o.content} if o is not None and o.kind == "file" else {}


def _checked_record(record: Any, where: str) -> dict[str, str] | None:
    if record is None:
        return None
    ok = isinstance(record, dict) and all(isinstance(k, str) and isinstance(v, str) for k, v in record.items())
    if ok and record.get("kind") == "file":
        ok = all(k in record for k in ("name", "path", "attr", "sha256", "file"))
        folder, _, base = record["file"].partition("/")
        ok = ok and folder == PLANT_COPIES and _SAFE_NAME.fullmatch(base) is not None
    if ok and record.get("kind") == "gym":
        ok = all(_MODULE.fullmatch(m) for m in record.get("gym_modules", "").split())
    if not ok or "name" not in record:
        raise InputError("damaged checkpoint: its meta 'plant' record is not a plant record", file=where)
    return record


def _registered_env(env_id: str) -> bool:
    """Whether Gymnasium's registry holds ``env_id`` (or a version of it) now: a look-up, no import but Gymnasium."""
    try:
        import gymnasium
    except ImportError:
        return False
    return any(k == env_id or k.startswith(env_id + "-v") for k in gymnasium.registry)


def _restore_gym(rec: dict[str, str], where: str) -> None:
    """A Gymnasium plant's run: the modules its training registered environments from (``--gym-module``)
    are named, never imported; an environment not registered here asks for the option again."""
    from mitlc.plants.gym_env import GYM_MODULES

    missing = [m for m in rec.get("gym_modules", "").split() if m not in GYM_MODULES]
    env_id = rec["name"][len("gym:") :]
    if missing and ":" not in env_id and not _registered_env(env_id):
        again = " ".join(f"--gym-module {m}" for m in missing)
        raise InputError(
            f"the run's environment '{env_id[:60]}' was registered by {again} in its training: pass {again} "
            "again (a run folder never imports code)",
            file=where,
        )


def restore_plant(record: Any, folder: str | Path, where: str | None = None) -> list[str]:
    """Make the plant a training in ``folder`` recorded (``record``: :func:`plant_record`'s) known again.

    A plant from a plant file is loaded from the folder's own copy (the code the training ran) when its
    name is not registered from a file of the same content already (a ``--plant-file`` given again wins,
    with a note when it differs). Other kinds need nothing (shipped, gym ids in the spec, entry points
    found by :func:`discover`) or cannot be loaded from the folder (``module:attribute``, and the
    ``--gym-module`` modules of a Gymnasium plant whose environment is not registered: an
    :class:`InputError` says which option to pass again; a run folder never imports code). Returns
    notes for the user, one line each.
    """
    where = where or str(folder)
    rec = _checked_record(record, where)
    if rec is None:
        return []
    name, kind = rec["name"], rec.get("kind")
    if kind in ("module", "entry_point", "registered") and name not in PLANTS:
        discover()
        if name not in PLANTS:
            how = {
                "module": f"pass --plant-file {rec.get('source', '')} again",
                "entry_point": f"install the package of the entry point {rec.get('source', '')}",
                "registered": "register it (mitlc.plants.register) before loading the run",
            }[kind]
            raise InputError(f"the run's plant '{name}' is not known here: {how}", file=where)
        return []
    if kind == "gym":
        _restore_gym(rec, where)
        return []
    if kind != "file":
        return []
    known = _origin(name)
    if known is not None and known.kind == "file":
        if hashlib.sha256(known.content).hexdigest() == rec["sha256"]:
            return []
        return [
            f"note: plant '{name}' comes from {known.source}, which differs from the copy this run was trained "
            f"with ({Path(folder) / rec['file']}); using {known.source}"
        ]
    if known is not None:  # given as module:attribute in this process: the user's explicit choice
        return []
    copy = Path(folder) / rec["file"]
    try:
        data = copy.read_bytes()
    except OSError:
        raise InputError(
            f"the run's copy of its plant file {rec['file']} is missing: pass --plant-file {rec['path']}",
            file=where,
        ) from None
    if hashlib.sha256(data).hexdigest() != rec["sha256"]:
        raise InputError(
            f"the run's copy of its plant file {rec['file']} was changed after the training (its SHA-256 differs)",
            file=where,
        )
    notes = []
    try:
        original = Path(rec["path"]).read_bytes()
    except OSError:
        original = None
    if original is not None and original != data:
        notes.append(f"note: {rec['path']} changed since the training; using the run's copy {copy}")
    source = f"{copy}:{rec['attr']}" if rec["attr"] else str(copy)
    load_plants(source, option=where, _recorded_as=rec["path"])
    return notes
