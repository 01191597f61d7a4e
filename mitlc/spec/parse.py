"""Parse spec text into a checked :class:`~mitlc.spec.model.Spec`.

The one grammar is ``grammar/mitl.lark`` (shipped inside the wheel as
``mitlc/grammar/mitl.lark``).  One :class:`lark.Transformer` builds the AST
while the LALR parser runs, so deeply nested input cannot exhaust the Python
stack.  Every problem becomes a :class:`~mitlc.errors.SpecSyntaxError` or
:class:`~mitlc.errors.SpecError` with file, line and column.

>>> print(parse_formula("[] (a -> <>[0:2.5] b) && !c"))
G (a -> F[0,2.5] b) & !c
>>> parse_formula("F[2,1] a")
Traceback (most recent call last):
  ...
mitlc.errors.SpecError: <spec>:1:3: error: inverted interval [2,1]: the lower end must not exceed the upper
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import re
import sys
import tempfile
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import lark
from lark import Lark, Token, Transformer

from mitlc.errors import MitlError, SpecError, SpecSyntaxError
from mitlc.limits import MAX_SPEC_BYTES, MAX_TIME
from mitlc.plants.base import PLANTS, Plant, StateVar
from mitlc.plants.gym_env import GYM_PREFIX, ObsVar, check_env_id, env_info, gym_plant
from mitlc.spec import ast as A
from mitlc.spec import predicates as P
from mitlc.spec.model import CRITERIA, OPTIONS, InitRange, PropDef, Requirement, Spec

__all__ = ["parse_spec", "load_spec", "parse_formula", "parse_predicate", "MAX_DEPTH", "MAX_TREE", "RESERVED"]

MAX_DEPTH = 64
"""Deepest formula or predicate nesting accepted, in levels: a chain of one associative
operator (``a & b & c``) is one level (:func:`mitlc.spec.ast.nesting`)."""

MAX_TREE = 256
"""Deepest syntax tree accepted, counting each operand of a chain: what keeps every
recursive pass of the compiler, monitor and exports far from Python's stack limit."""

RESERVED = frozenset(
    [
        "F",
        "G",
        "U",
        "R",
        "W",
        "X",
        "true",
        "false",
        "True",
        "False",
        "inf",
        "infty",
        "not",
        "and",
        "or",
        "implies",
        "iff",
        "eventually",
        "always",
        "until",
        "release",
        "weak_until",
        "prop",
        "formula",
        "check",
        "plant",
        "init",
        "horizon",
        "option",
        "in",
        "pi",
        "e",
        "setpoint",
        "require",
        "band",
        "state",
    ]
)


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
        return Lark._load_from_dict(tables["data"], tables["memo"], transformer=_Build())
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
def _parser(start: str) -> Lark:
    grammar = _grammar_text()
    where = _table_file(grammar, start)
    path = Path(where) if isinstance(where, str) else None
    key = _tables_key(grammar, start)
    if path is not None:
        kept = _load_tables(path, key)
        if kept is not None:
            return kept
    parser = Lark(grammar, parser="lalr", start=start, transformer=_Build(), maybe_placeholders=True)
    if path is not None:
        _save_tables(parser, path, key)
    return parser


def _pos(tok: Token) -> A.Pos:
    return A.Pos(tok.line or 1, tok.column or 1)


def _num(tok: Token) -> float:
    return float(tok)


class _Bound:
    __slots__ = ("value", "pos")

    def __init__(self, value: float, pos: A.Pos) -> None:
        self.value, self.pos = value, pos


class _RawInterval:
    __slots__ = ("lo", "hi", "lo_closed", "hi_closed")

    def __init__(self, lo: _Bound, hi: _Bound, lo_closed: bool, hi_closed: bool) -> None:
        self.lo, self.hi, self.lo_closed, self.hi_closed = lo, hi, lo_closed, hi_closed


def _interval(raw: _RawInterval | None) -> A.Interval:
    if raw is None:
        return A.UNBOUNDED
    lo, hi = raw.lo.value, raw.hi.value
    text = f"{'[' if raw.lo_closed else '('}{A.fmt_number(lo)},{A.fmt_number(hi)}{']' if raw.hi_closed else ')'}"
    where = raw.lo.pos
    if lo < 0:
        raise SpecError(f"negative interval {text}: time starts at 0", line=where.line, column=where.column)
    if math.isinf(lo):
        raise SpecError(f"interval {text} starts at infinity", line=where.line, column=where.column)
    if lo > hi:
        raise SpecError(
            f"inverted interval {text}: the lower end must not exceed the upper",
            line=where.line,
            column=where.column,
        )
    if lo == hi and not (raw.lo_closed and raw.hi_closed):
        raise SpecError(f"empty interval {text}", line=where.line, column=where.column)
    # [a, inf] is read as [a, inf): infinity is never reached
    return A.Interval(lo, hi, raw.lo_closed, raw.hi_closed and not math.isinf(hi))


