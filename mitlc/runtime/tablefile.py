"""The reward tables of a net kept on disk between processes: :func:`cached_tables`.

Tabulating a net (:func:`mitlc.runtime.tables.build_tables`) fires its rule on every pair of
marking and atom code; for a net of a few hundred markings that is most of a short ``mitlc check
--net``. The tables depend on the compiled net alone, so they are kept in mitlc's cache folder
(``tables/``, :mod:`mitlc.cachefiles`) as data: one ``.npz`` of plain arrays, read by
:class:`mitlc.npzfile.NpzArchive` (each array's header checked before its data is read, never
unpickled: reading it runs no code), named by the SHA-256 of the net as data
(:func:`tables_key`: the compiled net, mitlc's version and the file's format). A file that is
missing, unreadable, damaged, not the user's own, or whose arrays do not fit the net is ignored,
and the tables are built and written again; a cache that cannot be written costs only the time.

>>> import tempfile, os
>>> from mitlc.spec.parse import load_spec
>>> from mitlc.petri.compile import CompileOptions, compile_spec
>>> from mitlc.runtime import NetRuntime
>>> rs = compile_spec(load_spec("pendulum/n1_reach_in_time"), CompileOptions(violations="permanent"))
>>> before = os.environ.get("MITLC_CACHE_DIR")
>>> os.environ["MITLC_CACHE_DIR"] = folder = tempfile.mkdtemp()
>>> built = NetRuntime(rs, dt=0.05, steps=100, tables_cache=True).tables    # built, then written
>>> os.listdir(os.path.join(folder, "tables")) == [f"{tables_key(rs)}.npz"]
True
>>> kept = NetRuntime(rs, dt=0.05, steps=100, tables_cache=True).tables     # read back
>>> kept.next_code.shape, bool((kept.next_code == built.next_code).all() and (kept.reward == built.reward).all())
((4, 576, 8), True)
>>> if before is None:
...     del os.environ["MITLC_CACHE_DIR"]
... else:
...     os.environ["MITLC_CACHE_DIR"] = before
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mitlc.cachefiles import cache_folder, untrusted
from mitlc.fileio import save_npz
from mitlc.npzfile import NpzArchive
from mitlc.petri.compile import RewardSystem
from mitlc.runtime.tables import Tables

__all__ = ["cached_tables", "tables_key"]

_FORMAT = "mitlc-reward-tables 1"
"""The file format's name and version, part of every key: a new layout never reads an old file."""

_MAX_BYTES = 256 << 20
"""A tables file whose arrays declare more bytes than this is not read (``MAX_TABLE`` entries of
int64 are 32 MiB)."""

WORTH_KEEPING = 1 << 16
"""Smallest tables kept on disk, in entries (``next_code``'s plus the reward's pairs of codes): building
smaller ones (about 2 ms for 10,000 entries) costs less than naming and reading their file."""

_ARRAYS = ("next_code", "reward", "charge", "marked", "counter_inc", "markings", "clock_ends")


