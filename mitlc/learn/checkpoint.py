"""Reading a learner's checkpoint (``params.npz``) without trusting it.

A checkpoint is data. It is read within limits (:mod:`mitlc.npzfile`: every array's
header and unpacked size checked before its data is read, :data:`~mitlc.limits.MAX_META_CHARS`
of ``meta``, :data:`~mitlc.limits.MAX_CHECKPOINT_ARRAY_BYTES` per array) and its ``meta``
record is checked as a schema (types, ranges, sizes; the settings by the learner's own
checks) before anything uses it. A truncated file, another format saved under the name, a
zip bomb or a field of the wrong type is one :class:`InputError` naming the file and the
field, never a ``BadZipFile``, ``KeyError``, ``TypeError``, ``OverflowError`` or
``RecursionError``:

``p/params.npz: error: damaged checkpoint: settings.gamma is 'x', not a number``
"""

from __future__ import annotations

import dataclasses
import json
import math
import typing
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mitlc.errors import InputError, MitlError, TrainingError
from mitlc.limits import MAX_CHECKPOINT_ARRAY_BYTES, MAX_FEATURES, MAX_META_CHARS, MAX_SPEC_BYTES
from mitlc.npzfile import NpzArchive

if TYPE_CHECKING:
    from mitlc.spec.model import Spec

__all__ = ["read_checkpoint", "read_meta", "recorded_spec", "load_state", "damaged", "restore_plant", "KINDS"]

KINDS = ("sacpn", "hyrl")
"""The learners a checkpoint may be of (``meta.kind``; none: ``sacpn``)."""

_ARRAYS = ("xi", "theta", "returns")
"""The arrays a checkpoint holds besides ``meta`` (the only ones read)."""

_MAX_NAME = 1000
"""Characters of a name in ``meta`` (a place, a mode, a setting's text value)."""

_MAX_PATH = 4096
"""Characters of ``meta.spec_path`` (Linux's ``PATH_MAX``)."""

_MAX_TRIALS = 10**9
"""The most trials a checkpoint may say it has done."""

_MAX_COUNTS = 1000
"""Entries of a settings' count list (``rbf``: one per state variable)."""


class _Bad(Exception):
    """A field of ``meta`` that is not what it must be: ``field`` and what is wrong."""

    def __init__(self, field: str, why: str) -> None:
        super().__init__(f"{field} {why}")


def _count(n: int, noun: str) -> str:
    """``1 item``, ``2 items``."""
    return f"{n:,} {noun}" + ("" if n == 1 else "s")


def _shown(v: Any) -> str:
    """A value of ``meta`` as a message shows it: short, one line."""
    if isinstance(v, dict):
        return f"an object of {_count(len(v), 'key')}"
    if isinstance(v, list):
        return f"a list of {_count(len(v), 'item')}"
    if isinstance(v, int) and not isinstance(v, bool) and abs(v) >= 10**30:
        return f"an integer of {len(str(abs(v)))} digits"
    text = repr(v)
    return text if len(text) <= 40 else text[:40] + "..."


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _int(v: Any, field: str, lo: int = 0, hi: int | None = None) -> int:
    if not _is_int(v):
        raise _Bad(field, f"is {_shown(v)}, not an integer")
    if v < lo or (hi is not None and v > hi):
        where = f"from {lo:,} to {_bound(hi)}" if hi is not None else f"of at least {lo:,}"
        raise _Bad(field, f"is {_shown(v)}, not an integer {where}")
    return v


def _bound(n: int) -> str:
    """``1,000`` or, for a bound such as 2^128 - 1, that."""
    return f"2^{(n + 1).bit_length() - 1} - 1" if n >= 1 << 32 and not (n + 1) & n else f"{n:,}"


def _number(v: Any, field: str) -> float:
    if not _is_number(v):
        raise _Bad(field, f"is {_shown(v)}, not a number")
    try:
        x = float(v)
    except OverflowError:
        raise _Bad(field, f"is {_shown(v)}, not a finite number") from None
    if not math.isfinite(x):
        raise _Bad(field, f"is {_shown(v)}, not a finite number")
    return x