class _Build(Transformer):
    """Builds formula and predicate trees; one method per grammar alias."""

    # ---------------------------------------------------------- formulas
    def atom(self, children: list[Any]) -> A.Formula:
        (tok,) = children
        return A.Atom(str(tok), pos=_pos(tok))

    def inline_pred(self, children: list[Any]) -> A.Formula:
        pred = self.compare(children)
        pos = _first_pos(pred)
        return A.Atom(P.readable_name(pred), pos=pos, pred=pred)

    def true_(self, children: list[Any]) -> A.Formula:
        return A.Const(True, pos=_pos(children[0]))

    def false_(self, children: list[Any]) -> A.Formula:
        return A.Const(False, pos=_pos(children[0]))

    def not_(self, children: list[Any]) -> A.Formula:
        op, child = children
        return A.Not(child, pos=_pos(op))

    def weighted(self, children: list[Any]) -> A.Formula:
        tok, child = children
        w = _num(tok)
        if not (math.isfinite(w) and w > 0):
            raise SpecError(f"weight {tok} must be positive and finite", line=tok.line, column=tok.column)
        return A.Weighted(w, child, pos=_pos(tok))

    def eventually(self, children: list[Any]) -> A.Formula:
        op, interval, child = children
        return A.Eventually(child, _interval(interval), pos=_pos(op))

    def always(self, children: list[Any]) -> A.Formula:
        op, interval, child = children
        return A.Globally(child, _interval(interval), pos=_pos(op))

    def _timed_binary(self, cls: type, children: list[Any]) -> A.Formula:
        left, op, interval, right = children
        return cls(left, right, _interval(interval), pos=_pos(op))

    def until(self, children: list[Any]) -> A.Formula:
        return self._timed_binary(A.Until, children)

    def release(self, children: list[Any]) -> A.Formula:
        return self._timed_binary(A.Release, children)

    def weak_until(self, children: list[Any]) -> A.Formula:
        return self._timed_binary(A.WeakUntil, children)

    def _binary(self, cls: type, children: list[Any]) -> A.Formula:
        left, op, right = children
        return cls(left, right, pos=_pos(op))

    def and_(self, children: list[Any]) -> A.Formula:
        return self._binary(A.And, children)

    def or_(self, children: list[Any]) -> A.Formula:
        return self._binary(A.Or, children)

    def implies(self, children: list[Any]) -> A.Formula:
        return self._binary(A.Implies, children)

    def iff(self, children: list[Any]) -> A.Formula:
        return self._binary(A.Iff, children)

    # intervals: children are the two bounds
    def closed_closed(self, c: list[Any]) -> _RawInterval:
        return _RawInterval(c[0], c[1], True, True)

    def open_closed(self, c: list[Any]) -> _RawInterval:
        return _RawInterval(c[0], c[1], False, True)

    def closed_open(self, c: list[Any]) -> _RawInterval:
        return _RawInterval(c[0], c[1], True, False)

    def open_open(self, c: list[Any]) -> _RawInterval:
        return _RawInterval(c[0], c[1], False, False)

    # ---------------------------------------------------------- predicates
    # num/inf_ serve both interval bounds and arithmetic: they return _Bound for
    # bounds; the arithmetic rules unwrap it.
    def num(self, children: list[Any]) -> _Bound:
        (tok,) = children
        return _Bound(_num(tok), _pos(tok))

    def inf_(self, children: list[Any]) -> _Bound:
        (tok,) = children
        return _Bound(math.inf, _pos(tok))

    def var(self, children: list[Any]) -> P.Pred:
        (tok,) = children
        name = str(tok)
        if name in P.CONSTANTS:
            return P.Num(P.CONSTANTS[name], name=name)
        return P.Var(name, pos=_pos(tok))

    def call(self, children: list[Any]) -> P.Pred:
        tok, *args = children
        name = str(tok)
        if name not in P.FUNCTIONS:
            known = ", ".join(sorted(P.FUNCTIONS))
            raise SpecError(f"unknown function '{name}' (known: {known})", line=tok.line, column=tok.column)
        arity, _ = P.FUNCTIONS[name]
        if len(args) != arity:
            raise SpecError(
                f"{name}() takes {arity} argument{'s' if arity > 1 else ''}, got {len(args)}",
                line=tok.line,
                column=tok.column,
            )
        return P.Call(name, tuple(_arith(a) for a in args), pos=_pos(tok))

    def index(self, children: list[Any]) -> P.Pred:
        tok, num = children
        i = float(num)
        if not i.is_integer() or i >= 2**31:
            raise SpecError(
                f"an observation index is a whole number below 2**31, got '{num}'", line=num.line, column=num.column
            )
        if str(tok) != "obs":
            raise SpecError(
                f"'{tok}[...]': only the observation is indexed, as obs[i] in a 'state' line",
                line=tok.line,
                column=tok.column,
            )
        return P.Var(f"obs[{int(i)}]", pos=_pos(tok))

    def neg(self, children: list[Any]) -> P.Pred:
        (arg,) = children
        return P.Neg(_arith(arg))

    def binop(self, children: list[Any]) -> P.Pred:
        left, op, right = children
        return P.BinOp(str(op), _arith(left), _arith(right))

    def compare(self, children: list[Any]) -> P.Pred:
        operands = tuple(_arith(c) for c in children[0::2])
        ops = tuple(str(t) for t in children[1::2])
        return P.Compare(operands, ops)

    def p_and(self, children: list[Any]) -> P.Pred:
        return P.PAnd(_arith(children[0]), _arith(children[2]))

    def p_or(self, children: list[Any]) -> P.Pred:
        return P.POr(_arith(children[0]), _arith(children[2]))

    def p_not(self, children: list[Any]) -> P.Pred:
        return P.PNot(_arith(children[1]))

    # ---------------------------------------------------------- statements
    def prop_def(self, children: list[Any]) -> tuple:
        tok, pred = children
        return ("prop", tok, _arith(pred))

    def formula_def(self, children: list[Any]) -> tuple:
        return ("formula", children[0])

    def check_def(self, children: list[Any]) -> tuple:
        return ("check", children[0])

    def param(self, children: list[Any]) -> tuple:
        tok, value = children
        return (tok, _arith(value))

    def plant_def(self, children: list[Any]) -> tuple:
        tok, *params = children
        return ("plant", tok, [p for p in params if p is not None])

    def state_item(self, children: list[Any]) -> tuple:
        tok, expr, lo, hi = children
        return (tok, _arith(expr), None if lo is None else _arith(lo), None if hi is None else _arith(hi))

    def state_def(self, children: list[Any]) -> tuple:
        return ("state", children)

    def init_range(self, children: list[Any]) -> tuple:
        tok, lo, hi = children
        return (tok, _arith(lo), _arith(hi))

    def init_point(self, children: list[Any]) -> tuple:
        tok, value = children
        v = _arith(value)
        return (tok, v, v)

    def init_def(self, children: list[Any]) -> tuple:
        return ("init", children)

    def horizon_def(self, children: list[Any]) -> tuple:
        return ("horizon", _arith(children[1]), children[0])

    def setpoint_def(self, children: list[Any]) -> tuple:
        return ("setpoint", _arith(children[1]), children[0])

    def require_bound(self, children: list[Any]) -> tuple:
        tok, cmp, value, band = children
        if str(cmp) not in ("<=", "<"):
            raise SpecError(
                f"a requirement is an upper bound ('require {tok} <= value') or a range "
                f"('require {tok} in [a, b]'), not '{cmp}'",
                line=cmp.line,
                column=cmp.column,
            )
        return ("require", tok, None, _arith(value), None if band is None else _arith(band))

    def require_range(self, children: list[Any]) -> tuple:
        tok, lo, hi, band = children
        return ("require", tok, _arith(lo), _arith(hi), None if band is None else _arith(band))

    def option_def(self, children: list[Any]) -> tuple:
        tok, value = children
        return ("option", tok, value)

    def start(self, children: list[Any]) -> list:
        return children