def tables_key(rs: RewardSystem) -> str:
    """The SHA-256 that names the tables of ``rs``: the net as data (:func:`~mitlc.petri.export.to_dict`,
    less the spec's file name: the same spec elsewhere has the same tables), the atoms' order, the
    charge, whether the reward is graded, mitlc's version and the file format."""
    from mitlc import __version__
    from mitlc.petri.export import to_dict  # only for tables worth keeping

    net = {k: v for k, v in to_dict(rs, matrices="arcs").items() if k != "spec"}
    extra = {"atoms": rs.atoms, "charge": str(rs.charge), "graded": rs.grader is not None}
    text = json.dumps([_FORMAT, __version__, net, extra], sort_keys=True, allow_nan=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def cached_tables(rs: RewardSystem, build: Callable[[], Tables | None], n_codes: int, n_clocks: int) -> Tables | None:
    """The tables of ``rs`` read from the cache, else ``build()``'s, written to it for the next process
    (``n_codes``: the net's mixed-radix marking codes, ``n_clocks``: its clock conditions; what a file's
    tables must fit)."""
    if (1 << n_clocks) * n_codes * (1 << len(rs.atoms)) + n_codes * n_codes < WORTH_KEEPING:
        return build()
    folder, _ = cache_folder("tables")
    if folder is None:
        return build()
    path = folder / f"{tables_key(rs)}.npz"
    kept = _load(path, rs, n_codes, n_clocks)
    if kept is not None:
        return kept[0]
    tables = build()
    try:
        save_npz(path, _arrays(tables))
    except Exception:  # a full disk, a read-only folder: the next process builds them again
        pass
    return tables


def _arrays(tables: Tables | None) -> dict[str, np.ndarray]:
    if tables is None:  # the net is too large to tabulate: that is kept too
        return {"none": np.ones(1, dtype=np.int8)}
    return {name: np.asarray(a) for name in _ARRAYS if (a := getattr(tables, name)) is not None}


def _load(path: Path, rs: RewardSystem, n_codes: int, n_clocks: int) -> tuple[Tables | None] | None:
    """``(tables,)`` kept in ``path`` (``(None,)``: the net does not tabulate), or None: no such file,
    not to be trusted, damaged, or arrays that do not fit ``rs``'s net."""
    if untrusted(path) is not None:
        return None
    try:
        with NpzArchive(path, "reward tables") as z:  # each member's header checked before its data is read
            names = z.names
            if set(names) - {*_ARRAYS, "none"} or sum(z.header(n).nbytes for n in names) > _MAX_BYTES:
                return None
            arrays = {n: z.read(n, max_bytes=_MAX_BYTES) for n in names}
        return _tables(arrays, rs, n_codes, n_clocks)
    except Exception:  # a damaged file (a bad zip, a short array, Python objects): built again
        return None


def _tables(
    arrays: dict[str, np.ndarray], rs: RewardSystem, radix_codes: int, n_clocks: int
) -> tuple[Tables | None] | None:
    """The arrays of a tables file as :class:`Tables`, each checked against the net's sizes."""
    if set(arrays) == {"none"}:
        return (None,)
    n_subnets, n_counters = len(rs.net.subnets), len(rs.net.counters)
    next_code, marked = arrays.get("next_code"), arrays.get("marked")
    counter_inc = arrays.get("counter_inc")
    if next_code is None or marked is None or counter_inc is None or set(arrays) - set(_ARRAYS):
        return None
    if next_code.dtype != np.int64 or next_code.ndim != 3 or next_code.shape[2] != 1 << len(rs.atoms):
        return None
    n_codes = next_code.shape[1]
    if next_code.size and (next_code.min() < 0 or next_code.max() >= n_codes):
        return None
    if marked.ndim != 2 or marked.shape != (n_codes, n_subnets) or marked.dtype.kind not in "iu":
        return None
    if marked.size and (marked.min() < 0 or marked.max() >= len(rs.net.places)):
        return None
    markings, clock_ends = arrays.get("markings"), arrays.get("clock_ends")
    if (markings is None) != (clock_ends is None):
        return None
    index = None
    if markings is not None and clock_ends is not None:  # compact tables: codes index the reachable markings
        if markings.dtype != np.int8 or markings.shape != (n_codes, len(rs.net.places)) or clock_ends.ndim != 1:
            return None
        if clock_ends.dtype != np.float64 or next_code.shape[0] != 2 * len(clock_ends) + 1:
            return None
        if not (markings.sum(axis=1) == n_subnets).all() or not (np.take_along_axis(markings, marked, 1) == 1).all():
            return None
        index = {m.tobytes(): c for c, m in enumerate(markings)}
        if len(index) != n_codes or counter_inc.shape != (0, 0, 0):
            return None
    elif next_code.shape[:2] != (1 << n_clocks, radix_codes) or counter_inc.shape != (n_codes, n_codes, n_counters):
        return None
    pairs: list[np.ndarray | None] = []
    for name in ("reward", "charge"):
        a = arrays.get(name)
        if a is not None and (a.dtype != np.float64 or a.shape != (n_codes, n_codes)):
            return None
        pairs.append(a)
    if counter_inc.dtype != np.int64:
        return None
    for a in (next_code, marked, counter_inc, markings, clock_ends, *pairs):
        if a is not None:
            a.setflags(write=False)
    return (Tables(next_code, pairs[0], pairs[1], marked, counter_inc, markings, index, clock_ends),)
