"""The compiled reward Petri net: a frozen container of places, transitions and matrices.

Shapes follow the thesis (section 2-3-2): ``D_minus``, ``D_plus`` and
``D = D_plus - D_minus`` are ``(transitions, places)`` integer arrays, a
marking is a row vector over places and firing the transitions selected by the
row vector ``T`` gives ``M' = T D + M`` (2-26).

Every sub-net holds exactly one token.  A transition's guard is a
disjunction of terms, each a state condition over the propositions (evaluated
on ``x_k+1``) and/or a condition on the trial clock ``tau``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from mitlc.spec import ast as A
from mitlc.spec.ast import fmt_number

__all__ = ["Place", "GuardTerm", "Guard", "Transition", "SubNet", "Net", "eval_state", "clock_text"]


@dataclass(frozen=True, slots=True)
class Place:
    """A place: its name, ``kind`` and the sub-net it belongs to.

    ``kind`` is ``state``, ``timing``, ``violation``, or ``counter`` (a place
    whose tokens count violations and are not part of the one-token set).
    """

    name: str
    kind: str
    subnet: int
    label: str = ""


def clock_text(interval: A.Interval) -> str:
    """Print a clock condition ``tau in I`` the way a person would write it.

    >>> clock_text(A.Interval(1, math.inf, lo_closed=False))
    'tau > 1'
    >>> clock_text(A.Interval(0, 2, hi_closed=False))
    'tau < 2'
    """
    lo, hi = interval.lo, interval.hi
    lo_text = "" if lo == 0 and interval.lo_closed else f"tau {'>=' if interval.lo_closed else '>'} {fmt_number(lo)}"
    hi_text = "" if math.isinf(hi) else f"tau {'<=' if interval.hi_closed else '<'} {fmt_number(hi)}"
    if lo_text and hi_text:
        lo_op, hi_op = "<=" if interval.lo_closed else "<", "<=" if interval.hi_closed else "<"
        return f"{fmt_number(lo)} {lo_op} tau {hi_op} {fmt_number(hi)}"
    return lo_text or hi_text or "true"


def eval_state(f: A.Formula, truth: Mapping[str, np.ndarray]) -> np.ndarray:
    """Evaluate a state formula on arrays of proposition truth values."""
    if isinstance(f, A.Atom):
        return np.asarray(truth[f.name], dtype=bool)
    if isinstance(f, A.Const):
        some = next(iter(truth.values()), np.zeros(1, bool))
        return np.full(np.shape(some), f.value, dtype=bool)
    if isinstance(f, A.Not):
        return ~eval_state(f.child, truth)
    if isinstance(f, A.And):
        return eval_state(f.left, truth) & eval_state(f.right, truth)
    if isinstance(f, A.Or):
        return eval_state(f.left, truth) | eval_state(f.right, truth)
    if isinstance(f, A.Weighted):
        return eval_state(f.child, truth)
    raise TypeError(f"not a state formula: {f}")


@dataclass(frozen=True, slots=True)
class GuardTerm:
    """``state & tau in clock``; a missing part is true.

    A term with an ``event`` belongs to a timed obligation sub-net
    (:mod:`mitlc.petri.timed`): it says in words what moves the token there (an
    obligation's age entering or leaving ``age``, its value being decided), the
    runtime's obligation state fires it, and it is never true on the state and
    the trial clock alone.
    """

    state: A.Formula | None = None
    clock: A.Interval | None = None
    age: A.Interval | None = None
    event: str | None = None

    def __str__(self) -> str:
        parts = []
        if self.event is not None:
            age = clock_text(self.age).replace("tau", "age") if self.age is not None else "true"
            parts.append(self.event if age == "true" else f"{self.event} ({age})")
        if self.state is not None:
            parts.append(str(self.state))
        if self.clock is not None:
            parts.append(clock_text(self.clock))
        if len(parts) >= 2 and self.state is not None and self.state.prec < 5:
            i = parts.index(str(self.state))
            parts[i] = f"({parts[i]})"
        return " & ".join(parts) or "true"


@dataclass(frozen=True, slots=True)
class Guard:
    """A disjunction of :class:`GuardTerm`; the transition may fire where any holds."""

    terms: tuple[GuardTerm, ...]

    @staticmethod
    def state(f: A.Formula) -> Guard:
        return Guard((GuardTerm(state=f),))

    @staticmethod
    def clock(interval: A.Interval) -> Guard:
        return Guard((GuardTerm(clock=interval),))

    @property
    def is_event(self) -> bool:
        """Fired by a timed obligation's state, not by the state and the clock (:class:`GuardTerm`)."""
        return any(t.event is not None for t in self.terms)

    @property
    def is_timed(self) -> bool:
        return any(t.clock is not None for t in self.terms)

    @property
    def has_state(self) -> bool:
        return any(t.state is not None for t in self.terms)

    def evaluate(self, truth: Mapping[str, np.ndarray], tau: np.ndarray) -> np.ndarray:
        """Where the guard holds, given proposition truth at ``x_k+1`` and the clock ``tau_k+1``."""
        tau = np.asarray(tau, dtype=float)
        out = np.zeros(np.shape(tau), dtype=bool)
        for term in self.terms:
            if term.event is not None:
                continue
            ok = np.ones(np.shape(tau), dtype=bool)
            if term.state is not None:
                ok = ok & eval_state(term.state, truth)
            if term.clock is not None:
                c = term.clock
                lo_ok = tau >= c.lo if c.lo_closed else tau > c.lo
                hi_ok = tau <= c.hi if c.hi_closed else tau < c.hi
                ok = ok & lo_ok & hi_ok
            out = out | ok
        return out

    def __str__(self) -> str:
        if len(self.terms) == 1:
            return str(self.terms[0])

        def part(t: GuardTerm) -> str:
            compound = t.state is not None and (t.clock is not None or t.state.prec < 5)
            return f"({t})" if compound else str(t)

        return " | ".join(part(t) for t in self.terms)


@dataclass(frozen=True, slots=True)
class Transition:
    name: str
    guard: Guard
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    subnet: int


@dataclass(frozen=True, slots=True)
class SubNet:
    """One sub-net: its places and transitions (indices into the net) and its role.

    ``role`` is one of ``region`` (state), ``timeline`` (the trial clock),
    ``eventually``, ``until``, ``recurrence`` (timing), ``violation``.
    ``places`` hold exactly one token between them; ``counters`` (only in
    ``counted`` violation nets) are places whose token count grows.
    """

    name: str
    kind: str
    role: str
    places: tuple[int, ...]
    transitions: tuple[int, ...]
    formula: str = ""
    counters: tuple[int, ...] = ()


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=np.int64)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Net:
    """A composed reward Petri net."""

    places: tuple[Place, ...]
    transitions: tuple[Transition, ...]
    subnets: tuple[SubNet, ...]
    D_minus: np.ndarray = field(repr=False)
    D_plus: np.ndarray = field(repr=False)
    M0: np.ndarray = field(repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "D_minus", _frozen(self.D_minus))
        object.__setattr__(self, "D_plus", _frozen(self.D_plus))
        object.__setattr__(self, "M0", _frozen(self.M0))
        shape = (len(self.transitions), len(self.places))
        if self.D_minus.shape != shape or self.D_plus.shape != shape:
            raise ValueError(f"D matrices must be {shape}")

    @property
    def D(self) -> np.ndarray:
        """The composite change matrix ``D = D+ - D-`` (transitions x places)."""
        d = self.D_plus - self.D_minus
        d.setflags(write=False)
        return d

    @property
    def counters(self) -> tuple[int, ...]:
        """Indices of the counting places (``counted`` violation nets)."""
        return tuple(i for s in self.subnets for i in s.counters)

    @property
    def place_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.places)

    @property
    def transition_names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.transitions)

    def place_index(self, name: str) -> int:
        return self.place_names.index(name)

    def fire(self, marking: np.ndarray, fired: np.ndarray) -> np.ndarray:
        """``M' = T D + M`` for row vectors (or a batch of rows) ``fired`` and ``marking``."""
        return fired @ self.D + marking

    def successors(self, place: int) -> tuple[int, ...]:
        """Places a token in ``place`` can move to in one transition."""
        out: list[int] = []
        for t in range(len(self.transitions)):
            if self.D_minus[t, place]:
                out.extend(int(j) for j in np.flatnonzero(self.D_plus[t]))
        return tuple(dict.fromkeys(out))

    def reachable_markings(self) -> list[np.ndarray]:
        """Markings reachable from ``M0`` ignoring guards (one token per sub-net)."""
        per_subnet = []
        for sub in self.subnets:
            start = next(i for i in sub.places if self.M0[i])
            seen, stack = {start}, [start]
            while stack:
                for nxt in self.successors(stack.pop()):
                    if nxt in sub.places and nxt not in seen:  # counters are not the token's places
                        seen.add(nxt)
                        stack.append(nxt)
            per_subnet.append(sorted(seen))
        out = []
        for combo in itertools.product(*per_subnet):
            m = np.zeros(len(self.places), dtype=np.int64)
            m[list(combo)] = 1
            out.append(m)
        return out

    def step_pairs(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Every pair ``(M_k, M_k+1)`` where each sub-net's token stays or makes one move."""
        for m in self.reachable_markings():
            options = []
            for sub in self.subnets:
                here = next(i for i in sub.places if m[i])
                options.append([here, *(j for j in self.successors(here) if j in sub.places)])
            for combo in itertools.product(*options):
                nxt = np.zeros_like(m)
                nxt[list(combo)] = 1
                yield m, nxt