def _first_pos(p: P.Pred) -> A.Pos | None:
    """Where a predicate starts in the text: its leftmost node that knows (else its first variable's)."""
    node: P.Pred | None = p
    while node is not None:
        pos = getattr(node, "pos", None)
        if pos is not None:
            return pos
        kids = node.children
        node = kids[0] if kids else None
    for v in P.variables(p):
        if v.pos is not None:
            return v.pos
    return None


def _arith(x: Any) -> P.Pred:
    if isinstance(x, _Bound):
        return P.Num(x.value)
    return x


# -------------------------------------------------------------- error mapping

_FRIENDLY = {
    "NAME": "a name",
    "PLANT_NAME": "a plant name",
    "NUMBER": "a number",
    "$END": "end of input",
    "LPAR": "'('",
    "RPAR": "')'",
    "LSQB": "'['",
    "RSQB": "']'",
    "COMMA": "','",
    "EQUAL": "'='",
    "STAR": "'*'",
    "MINUS": "'-'",
    "PLUS": "'+'",
    "CMP": "a comparison",
    "ADDOP": "'+' or '-'",
    "MULOP": "'*' or '/'",
    "NOT": "'!'",
    "AND": "'&'",
    "OR": "'|'",
    "IMPLIES": "'->'",
    "IFF": "'<->'",
    "FINALLY": "'F'",
    "GLOBALLY": "'G'",
    "UNTIL": "'U'",
    "RELEASE": "'R'",
    "WEAK": "'W'",
    "TRUE": "'true'",
    "FALSE": "'false'",
    "INF": "'inf'",
    "_SEP": "',' or ':'",
}


def _friendly(names: set[str]) -> str:
    out = set()
    for n in names:
        if n in _FRIENDLY:
            out.add(_FRIENDLY[n])
        elif n.startswith("_") and n[1:].isupper():
            out.add(f"'{n[1:].lower()}'")
        else:
            out.add(n.lower())
    items = sorted(out)
    if len(items) > 8:
        items = items[:8] + ["..."]
    return ", ".join(items)


def _lines(text: str) -> list[str]:
    """The lines as the parser counts them (only "\\n" ends one; a last empty line after a final
    newline is not a line), at least one."""
    lines = text.split("\n")
    if len(lines) > 1 and lines[-1] == "":
        lines.pop()
    return [ln.removesuffix("\r") for ln in lines]


def _syntax_error(exc: lark.exceptions.UnexpectedInput, text: str) -> SpecSyntaxError:
    if isinstance(exc, lark.exceptions.UnexpectedCharacters):
        pos: int = exc.pos_in_stream  # type: ignore[assignment]  # lark types it None; the lexer always sets an int
        ch = text[pos] if pos < len(text) else "?"
        return SpecSyntaxError(f"unexpected character {ch!r}", line=exc.line, column=exc.column, source=text)
    if isinstance(exc, lark.exceptions.UnexpectedToken):
        tok = exc.token
        if tok.type == "$END":
            lines = _lines(text)
            line, col = len(lines), len(lines[-1]) + 1
            return SpecSyntaxError(
                f"unexpected end of input, expected {_friendly(set(exc.expected))}",
                line=line,
                column=col,
                source=text,
            )
        return SpecSyntaxError(
            f"unexpected {str(tok)!r}, expected {_friendly(set(exc.expected))}",
            line=tok.line,
            column=tok.column,
            source=text,
            hint=_comparison_hint(tok, set(exc.expected)),
        )
    lines = _lines(text)
    return SpecSyntaxError("unexpected end of input", line=len(lines), column=len(lines[-1]) + 1, source=text)


