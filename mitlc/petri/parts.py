"""Sub-nets under construction: what each builder of the compiler hands to the assembly.

A :class:`Part` names its places (local indices), its arcs between them with guards, and
its initially marked place; :meth:`mitlc.petri.compile.compile_spec` numbers them into
one :class:`~mitlc.petri.net.Net`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from mitlc.petri import reward as R
from mitlc.petri.net import Guard

__all__ = ["Part", "tokens"]

Arc = tuple[int, int | tuple[int, ...], Guard]
"""An arc of a :class:`Part`: local source, local destination(s), guard."""


@dataclass
class Part:
    """One sub-net: places ``(name, label)``, arcs ``(src, dst or dsts, guard)`` by local index."""

    name: str
    kind: str
    role: str
    places: list[tuple[str, str]]  # (name, label)
    arcs: list[Arc]  # local src, local dst(s), guard; a list: the violation builder adds arcs later
    initial: int
    formula: str = ""
    counters: tuple[int, ...] = ()  # local indices of counting places (outside the one-token set)


def tokens(names: Sequence[str], prev: bool = False) -> R.Tokens:
    """Tokens in the places ``names`` now (``prev``: one step ago), resolved at assembly."""
    return R.Tokens((), tuple(names), prev)
