"""Reading a learner's checkpoint (``params.npz``) without trusting it.

A checkpoint is data: a truncated file, another format saved under the name, or a
``meta`` record with missing keys or wrong types is one :class:`InputError` naming
the file, never a ``BadZipFile``, ``KeyError`` or ``TypeError``.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import InputError

__all__ = ["read_checkpoint", "read_meta", "load_state", "damaged", "restore_plant"]

_COMMON = {
    "runs": int,
    "seed": int,
    "trial": int,
    "settings": dict,
    "rng_states": list,
    "eval_rng_states": list,
    "spec_source": str,
    "spec_path": str,
}
_ARRAYS = {"sacpn": ("xi", "theta", "returns", "meta"), "hyrl": ("xi", "theta", "returns", "meta")}


def read_checkpoint(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays of the checkpoint at ``path`` and its checked ``meta`` record."""
    where = str(path)
    try:
        d = np.load(path, allow_pickle=False)
        if not isinstance(d, np.lib.npyio.NpzFile):
            raise InputError("not a checkpoint: a single .npy array, not an .npz archive", file=where)
        with d:
            arrays = {k: d[k] for k in d.files}
    except InputError:
        raise
    except (OSError, zipfile.BadZipFile, ValueError, EOFError, TypeError) as exc:
        raise InputError(
            f"cannot read checkpoint: {_why(exc)} (truncated, or not an .npz archive)", file=where
        ) from None
    if "meta" not in arrays:
        raise InputError("not a mitlc checkpoint: no 'meta' record", file=where)
    try:
        meta = json.loads(str(arrays["meta"]))
    except ValueError:
        raise InputError("damaged checkpoint: its 'meta' record is not JSON", file=where) from None
    if not isinstance(meta, dict):
        raise InputError("damaged checkpoint: its 'meta' record is not an object", file=where)
    kind = meta.get("kind", "sacpn")
    if kind not in _ARRAYS:
        raise InputError(f"unknown checkpoint kind {kind!r} (sacpn or hyrl)", file=where)
    for key, typ in _COMMON.items():
        value = meta.get(key)
        if not isinstance(value, typ) or isinstance(value, bool):
            got = "missing" if key not in meta else f"{type(value).__name__} {value!r:.40}"
            want = {"int": "an integer", "dict": "an object", "list": "a list", "str": "a string"}[typ.__name__]
            raise InputError(f"damaged checkpoint: meta '{key}' should be {want}, is {got}", file=where)
    if meta["runs"] < 1 or meta["seed"] < 0 or meta["trial"] < 0:
        raise InputError("damaged checkpoint: runs, seed or trial out of range", file=where)
    missing = [a for a in _ARRAYS[kind] if a not in arrays]
    if missing:
        raise InputError(f"damaged checkpoint: no array '{missing[0]}'", file=where)
    return arrays, meta


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
    except (KeyError, TypeError, ValueError, IndexError) as exc:
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