def _comparison_hint(tok: Token, expected: set[str]) -> str | None:
    """What to write instead, at a comparison the formula grammar does not take."""
    if tok.type == "CMP":
        return (
            "a comparison in a formula compares numbers, and its left side starts with a name, a number or a "
            "call, not '(' (which opens a formula): G (abs(q) < 0.3), 2 > (q + 1); or name it: prop kappa = ..."
        )
    if tok.type == "RPAR" and "CMP" in expected:
        return (
            "inside a formula '(' opens a formula, so a comparison cannot start with one: write q + 1 < 2 or "
            "2 > (q + 1), or name it with 'prop NAME = ...'"
        )
    return None


def _run(start: str, text: str, path: str | None) -> Any:
    try:
        return _parser(start).parse(text)
    except lark.exceptions.UnexpectedInput as exc:
        raise _syntax_error(exc, text).located(path) from None
    except lark.exceptions.VisitError as exc:  # pragma: no cover - lark wraps some callbacks
        inner = exc.orig_exc
        if isinstance(inner, MitlError):
            raise inner.located(path, text) from None
        raise
    except MitlError as exc:
        raise exc.located(path, text) from None


# -------------------------------------------------------------- checks


def _too_deep(tree: Any, what: str) -> str | None:
    """Why ``tree`` is refused for its shape (:data:`MAX_DEPTH`, :data:`MAX_TREE`), or None."""
    levels, depth = A.nesting(tree)  # iterative: safe on the deepest input
    if levels > MAX_DEPTH:
        return f"{what} nesting too deep (more than {MAX_DEPTH} levels)"
    if depth > MAX_TREE:
        return (
            f"{what} too long: its tree is more than {MAX_TREE} operators deep (a chain such as a & b & ... "
            "counts one per operand); split it into propositions or shorter parts"
        )
    return None


def _check_depth(f: A.Formula) -> None:
    problem = _too_deep(f, "formula")
    if problem is not None:
        pos = getattr(f, "pos", None)
        raise SpecError(
            problem,
            line=pos.line if pos else None,
            column=pos.column if pos else None,
        )


def _check_weights(f: A.Formula, text: str) -> None:
    """The weights of ``f``: their products along each path must stay finite (an infinite
    reward), and ``10 * q < 1``, which reads as the weight 10 on ``q < 1``, must say so with
    parentheses. The overflow is looked for first, over the whole formula."""
    lines = text.split("\n")

    def offset(pos: A.Pos) -> int:
        return sum(len(line) + 1 for line in lines[: pos.line - 1]) + pos.column - 1

    stack: list[tuple[A.Formula, float]] = [(f, 1.0)]  # the product of the weights above each node
    while stack:
        node, w = stack.pop()
        if isinstance(node, A.Weighted):
            w *= node.weight
            if not math.isfinite(w):
                pos = node.pos or A.Pos(1, 1)
                raise SpecError(
                    f"the weights multiply to more than the largest number ({A.fmt_number(node.weight)} * ...): "
                    "a reward that large is infinite",
                    line=pos.line,
                    column=pos.column,
                )
        stack.extend((c, w) for c in node.children)
    for node in A.walk(f):
        if not (isinstance(node, A.Weighted) and isinstance(node.child, A.Atom) and node.child.pred is not None):
            continue
        if node.pos is None or node.child.pos is None:
            continue
        if "(" not in text[offset(node.pos) : offset(node.child.pos)]:
            wt, pred = A.fmt_number(node.weight), node.child.pred
            raise SpecError(
                f"'{wt} * {pred}' is ambiguous: write {wt} * ({pred}) for a weighted proposition; a product "
                "inside a comparison puts the number after the name (q * 2 < 1)",
                line=node.child.pos.line,
                column=node.child.pos.column,
            )


def _line_ends(text: str) -> str:
    """``text`` with each lone carriage return (old Mac line ends) made a line feed: the lexer ends a line
    (and a comment) at ``\n`` only, so a spec of CR-only lines would read as one line. ``\r\n`` is left as
    it is: it parses the same (``\r`` is white space), and the text's hash, which a training or a sweep
    records, stays the same."""
    return _LONE_CR.sub("\n", text) if "\r" in text else text


_LONE_CR = re.compile(r"\r(?!\n)")


def parse_formula(text: str) -> A.Formula:
    """Parse one formula (no spec statements)."""
    text = _line_ends(text)
    f = _run("formula", text, None)
    try:
        _check_depth(f)
        _check_weights(f, text)
    except MitlError as exc:
        raise exc.located(None, text) from None
    return f


def parse_predicate(text: str) -> P.Pred:
    """Parse one predicate over state variables."""
    return _arith(_run("pred", _line_ends(text), None))


def _const(p: P.Pred, what: str, pos: Token) -> float:
    problem = _too_deep(p, f"{what}:")
    if problem is not None:
        raise SpecError(problem, line=pos.line, column=pos.column)
    if P.is_boolean(p):
        raise SpecError(f"{what} must be a number, not a condition", line=pos.line, column=pos.column)
    names = P.variables(p)
    if names:
        v = names[0]
        where = v.pos or _pos(pos)
        raise SpecError(f"{what} must be a constant, but uses '{v.name}'", line=where.line, column=where.column)
    value = P.const_value(p)
    assert value is not None
    if math.isnan(value):
        raise SpecError(f"{what} is not a number", line=pos.line, column=pos.column)
    return value