def _text(v: Any, field: str, longest: int = _MAX_NAME) -> str:
    if not isinstance(v, str):
        raise _Bad(field, f"is {_shown(v)}, not a string")
    try:
        size = len(v.encode("utf-8"))
    except UnicodeEncodeError:
        raise _Bad(field, "is not UTF-8 text (it holds a lone surrogate)") from None
    if size > longest:
        raise _Bad(field, f"is {size:,} bytes long, more than the {longest:,} it may be")
    if "\0" in v:
        raise _Bad(field, "holds a NUL character")
    return v


def _names(v: Any, field: str) -> list[str]:
    if not isinstance(v, list):
        raise _Bad(field, f"is {_shown(v)}, not a list of names")
    return [_text(x, f"{field}[{i}]") for i, x in enumerate(v)]


def _choice(v: Any, field: str, choices: tuple[str, ...]) -> str:
    if v not in choices or not isinstance(v, str):
        raise _Bad(field, f"is {_shown(v)}, not one of {', '.join(choices)}")
    return v


# ---------------------------------------------------------------- the generators' states


_PCG_MAX = (1 << 128) - 1


def _rng_state(v: Any, field: str) -> None:
    """A PCG64 generator's state as ``bit_generator.state`` gives it (what the learners save)."""
    if not isinstance(v, dict):
        raise _Bad(field, f"is {_shown(v)}, not a generator state")
    if v.get("bit_generator") != "PCG64":
        raise _Bad(f"{field}.bit_generator", f"is {_shown(v.get('bit_generator'))}, not 'PCG64'")
    state = v.get("state")
    if not isinstance(state, dict):
        raise _Bad(f"{field}.state", f"is {_shown(state)}, not an object")
    for key in ("state", "inc"):
        if key not in state:
            raise _Bad(f"{field}.state.{key}", "is missing")
        _int(state[key], f"{field}.state.{key}", 0, _PCG_MAX)
    for key, hi in (("has_uint32", 1), ("uinteger", (1 << 32) - 1)):
        if key not in v:
            raise _Bad(f"{field}.{key}", "is missing")
        _int(v[key], f"{field}.{key}", 0, hi)


def _rng_states(v: Any, field: str, runs: int) -> None:
    if not isinstance(v, list):
        raise _Bad(field, f"is {_shown(v)}, not a list")
    if len(v) != runs:
        raise _Bad(field, f"has {_count(len(v), 'generator state')}, not one per run ({runs:,})")
    for i, s in enumerate(v):
        _rng_state(s, f"{field}[{i}]")


# ---------------------------------------------------------------- the settings


def _setting_checker(hint: Any) -> Callable[[Any, str], None]:
    """A check of a JSON value for a settings field of type ``hint`` (as :func:`~mitlc.learn.settings.to_dict`
    writes it: tuples as lists)."""
    if hint is float:
        return lambda v, f: (_number(v, f), None)[1]
    if hint is int:
        return lambda v, f: (_int(v, f, -(1 << 63), (1 << 63) - 1), None)[1]
    if hint is bool:

        def boolean(v: Any, f: str) -> None:
            if not isinstance(v, bool):
                raise _Bad(f, f"is {_shown(v)}, not true or false")

        return boolean
    if hint is str:
        return lambda v, f: (_text(v, f), None)[1]
    args = typing.get_args(hint)
    if type(None) in args and len(args) == 2:
        inner = _setting_checker(next(a for a in args if a is not type(None)))
        return lambda v, f: None if v is None else inner(v, f)
    if typing.get_origin(hint) is tuple:
        if args == (int, Ellipsis) or (args and all(a is int for a in args)):
            n = None if args == (int, Ellipsis) else len(args)

            def counts(v: Any, f: str) -> None:
                if not isinstance(v, list) or not 1 <= len(v) <= _MAX_COUNTS or (n is not None and len(v) != n):
                    want = f"a list of {n} counts" if n is not None else "a list of counts"
                    raise _Bad(f, f"is {_shown(v)}, not {want}")
                for i, c in enumerate(v):
                    _int(c, f"{f}[{i}]", 1, MAX_FEATURES)

            return counts
        if len(args) == 2 and args[1] is Ellipsis and typing.get_args(args[0]) == (str, float, float):

            def bounds(v: Any, f: str) -> None:
                if not isinstance(v, list):
                    raise _Bad(f, f"is {_shown(v)}, not a list of [name, lo, hi]")
                for i, e in enumerate(v):
                    if not isinstance(e, list) or len(e) != 3:
                        raise _Bad(f"{f}[{i}]", f"is {_shown(e)}, not [name, lo, hi]")
                    _text(e[0], f"{f}[{i}][0]")
                    _number(e[1], f"{f}[{i}][1]")
                    _number(e[2], f"{f}[{i}][2]")

            return bounds
    raise TypeError(f"no checkpoint check for {hint}")  # pragma: no cover - a new field of an unknown type


