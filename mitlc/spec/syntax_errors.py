"""Lark's syntax errors as mitlc's messages: a :class:`~mitlc.errors.SpecSyntaxError` at the
line and column, saying in words what was expected (``a name``, ``')'``), with a hint at a
comparison the formula grammar does not take.
"""

from __future__ import annotations

import lark
from lark import Token

from mitlc.errors import SpecSyntaxError

__all__ = ["syntax_error", "text_lines"]


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


def text_lines(text: str) -> list[str]:
    """The lines as the parser counts them (only "\\n" ends one; a last empty line after a final
    newline is not a line), at least one."""
    lines = text.split("\n")
    if len(lines) > 1 and lines[-1] == "":
        lines.pop()
    return [ln.removesuffix("\r") for ln in lines]


def syntax_error(exc: lark.exceptions.UnexpectedInput, text: str) -> SpecSyntaxError:
    """Lark's ``exc`` on ``text`` as one located message."""
    if isinstance(exc, lark.exceptions.UnexpectedCharacters):
        pos: int = exc.pos_in_stream  # type: ignore[assignment]  # lark types it None; the lexer always sets an int
        ch = text[pos] if pos < len(text) else "?"
        return SpecSyntaxError(f"unexpected character {ch!r}", line=exc.line, column=exc.column, source=text)
    if isinstance(exc, lark.exceptions.UnexpectedToken):
        tok = exc.token
        if tok.type == "$END":
            lines = text_lines(text)
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
    lines = text_lines(text)
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