def parse_spec(text: str, path: str | None = None) -> Spec:
    """Parse and check a whole spec; raise a located :class:`MitlError` if it is wrong.

    A lone carriage return ends a line as ``\n`` does (:func:`_line_ends`; ``source`` is the text so read)."""
    text = _line_ends(text)
    try:
        return _parse_spec(text, path)
    except MitlError as exc:
        raise exc.located(path, text) from None


def _parse_spec(text: str, path: str | None) -> Spec:
    statements = _run("start", text, path)
    warnings: list[str] = []
    props: dict[str, PropDef] = {}
    formula = check = None
    plant_name: str | None = None
    plant_params: dict[str, float] = {}
    init: dict[str, InitRange] = {}
    horizon: float | None = None
    options: dict[str, str] = {}
    setpoint: float | None = None
    requirements: dict[str, Requirement] = {}
    seen: dict[str, Token] = {}

    def once(key: str, tok: Token) -> None:
        if key in seen:
            first = seen[key]
            raise SpecError(f"'{key}' given twice (first at line {first.line})", line=tok.line, column=tok.column)
        seen[key] = tok

    # Plant first: the state variables it declares are needed to check predicates.
    env_plant = None
    state_lines = [st for st in statements if st[0] == "state"]
    for st in statements:
        if st[0] == "plant" and str(st[1]).startswith(GYM_PREFIX):
            _, tok, params = st
            once("plant", tok)
            plant_name = str(tok)
            env_plant, plant_params = _env_plant(tok, params, state_lines)
        elif st[0] == "plant":
            _, tok, params = st
            once("plant", tok)
            name = str(tok)
            if name not in PLANTS:
                from mitlc.plants.user import discover

                discover()  # installed packages' mitlc.plants entry points
            if name not in PLANTS:
                raise SpecError(
                    f"unknown plant '{name}' (known: {', '.join(sorted(PLANTS))})",
                    line=tok.line,
                    column=tok.column,
                    hint="a plant of your own: --plant-file FILE.py (or module:attribute), or an installed "
                    "package's 'mitlc.plants' entry point; mitlc plants lists the known ones (mitlc docs plants)",
                )
            plant_name = name
            for ptok, value in params:
                pname = str(ptok)
                if pname in plant_params:
                    raise SpecError(f"parameter '{pname}' given twice", line=ptok.line, column=ptok.column)
                if pname not in PLANTS[name].defaults:
                    raise SpecError(
                        f"plant '{name}' has no parameter '{pname}' "
                        f"(known: {', '.join(sorted(PLANTS[name].defaults))})",
                        line=ptok.line,
                        column=ptok.column,
                    )
                v = _const(value, f"parameter '{pname}'", ptok)
                if not (math.isfinite(v) and v > 0):
                    raise SpecError(
                        f"parameter '{pname}' must be positive and finite, got {A.fmt_number(v)}",
                        line=ptok.line,
                        column=ptok.column,
                    )
                plant_params[pname] = v
    if state_lines and env_plant is None:
        tok = state_lines[0][1][0][0]
        raise SpecError(
            "a 'state' line maps a Gymnasium environment's observation (plant gym:ID); "
            + (f"plant '{plant_name}' declares its own state variables" if plant_name else "the spec names no plant"),
            line=tok.line,
            column=tok.column,
        )
    plant = env_plant if env_plant is not None else PLANTS.get(plant_name) if plant_name else None
    state_names = set(plant.state_names) if plant else None

    def check_vars(pred: P.Pred) -> None:
        for v in P.variables(pred):
            pos = v.pos or A.Pos(1, 1)
            if v.name.startswith("obs["):
                raise SpecError(
                    f"'{v.name}' reads the observation only in a 'state' line; name it there "
                    "(state NAME = obs[i]) and use the name",
                    line=pos.line,
                    column=pos.column,
                )
            if v.name in props and (state_names is None or v.name not in state_names):
                raise SpecError(
                    f"'{v.name}' is a proposition, not a number: a comparison compares state variables",
                    line=pos.line,
                    column=pos.column,
                    hint=f"to use {v.name} in a formula write it on its own (G {v.name}); a predicate is "
                    "written as a comparison, e.g. abs(q) < 0.3",
                )
            if state_names is not None and v.name not in state_names:
                raise SpecError(
                    f"unknown state variable '{v.name}' (plant '{plant_name}' has: {', '.join(plant.state_names)})",  # type: ignore[union-attr]
                    line=pos.line,
                    column=pos.column,
                    hint=(f"map it to the observation: state {v.name} = obs[i]" if env_plant is not None else None),
                )

    for st in statements:
        kind = st[0]
        if kind == "prop":
            _, tok, pred = st
            name = str(tok)
            if name in RESERVED:
                raise SpecError(
                    f"'{name}' is a reserved word and cannot name a proposition",
                    line=tok.line,
                    column=tok.column,
                )
            if name in props:
                first = props[name].pos
                raise SpecError(
                    f"proposition '{name}' defined twice (first at line {first.line if first else '?'})",
                    line=tok.line,
                    column=tok.column,
                )
            if not P.is_boolean(pred):
                raise SpecError(
                    f"proposition '{name}' must be a condition such as 'abs(q) < 0.3', not a number",
                    line=tok.line,
                    column=tok.column,
                )
            problem = _too_deep(pred, f"predicate of '{name}':")
            if problem is not None:
                raise SpecError(
                    problem,
                    line=tok.line,
                    column=tok.column,
                )
            check_vars(pred)
            props[name] = PropDef(name, pred, pos=_pos(tok))
        elif kind in ("formula", "check"):
            f = st[1]
            _check_depth(f)
            if kind == "formula":
                if formula is not None:
                    pos = getattr(f, "pos", None) or A.Pos(1, 1)
                    raise SpecError("more than one 'formula'", line=pos.line, column=pos.column)
                formula = f
            else:
                if check is not None:
                    pos = getattr(f, "pos", None) or A.Pos(1, 1)
                    raise SpecError("more than one 'check'", line=pos.line, column=pos.column)
                check = f
        elif kind == "init":
            for tok, lo_p, hi_p in st[1]:
                var = str(tok)
                if state_names is not None and var not in state_names:
                    raise SpecError(
                        f"unknown state variable '{var}' in init (plant '{plant_name}' has: "
                        f"{', '.join(sorted(state_names))})",
                        line=tok.line,
                        column=tok.column,
                    )
                if var in init:
                    raise SpecError(f"initial range of '{var}' given twice", line=tok.line, column=tok.column)
                lo = _const(lo_p, f"initial bound of '{var}'", tok)
                hi = _const(hi_p, f"initial bound of '{var}'", tok)
                if not (math.isfinite(lo) and math.isfinite(hi) and math.isfinite(hi - lo)):
                    raise SpecError(
                        f"initial range of '{var}' must be finite (and its width too), got "
                        f"[{A.fmt_number(lo)}, {A.fmt_number(hi)}]",
                        line=tok.line,
                        column=tok.column,
                    )
                if lo > hi:
                    raise SpecError(
                        f"inverted initial range of '{var}': [{A.fmt_number(lo)}, {A.fmt_number(hi)}]",
                        line=tok.line,
                        column=tok.column,
                    )
                init[var] = InitRange(var, lo, hi)
        elif kind == "horizon":
            _, value, tok = st
            h = _const(value, "horizon", tok)
            if not (math.isfinite(h) and h > 0):
                raise SpecError(
                    f"horizon must be positive and finite, got {A.fmt_number(h)}", line=tok.line, column=tok.column
                )
            if h > MAX_TIME:
                raise SpecError(
                    f"horizon {A.fmt_number(h)} s is longer than the longest supported, {A.fmt_number(MAX_TIME)} s",
                    line=tok.line,
                    column=tok.column,
                )
            once("horizon", tok)
            horizon = h
        elif kind == "setpoint":
            _, value, tok = st
            once("setpoint", tok)
            setpoint = _const(value, "setpoint", tok)
            if not math.isfinite(setpoint):
                raise SpecError("setpoint must be finite", line=tok.line, column=tok.column)
        elif kind == "require":
            _, tok, lo_p, hi_p, band_p = st
            name = str(tok)
            if name not in CRITERIA:
                raise SpecError(
                    f"unknown criterion '{name}' (known: {', '.join(CRITERIA)})", line=tok.line, column=tok.column
                )
            if name in requirements:
                raise SpecError(f"criterion '{name}' required twice", line=tok.line, column=tok.column)
            hi = _const(hi_p, f"bound of {name}", tok)
            lo = 0.0 if lo_p is None else _const(lo_p, f"bound of {name}", tok)
            if not (math.isfinite(lo) and math.isfinite(hi)) or lo < 0 or lo > hi:
                raise SpecError(
                    f"bounds of {name} must be finite with 0 <= lower <= upper, got "
                    f"[{A.fmt_number(lo)}, {A.fmt_number(hi)}]",
                    line=tok.line,
                    column=tok.column,
                )
            band = None
            if band_p is not None:
                if name != "settling_time":
                    raise SpecError(f"only settling_time takes a band, not {name}", line=tok.line, column=tok.column)
                band = _const(band_p, "band", tok)
                if not 0 < band < 1:
                    raise SpecError(
                        f"band must be a fraction in (0, 1), got {A.fmt_number(band)}", line=tok.line, column=tok.column
                    )
            requirements[name] = Requirement(name, lo, hi, band, pos=_pos(tok))
        elif kind == "option":
            _, tok, value = st
            key = str(tok)
            if key not in OPTIONS:
                raise SpecError(
                    f"unknown option '{key}' (known: {', '.join(sorted(OPTIONS))})",
                    line=tok.line,
                    column=tok.column,
                )
            val = str(value) if isinstance(value, Token) else str(value)
            if val not in OPTIONS[key]:
                raise SpecError(
                    f"option '{key}' must be one of {', '.join(OPTIONS[key])}, got '{val}'",
                    line=tok.line,
                    column=tok.column,
                )
            once(f"option {key}", tok)
            options[key] = val

    if formula is None and not requirements:
        lines = _lines(text)
        raise SpecError("the spec has no 'formula' (nor any 'require')", line=len(lines), column=1)

    for f in (formula, check):
        if f is None:
            continue
        _check_weights(f, text)
        for node in A.walk(f):  # inline predicates become propositions named after their text
            if not (isinstance(node, A.Atom) and isinstance(node.pred, P.Pred)):
                continue
            pos = node.pos or A.Pos(1, 1)
            known = props.get(node.name)
            if known is not None:
                if str(known.pred) != str(node.pred):
                    raise SpecError(
                        f"the inline predicate '{node.pred}' is named '{node.name}', which a prop line defines "
                        f"as '{known.pred}': rename that proposition",
                        line=pos.line,
                        column=pos.column,
                    )
                continue
            problem = _too_deep(node.pred, "inline predicate:")
            if problem is not None:
                raise SpecError(
                    problem,
                    line=pos.line,
                    column=pos.column,
                )
            check_vars(node.pred)
            props[node.name] = PropDef(node.name, node.pred, pos=pos, inline=True)
        for node in A.walk(f):
            if isinstance(node, A.Atom) and node.name not in props:
                pos = node.pos or A.Pos(1, 1)
                hint = f"defined: {', '.join(props)}" if props else "define it with 'prop NAME = condition'"
                raise SpecError(f"undefined proposition '{node.name}'", line=pos.line, column=pos.column, hint=hint)
    used = set(A.atoms(formula)) if formula is not None else set()
    used |= set(A.atoms(check)) if check is not None else set()
    for name, p in props.items():
        if name not in used:
            pos = p.pos or A.Pos(1, 1)
            warnings.append(f"{path or '<spec>'}:{pos.line}:{pos.column}: warning: proposition '{name}' is never used")

    return Spec(
        formula=formula,
        props=tuple(props.values()),
        check=check,
        plant_name=plant_name,
        plant_params=tuple(plant_params.items()),
        init=tuple(init.values()),
        horizon=horizon,
        options=tuple(options.items()),
        setpoint=0.0 if setpoint is None else setpoint,
        requirements=tuple(requirements.values()),
        path=path,
        source=text,
        warnings=tuple(warnings),
        env_plant=env_plant,
    )