def _settings(v: Any, kind: str) -> None:
    """``meta.settings``: each field the learner knows of the type it has, then the learner's own range
    checks (:meth:`SacpnSettings.check`, :meth:`HyrlSettings.check`). Unknown keys (a newer file) are ignored."""
    if not isinstance(v, dict):
        raise _Bad("settings", f"is {_shown(v)}, not an object")
    cls: Any
    if kind == "hyrl":
        from mitlc.learn.hyrl.hyrl import _LEGACY_SETTINGS, HyrlSettings

        cls, v = HyrlSettings, {**_LEGACY_SETTINGS, **v}
    else:
        from mitlc.learn.sacpn import SacpnSettings

        cls = SacpnSettings
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if f.name in v:
            _setting_checker(hints[f.name])(v[f.name], f"settings.{f.name}")
    try:
        cls.from_dict(v).check()
    except TrainingError as exc:  # "gamma must be in [0, 1], got 2": settings.gamma must be ...
        first, _, rest = exc.message.partition(" ")
        if first in {f.name for f in dataclasses.fields(cls)} and rest:
            raise _Bad(f"settings.{first}", rest) from None
        raise _Bad("settings:", exc.message) from None


# ---------------------------------------------------------------- the meta record


def _check_meta(meta: dict[str, Any]) -> str:
    """Check ``meta`` as data; return the checkpoint's kind. Raises :class:`_Bad` naming the field."""
    from mitlc.spec.model import OPTIONS

    kind = meta.get("kind", "sacpn")
    if kind not in KINDS or not isinstance(kind, str):
        raise _Bad("kind", f"is {_shown(kind)}, not one of {', '.join(KINDS)}")
    for key in ("runs", "seed", "trial", "settings", "rng_states", "eval_rng_states", "spec_source", "spec_path"):
        if key not in meta:
            raise _Bad(key, "is missing")
    runs = _int(meta["runs"], "runs", 1)
    _int(meta["seed"], "seed", 0)
    trial = _int(meta["trial"], "trial", 0, _MAX_TRIALS)
    _text(meta["spec_source"], "spec_source", MAX_SPEC_BYTES)
    _text(meta["spec_path"], "spec_path", _MAX_PATH)
    _rng_states(meta["rng_states"], "rng_states", runs)
    _rng_states(meta["eval_rng_states"], "eval_rng_states", runs)
    if "plant" in meta and meta["plant"] is not None and not isinstance(meta["plant"], dict):
        raise _Bad("plant", f"is {_shown(meta['plant'])}, not a plant record")
    if kind == "hyrl":
        for key in ("modes", "feature_vars"):
            if key not in meta:
                raise _Bad(key, "is missing")
            _names(meta[key], key)
        if "wall_s" in meta and _number(meta["wall_s"], "wall_s") < 0:
            raise _Bad("wall_s", f"is {_shown(meta['wall_s'])}, not a time of at least 0")
    else:
        if "places" not in meta:
            raise _Bad("places", "is missing")
        _names(meta["places"], "places")
        if "state_names" in meta:
            _names(meta["state_names"], "state_names")
        if "inputs" in meta and not _names(meta["inputs"], "inputs"):
            raise _Bad("inputs", "is an empty list, not the plant's inputs")
        for key in ("conjunction", "violations", "clock", "reward"):
            if meta.get(key) is not None:
                _choice(meta[key], key, OPTIONS[key])
        if meta.get("ramp_trials") is not None:
            _int(meta["ramp_trials"], "ramp_trials", 0, _MAX_TRIALS)
        if "diverged" in meta:
            d = meta["diverged"]
            if not isinstance(d, list) or len(d) != runs:
                raise _Bad("diverged", f"is {_shown(d)}, not one trial (or -1) per run ({runs:,})")
            for i, x in enumerate(d):
                _int(x, f"diverged[{i}]", -1, trial)
    _settings(meta["settings"], kind)
    if kind == "sacpn" and "state_names" in meta:
        _grid_of(meta["settings"], meta["state_names"])
    return kind


