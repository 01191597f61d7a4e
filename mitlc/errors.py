"""One error tree for every stage.

Every error a user can cause is a :class:`MitlError`.  It carries where it
happened (file, line, column) so the CLI can print one clear line, followed by
the offending source line with a caret when the source is known.

>>> err = SpecError("undefined proposition 'kapa'", file="p.mitl", line=3, column=11,
...                 source="formula F kapa")
>>> print(err.headline())
p.mitl:3:11: error: undefined proposition 'kapa'
"""

from __future__ import annotations

import re

__all__ = [
    "MitlError",
    "SpecSyntaxError",
    "SpecError",
    "CompileError",
    "TrainingError",
    "InputError",
    "shorten_names",
    "NAME_CHARS",
]


_CONTEXT = 100
"""Characters of the offending line shown around the column."""

NAME_CHARS = 60
"""A name longer than this is cut in a message (its first characters and ``...``): a 900 KB
identifier is said in 60 characters, not echoed whole."""

_LONG_NAME = re.compile(rf"[A-Za-z_][A-Za-z0-9_]{{{NAME_CHARS},}}")


def shorten_names(text: str) -> str:
    """``text`` with each name longer than :data:`NAME_CHARS` cut to that many characters, ``...`` last
    (hexadecimal digests, such as a SHA-256, are left whole).

    >>> shorten_names("undefined proposition '" + "a" * 1000 + "'")
    "undefined proposition 'aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa...'"
    """

    def cut(m: re.Match[str]) -> str:
        name = m.group(0)
        if re.fullmatch(r"[0-9a-f]+", name) and re.search(r"[0-9]", name):  # a digest, not a name
            return name
        return name[: NAME_CHARS - 3] + "..."

    return _LONG_NAME.sub(cut, text)


class MitlError(Exception):
    """Root of all mitlc errors a user can cause."""

    kind = "error"

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        line: int | None = None,
        column: int | None = None,
        source: str | None = None,
        hint: str | None = None,
    ) -> None:
        message = shorten_names(message)
        hint = shorten_names(hint) if hint is not None else None
        super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.column = column
        self.source = source
        self.hint = hint

    def located(self, file: str | None = None, source: str | None = None) -> MitlError:
        """Fill in the file name and source text if they are not known yet."""
        if self.file is None:
            self.file = file
        if self.source is None:
            self.source = source
        return self

    def where(self) -> str:
        parts = [self.file or "<spec>"]
        if self.line is not None:
            parts.append(str(self.line))
            if self.column is not None:
                parts.append(str(self.column))
        return ":".join(parts)

    def headline(self) -> str:
        """The one-line message: ``file:line:col: error: message``."""
        return f"{self.where()}: {self.kind}: {self.message}"

    def context(self) -> str:
        """The offending source line with a caret under the column, or ''."""
        if self.source is None or self.line is None:
            return ""
        lines = self.source.split("\n")  # lines as the lexer counts them (not form feeds or U+2028)
        if not 1 <= self.line <= len(lines):
            return ""
        text = lines[self.line - 1].rstrip("\r").expandtabs(1)
        text = "".join(ch if ch.isprintable() else " " for ch in text)  # a form feed shows as a space
        col = (self.column or 1) - 1
        if len(text) > _CONTEXT:  # a window around the column, marked where it cuts
            start = max(0, min(col - _CONTEXT // 2, len(text) - _CONTEXT))
            end = start + _CONTEXT
            text = ("..." if start else "") + text[start:end] + ("..." if end < len(text) else "")
            col = col - start + (3 if start else 0)
        caret = " " * col + "^"
        return f"  {text}\n  {caret}"

    def render(self) -> str:
        out = [self.headline()]
        ctx = self.context()
        if ctx:
            out.append(ctx)
        if self.hint:
            out.append(f"  hint: {self.hint}")
        return "\n".join(out)

    def __str__(self) -> str:
        return self.headline()


class SpecSyntaxError(MitlError):
    """The spec text does not follow the grammar."""

    kind = "syntax error"


class SpecError(MitlError):
    """The spec parses but means nothing sensible (undefined names, bad intervals...)."""


class CompileError(MitlError):
    """The formula cannot be turned into a reward net."""


class TrainingError(MitlError):
    """Training cannot go on (diverging parameters, bad settings)."""


class InputError(MitlError):
    """A data file or an option given to a command is unusable."""