def _columns(index: dict[str, int]) -> Any:
    """How compile_numpy reads ``obs[i]`` off a flattened observation batch ``(B, m)``."""

    def var(name: str) -> Any:
        i = index[name]
        return lambda flat: flat[:, i]

    return var


def _env_plant(tok: Token, params: list, state_lines: list) -> tuple[Plant, dict[str, float]]:
    """The plant of ``plant gym:ID(...)`` and its ``state`` lines (:mod:`mitlc.plants.gym_env`)."""
    env_id = str(tok)[len(GYM_PREFIX) :]
    try:
        check_env_id(env_id)  # first: 'gym:module:Env' would make Gymnasium import module
    except MitlError as exc:
        raise SpecError(exc.message, line=tok.line, column=tok.column, hint=exc.hint) from None
    values: dict[str, float] = {}
    for ptok, value in params:
        pname = str(ptok)
        if pname in values:
            raise SpecError(f"parameter '{pname}' given twice", line=ptok.line, column=ptok.column)
        number = _const(value, f"parameter '{pname}'", ptok)
        if not math.isfinite(number):
            raise SpecError(f"parameter '{pname}' must be finite", line=ptok.line, column=ptok.column)
        values[pname] = number
    dt_given = values.pop("dt", None)
    try:
        info = env_info(env_id, values)
    except MitlError as exc:
        raise SpecError(exc.message, line=tok.line, column=tok.column, hint=exc.hint) from None
    if dt_given is not None:
        if not dt_given > 0:
            raise SpecError(
                f"parameter 'dt' must be positive, got {A.fmt_number(dt_given)}", line=tok.line, column=tok.column
            )
        dt = dt_given
    elif info.dt is not None:
        dt = info.dt
        if not (math.isfinite(dt) and dt > 0):
            raise SpecError(
                f"{info.dt_where} is {dt}, not a positive time: give {tok}(dt = ...)", line=tok.line, column=tok.column
            )
    else:
        raise SpecError(
            f"'{env_id}' keeps no time step (no dt, tau or metadata['dt']): give the seconds per step, "
            f"plant {tok}(dt = ...)",
            line=tok.line,
            column=tok.column,
        )
    if not state_lines:
        raise SpecError(
            f"plant '{tok}' needs its state variables mapped to the observation "
            f"({len(info.obs_low)} entries): add a line such as 'state x = obs[0]'",
            line=tok.line,
            column=tok.column,
        )
    size = len(info.obs_low)
    observe: list[ObsVar] = []
    for st in state_lines:
        for ntok, expr, lo_p, hi_p in st[1]:
            name = str(ntok)
            if name in RESERVED or name in P.CONSTANTS:
                raise SpecError(
                    f"'{name}' is a reserved word and cannot name a state variable", line=ntok.line, column=ntok.column
                )
            if any(o.var.name == name for o in observe):
                raise SpecError(f"state variable '{name}' mapped twice", line=ntok.line, column=ntok.column)
            if P.is_boolean(expr):
                raise SpecError(
                    f"state variable '{name}' must be a number read off the observation, not a condition",
                    line=ntok.line,
                    column=ntok.column,
                )
            index: dict[str, int] = {}
            for v in P.variables(expr):
                pos = v.pos or _pos(ntok)
                if not v.name.startswith("obs["):
                    raise SpecError(
                        f"a 'state' line reads the observation: write obs[i] (entry i of the flattened "
                        f"observation), not '{v.name}'",
                        line=pos.line,
                        column=pos.column,
                    )
                i = int(v.name[4:-1])
                if i >= size:
                    raise SpecError(
                        f"{v.name} is outside the observation of '{env_id}' "
                        f"({size} entries: obs[0] to obs[{size - 1}])",
                        line=pos.line,
                        column=pos.column,
                    )
                index[v.name] = i
            if not index:
                raise SpecError(
                    f"state variable '{name}' reads nothing of the observation", line=ntok.line, column=ntok.column
                )
            angle = isinstance(expr, P.Call) and expr.fn == "atan2"
            if lo_p is not None:
                lo = _const(lo_p, f"lower bound of '{name}'", ntok)
                hi = _const(hi_p, f"upper bound of '{name}'", ntok)
            elif angle:
                lo, hi = -math.pi, math.pi
            elif isinstance(expr, P.Var):
                lo, hi = float(info.obs_low[index[expr.name]]), float(info.obs_high[index[expr.name]])
                if not (math.isfinite(lo) and math.isfinite(hi)):
                    raise SpecError(
                        f"{expr.name} of '{env_id}' is unbounded ([{A.fmt_number(lo)}, {A.fmt_number(hi)}]): "
                        f"give its range, state {name} = {expr.name} in [lo, hi]",
                        line=ntok.line,
                        column=ntok.column,
                    )
            else:
                raise SpecError(
                    f"give the range of '{name}': state {name} = {expr} in [lo, hi]",
                    line=ntok.line,
                    column=ntok.column,
                )
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise SpecError(
                    f"the range of '{name}' must be finite with lower < upper, "
                    f"got [{A.fmt_number(lo)}, {A.fmt_number(hi)}]",
                    line=ntok.line,
                    column=ntok.column,
                )
            read = P.compile_numpy(expr, _columns(index))
            observe.append(ObsVar(StateVar(name, lo, hi, periodic=angle), read, str(expr)))
    plant = gym_plant(env_id, values, observe, dt, info)
    return plant, {**values, "dt": dt}