def _grid_of(settings: dict[str, Any], names: list[str]) -> None:
    """A SACPN checkpoint's feature grid agrees with the state it was trained on (``state_names``):
    one ``rbf`` count per variable, ``feature_bounds`` of its variables (or the former default's entry)."""
    from mitlc.learn.sacpn.sacpn import FORMER_DEFAULT_BOUNDS

    rbf = settings.get("rbf")
    if rbf is not None and len(rbf) != len(names):
        raise _Bad("settings.rbf", f"has {_count(len(rbf), 'count')}, not one per state variable ({', '.join(names)})")
    defaults = set(FORMER_DEFAULT_BOUNDS)
    for i, entry in enumerate(settings.get("feature_bounds", ())):
        if entry[0] not in names and tuple(entry) not in defaults:
            raise _Bad(
                f"settings.feature_bounds[{i}][0]", f"is {_shown(entry[0])}, not a state variable ({', '.join(names)})"
            )


def _read_meta_record(archive: NpzArchive, where: str) -> dict[str, Any]:
    if "meta" not in archive:
        raise InputError("not a mitlc checkpoint: no 'meta' record", file=where)
    m = archive.header("meta")
    if m.dtype.kind != "U" or m.shape != ():
        raise InputError(f"damaged checkpoint: its 'meta' record is not text (shape {m.shape}, {m.dtype})", file=where)
    chars = m.dtype.itemsize // 4
    if chars > MAX_META_CHARS:
        raise InputError(
            f"damaged checkpoint: its 'meta' record is {chars:,} characters, "
            f"more than the {MAX_META_CHARS:,} supported",
            file=where,
        )
    text = str(archive.read("meta", m.nbytes)[()])
    try:
        meta = json.loads(text)
    except RecursionError:
        raise InputError("damaged checkpoint: its 'meta' record is not JSON (nested too deeply)", file=where) from None
    except ValueError as exc:
        why = str(exc).splitlines()[0][:80] if str(exc) else type(exc).__name__
        raise InputError(f"damaged checkpoint: its 'meta' record is not JSON ({why})", file=where) from None
    if not isinstance(meta, dict):
        raise InputError("damaged checkpoint: its 'meta' record is not an object", file=where)
    return meta


def _check_arrays(archive: NpzArchive, meta: dict[str, Any], kind: str, where: str) -> dict[str, np.ndarray]:
    """``xi``, ``theta`` and ``returns``, each header checked against ``meta`` before its data is read."""
    for name in _ARRAYS:
        if name not in archive:
            raise InputError(f"damaged checkpoint: no array '{name}'", file=where)
    heads = {name: archive.header(name) for name in _ARRAYS}
    runs, trial = meta["runs"], meta["trial"]
    for name, m in heads.items():
        if m.dtype.kind not in "fiu":
            raise InputError(f"damaged checkpoint: array '{name}' holds {m.dtype}, not real numbers", file=where)
    xi, theta, returns = heads["xi"].shape, heads["theta"].shape, heads["returns"].shape
    n_in = len(meta.get("inputs", ["u"])) if kind == "sacpn" else 1  # SACPN: an actor row per place and input
    if n_in == 1 and (len(xi) != 3 or xi[0] != runs):
        raise InputError(
            f"damaged checkpoint: array 'xi' has shape {xi}, not (runs = {runs}, rows, features)", file=where
        )
    if n_in > 1 and (len(xi) != 4 or xi[0] != runs or xi[2] != n_in):
        raise InputError(
            f"damaged checkpoint: array 'xi' has shape {xi}, not (runs = {runs}, rows, inputs = {n_in}, features)",
            file=where,
        )
    rows = xi[1] + (1 if kind == "hyrl" else 0)  # HyRL's critic has a general row besides one per mode
    if theta != (runs, rows, xi[-1]):
        raise InputError(
            f"damaged checkpoint: array 'theta' has shape {theta}, not {(runs, rows, xi[-1])} (from 'xi')", file=where
        )
    if returns != (runs, trial):
        raise InputError(
            f"damaged checkpoint: array 'returns' has shape {returns}, not (runs, trial) = {(runs, trial)}",
            file=where,
        )
    arrays = {name: archive.read(name, MAX_CHECKPOINT_ARRAY_BYTES) for name in _ARRAYS}
    for name in ("xi", "theta"):
        if not np.isfinite(arrays[name]).all():
            raise InputError(
                f"damaged checkpoint: array '{name}' holds a value that is not a finite number "
                "(a checkpoint keeps each run's last finite parameters)",
                file=where,
            )
    return arrays


