"""The LALR parser of ``grammar/mitl.lark`` and the cache of its tables between processes.

:func:`parser_for` builds the parser for one start rule (``start``, ``formula``, ``pred``) with the
transformer of :mod:`mitlc.spec.transform`, and keeps its tables as JSON data in mitlc's cache
folder (:mod:`mitlc.cachefiles`): building them is most of a short ``mitlc check``'s start-up.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import sys
import tempfile
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import lark
from lark import Lark

from mitlc.spec.transform import Build

__all__ = ["parser_for"]


def _grammar_text() -> str:
    local = Path(__file__).resolve().parents[2] / "grammar" / "mitl.lark"
    if local.is_file():
        return local.read_text(encoding="utf-8")
    return resources.files("mitlc.grammar").joinpath("mitl.lark").read_text(encoding="utf-8")


_TABLES_FORMAT = "mitlc-parser-tables 1"
"""The first word pair of a tables file: the format, then its version."""

_MAX_TABLES_BYTES = 16 << 20
"""A tables file larger than this is not read (the grammar's are about 140 KB)."""

_LOAD_OPTIONS = frozenset(
    getattr(
        lark.lark,
        "_LOAD_ALLOWED_OPTIONS",
        {"postlex", "transformer", "lexer_callbacks", "use_bytes", "debug", "g_regex_flags", "regex"}
        | {"propagate_positions", "tree_class", "_plugins"},
    )
)
"""Options given again when tables are loaded (the transformer is code: never in the file)."""


def _tables_key(grammar: str, start: str) -> str:
    return hashlib.sha256(f"{grammar}\0{start}\0{lark.__version__}\0{sys.version_info[:2]}".encode()).hexdigest()


def _table_file(grammar: str, start: str) -> str | bool:
    """Where the parser's tables are kept between processes (building them is most of a short
    ``mitlc check``'s start-up), or False when the disk cache is off, cannot be written, or is not
    to be trusted (:func:`mitlc.cachefiles.cache_folder`). The name holds the grammar's, lark's and
    Python's hash, so a stale file is never read; the file's first line holds the whole hash again."""
    from mitlc.cachefiles import cache_folder

    folder, _ = cache_folder("parser")
    if folder is None:
        return False
    return str(folder / f"mitl-{start}-{_tables_key(grammar, start)[:16]}.json")


def _tagged(x: Any) -> Any:
    """lark's serialised tables as JSON: tuples and dicts with keys other than strings are tagged."""
    if isinstance(x, tuple):
        return {"__tuple__": [_tagged(v) for v in x]}
    if isinstance(x, list):
        return [_tagged(v) for v in x]
    if isinstance(x, dict):
        if all(type(k) is str for k in x) and not (len(x) == 1 and next(iter(x)) in ("__tuple__", "__items__")):
            return {k: _tagged(v) for k, v in x.items()}
        return {"__items__": [[_tagged(k), _tagged(v)] for k, v in x.items()]}
    if x is None or type(x) in (str, int, float, bool):
        return x
    raise TypeError(f"{type(x).__name__} in lark's tables")


def _untagged(d: dict) -> Any:
    if len(d) == 1:
        if "__tuple__" in d:
            return tuple(d["__tuple__"])
        if "__items__" in d:
            return {k: v for k, v in d["__items__"]}
    return d


def _load_tables(path: Path, key: str) -> Lark | None:
    """The parser kept in ``path``, or None (no such file, another grammar, damaged, or not to be trusted).

    The file is JSON data (lark's ``memo_serialize``), never a pickle: reading it runs no code. It is
    read only when it and its folder are the user's own and no one else's to write
    (:func:`mitlc.cachefiles.untrusted`): tables written by someone else could change what a spec means."""
    from mitlc.cachefiles import untrusted

    if untrusted(path) is not None:
        return None
    try:
        with path.open("rb") as fh:
            raw = fh.read(_MAX_TABLES_BYTES + 1)
        head, _, body = raw.partition(b"\n")
        fmt_name, fmt_version, file_key, digest = head.decode("ascii").split(" ")
        if len(raw) > _MAX_TABLES_BYTES or f"{fmt_name} {fmt_version}" != _TABLES_FORMAT or file_key != key:
            return None
        if hashlib.sha256(body).hexdigest() != digest:
            return None
        tables = json.loads(body, object_hook=_untagged)
        return Lark._load_from_dict(tables["data"], tables["memo"], transformer=Build())
    except Exception:  # a damaged file, or another lark's internals: build the tables instead
        return None


def _save_tables(parser: Lark, path: Path, key: str) -> None:
    """Write ``parser``'s tables to ``path`` as JSON data, atomically; nothing when that fails."""
    from lark.grammar import Rule
    from lark.lexer import TerminalDef

    tmp = None
    try:
        data, memo = parser.memo_serialize([TerminalDef, Rule])
        data["options"] = {k: v for k, v in data["options"].items() if k not in _LOAD_OPTIONS}
        body = json.dumps({"data": _tagged(data), "memo": _tagged(memo)}, separators=(",", ":")).encode()
        head = f"{_TABLES_FORMAT} {key} {hashlib.sha256(body).hexdigest()}\n".encode()
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tables-", suffix=".tmp")  # mode 0600
        with os.fdopen(fd, "wb") as fh:
            fh.write(head + body)
        os.replace(tmp, path)
        tmp = None
    except Exception:  # a full disk, a read-only folder, another lark: the next process builds them again
        pass
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


@cache
def parser_for(start: str) -> Lark:
    """The parser from the grammar's rule ``start``: its tables loaded from the cache, else built (and kept)."""
    grammar = _grammar_text()
    where = _table_file(grammar, start)
    path = Path(where) if isinstance(where, str) else None
    key = _tables_key(grammar, start)
    if path is not None:
        kept = _load_tables(path, key)
        if kept is not None:
            return kept
    parser = Lark(grammar, parser="lalr", start=start, transformer=Build(), maybe_placeholders=True)
    if path is not None:
        _save_tables(parser, path, key)
    return parser