def load_spec(path: str | Path) -> Spec:
    """Read and check a ``.mitl`` file, or a shipped spec by name (``pendulum/p2_avoid``).

    A file of that name wins; without one, the shipped specs
    (:mod:`mitlc.spec.library`, ``mitlc specs`` lists them) are looked up.
    """
    from mitlc.spec import library

    p = Path(path)
    if not p.exists() and (shipped := library.find(str(path))) is not None:
        return parse_spec(shipped.read_text(), shipped.origin)
    try:
        if p.exists() and not p.is_file():  # a directory, a device (/dev/zero), a FIFO: not a spec
            kind = "a directory" if p.is_dir() else "not a regular file"
            raise SpecError(f"cannot read spec: {kind}", file=str(path))
        with p.open("rb") as fh:
            raw = fh.read(MAX_SPEC_BYTES + 1)
    except OSError as exc:
        hint = None
        if not p.exists():
            hint = "no file of that name, and no shipped spec either (mitlc specs lists them, e.g. pendulum/p2_avoid)"
        raise SpecError(f"cannot read spec: {exc.strerror or exc}", file=str(path), hint=hint) from None
    if len(raw) > MAX_SPEC_BYTES:
        raise SpecError(f"spec is larger than {MAX_SPEC_BYTES >> 10} KiB, the most a spec may be", file=str(path))
    try:
        text = raw.decode("utf-8-sig")  # a byte-order mark at the start is allowed
    except UnicodeDecodeError as exc:
        raise SpecError(f"spec is not UTF-8 text (byte {exc.start})", file=str(path)) from None
    return parse_spec(text, str(path))