def read_checkpoint(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays of the checkpoint at ``path`` (``xi``, ``theta``, ``returns``, ``meta``) and its
    checked ``meta`` record."""
    where = str(path)
    with NpzArchive(path, "checkpoint") as archive:
        meta = _read_meta_record(archive, where)
        try:
            kind = _check_meta(meta)
        except _Bad as exc:
            raise InputError(f"damaged checkpoint: {exc}", file=where) from None
        arrays = _check_arrays(archive, meta, kind, where)
    arrays["meta"] = np.array(json.dumps(meta))
    return arrays, meta


def check_against(meta: dict[str, Any], spec: Spec, path: str | Path) -> None:
    """A SACPN checkpoint's feature grid fits the plant of ``spec``, the spec it is loaded with: one
    line naming the checkpoint and the field when not (a checkpoint from before ``state_names`` was
    recorded is checked here rather than against itself)."""
    plant = spec.plant
    if meta.get("kind", "sacpn") != "sacpn" or plant is None:
        return
    names, recorded = list(plant.state_names), meta.get("state_names")
    if recorded is not None and len(recorded) != len(names):  # a whole checkpoint, another plant's spec
        raise InputError(
            f"the policy was trained on the state ({', '.join(recorded)}); the spec's plant "
            f"'{plant.name}' has ({', '.join(names)})",
            file=str(path),
        )
    inputs = meta.get("inputs", ["u"])
    if len(inputs) != plant.n_inputs:
        raise InputError(
            f"the policy was trained on the inputs ({', '.join(inputs)}); the spec's plant "
            f"'{plant.name}' has ({', '.join(plant.input_names)})",
            file=str(path),
        )
    try:
        _grid_of(meta["settings"], names)
    except _Bad as exc:
        raise InputError(f"damaged checkpoint: {exc}", file=str(path)) from None


def recorded_spec(meta: dict[str, Any], path: str | Path) -> Spec:
    """The spec the checkpoint at ``path`` was trained on: its ``spec_source``, parsed (named by its
    ``spec_path``). The text is the checkpoint's, so an error in it is too: one line naming the
    checkpoint, the field and the line (the file at ``spec_path`` may say something else today)."""
    from mitlc.spec.parse import parse_spec

    try:
        return parse_spec(meta["spec_source"], meta["spec_path"] or None)
    except MitlError as exc:
        line = f", line {exc.line}" if exc.line is not None else ""
        raise InputError(f"damaged checkpoint: spec_source{line}: {exc.message}", file=str(path)) from None


def read_meta(path: str | Path) -> dict[str, Any]:
    """The checked ``meta`` record of a checkpoint (settings, runs, seed, spec text...)."""
    return read_checkpoint(path)[1]


def load_state(learner: Any, arrays: dict[str, np.ndarray], path: str | Path) -> None:
    """``learner.load_state_dict(arrays)``, any failure of a checkpoint that passed
    :func:`read_checkpoint` as one :class:`InputError` naming ``path``."""
    try:
        learner.load_state_dict(arrays)
    except InputError as exc:
        raise exc.located(str(path)) from None
    except (KeyError, TypeError, ValueError, IndexError, OverflowError) as exc:
        raise damaged(path, exc) from None


def damaged(path: str | Path, exc: BaseException) -> InputError:
    """What to raise when a checkpoint that passed :func:`read_checkpoint` still does not load."""
    return InputError(f"damaged checkpoint: {_why(exc)}", file=str(path))


def _why(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def restore_plant(meta: dict[str, Any], path: str | Path) -> list[str]:
    """Make the plant of the checkpoint at ``path`` known before its spec is parsed: a plant file's
    copy in the checkpoint's folder is loaded when the plant is not registered (see
    :func:`mitlc.plants.user.restore_plant`). Returns notes for the user, one line each."""
    from mitlc.plants.user import restore_plant as restore

    return restore(meta.get("plant"), Path(path).parent, where=str(path))