def with_inline_props(spec: Spec, f: A.Formula) -> Spec:
    """``spec`` with the inline predicates of ``f``, a formula given apart from the spec (``mitlc check
    --formula 'abs(q) < 0.3 U[0,1] (qdot > 1)'``), added as propositions, named and checked as a
    spec's own are: a name that a prop line defines otherwise, a predicate nested too deep, an
    unknown state variable or a proposition used as a number is a :class:`SpecError` at the predicate.

    >>> spec = parse_spec("plant pendulum\\nprop up = abs(q) < 0.3\\nformula F up")
    >>> [p.name for p in with_inline_props(spec, parse_formula("up U[0,1] (qdot > 1)")).props]
    ['up', 'qdot_gt_1']
    """
    import dataclasses  # here, not at the top: this function is an addition kept apart

    props = {p.name: p for p in spec.props}
    plant = spec.plant
    state = set(plant.state_names) if plant is not None else None
    for node in A.walk(f):
        if not (isinstance(node, A.Atom) and isinstance(node.pred, P.Pred)):
            continue
        pos = node.pos or A.Pos(1, 1)
        known = props.get(node.name)
        if known is not None:
            if str(known.pred) != str(node.pred):
                raise SpecError(
                    f"the inline predicate '{node.pred}' is named '{node.name}', which the spec defines "
                    f"as '{known.pred}': write that proposition's name, or another predicate",
                    line=pos.line,
                    column=pos.column,
                )
            continue
        problem = _too_deep(node.pred, "inline predicate:")
        if problem is not None:
            raise SpecError(problem, line=pos.line, column=pos.column)
        for v in P.variables(node.pred):
            where = v.pos or pos
            if v.name in props and (state is None or v.name not in state):
                raise SpecError(
                    f"'{v.name}' is a proposition, not a number: a comparison compares state variables",
                    line=where.line,
                    column=where.column,
                )
            if plant is not None and state is not None and v.name not in state:
                raise SpecError(
                    f"unknown state variable '{v.name}' (plant '{plant.name}' has: {', '.join(plant.state_names)})",
                    line=where.line,
                    column=where.column,
                )
        props[node.name] = PropDef(node.name, node.pred, pos=pos, inline=True)
    if len(props) == len(spec.props):
        return spec
    return dataclasses.replace(spec, props=tuple(props.values()))
