"""The compiled reward Petri net: a frozen container of places, transitions and matrices.

Shapes follow the thesis (section 2-3-2): ``D_minus``, ``D_plus`` and
``D = D_plus - D_minus`` are ``(transitions, places)`` integer arrays, a
marking is a row vector over places and firing the transitions selected by the
row vector ``T`` gives ``M' = T D + M`` (2-26).

The net stores ``D-`` and ``D+`` sparse (:class:`Incidence`, compressed rows:
almost every transition has one input and one output place, and a region net
of ``n`` places has ``n (n - 1)`` transitions); the dense matrices are views
computed on first use and kept, for nets of at most
:data:`~mitlc.limits.MAX_DENSE_ENTRIES` entries, and refused with a
:class:`~mitlc.errors.CompileError` naming the size past it.

Every sub-net holds exactly one token.  A transition's guard is a
disjunction of terms, each a state condition over the propositions (evaluated
on ``x_k+1``) and/or a condition on the trial clock ``tau``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mitlc.errors import CompileError
from mitlc.limits import MAX_DENSE_ENTRIES
from mitlc.spec import ast as A
from mitlc.spec.ast import fmt_number

__all__ = ["Place", "GuardTerm", "Guard", "Transition", "SubNet", "Incidence", "Net", "eval_state", "clock_text"]


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


def _frozen(a: Any, dtype: type = np.int64) -> np.ndarray:
    a = np.array(a, dtype=dtype)
    a.setflags(write=False)
    return a


class Incidence:
    """A ``(transitions, places)`` integer matrix in compressed rows (CSR), read-only.

    Row ``t``'s nonzero entries are ``data[indptr[t]:indptr[t + 1]]`` in the columns
    ``indices[indptr[t]:indptr[t + 1]]``, increasing; no stored entry is zero, so two
    equal matrices have equal arrays.

    >>> a = Incidence.from_dense(np.array([[1, 0, 0], [0, 2, 1]]))
    >>> a.indptr.tolist(), a.indices.tolist(), a.data.tolist()
    ([0, 1, 3], [0, 1, 2], [1, 2, 1])
    >>> a.left_multiply(np.array([1, 1])).tolist()     # x @ A
    [1, 2, 1]
    """

    __slots__ = ("shape", "indptr", "indices", "data")
    shape: tuple[int, int]
    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray

    def __init__(self, shape: tuple[int, int], indptr: Any, indices: Any, data: Any) -> None:
        rows, cols = (int(shape[0]), int(shape[1]))
        indptr, indices, data = _frozen(indptr), _frozen(indices), _frozen(data)
        if indptr.shape != (rows + 1,) or indices.shape != data.shape or indices.ndim != 1:
            raise ValueError("malformed compressed rows")
        if indptr[0] != 0 or indptr[-1] != len(indices) or np.any(np.diff(indptr) < 0):
            raise ValueError("malformed compressed rows")
        if len(indices) and (indices.min() < 0 or indices.max() >= cols):
            raise ValueError(f"column index outside 0..{cols - 1}")
        for name, value in (("shape", (rows, cols)), ("indptr", indptr), ("indices", indices), ("data", data)):
            object.__setattr__(self, name, value)

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError("an Incidence is read-only")

    # read-only: a copy is the same matrix; pickling (sweep workers, copies of env specs)
    # rebuilds it through __init__
    def __copy__(self) -> Incidence:
        return self

    def __deepcopy__(self, memo: dict[int, object]) -> Incidence:
        return self

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        return (Incidence, (self.shape, np.array(self.indptr), np.array(self.indices), np.array(self.data)))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Incidence):
            return NotImplemented
        return (
            self.shape == other.shape
            and np.array_equal(self.indptr, other.indptr)
            and np.array_equal(self.indices, other.indices)
            and np.array_equal(self.data, other.data)
        )

    __hash__ = None  # type: ignore[assignment]  # equality by value on arrays

    def __repr__(self) -> str:
        return f"Incidence({self.shape[0]} x {self.shape[1]}, {self.nnz} entries)"

    @staticmethod
    def from_dense(a: Any) -> Incidence:
        a = np.asarray(a, dtype=np.int64)
        if a.ndim != 2:
            raise ValueError(f"a (transitions, places) matrix, got shape {a.shape}")
        rows, cols = np.nonzero(a)
        indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=a.shape[0]))])
        return Incidence(a.shape, indptr, cols, a[rows, cols])

    @staticmethod
    def ones(shape: tuple[int, int], rows: Any, cols: Any) -> Incidence:
        """The 0/1 matrix with ones at ``(rows[k], cols[k])`` (a pair given twice is still 1)."""
        rows, cols = np.asarray(rows, dtype=np.int64), np.asarray(cols, dtype=np.int64)
        if rows.shape != cols.shape or rows.ndim != 1:
            raise ValueError("rows and cols must be equal-length vectors")
        if len(rows) and (rows.min() < 0 or rows.max() >= shape[0]):
            raise ValueError(f"row index outside 0..{shape[0] - 1}")
        key = rows * max(int(shape[1]), 1) + cols
        if len(key) > 1 and not np.all(key[1:] > key[:-1]):  # already sorted and distinct: as they are
            key = np.unique(key)
        r, c = np.divmod(key, max(int(shape[1]), 1))
        indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=shape[0]))])
        return Incidence(shape, indptr, c, np.ones(len(c), dtype=np.int64))

    @property
    def nnz(self) -> int:
        return len(self.indices)

    @property
    def nbytes(self) -> int:
        """Bytes of the three arrays."""
        return int(self.indptr.nbytes + self.indices.nbytes + self.data.nbytes)

    def row_of_entries(self) -> np.ndarray:
        """The row of every stored entry, ``(nnz,)``."""
        return np.repeat(np.arange(self.shape[0], dtype=np.int64), np.diff(self.indptr))

    def row(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        """Row ``t``'s columns and values."""
        a, b = self.indptr[t], self.indptr[t + 1]
        return self.indices[a:b], self.data[a:b]

    def single_columns(self) -> np.ndarray:
        """Each row's column where the row is a single 1, -1 where it is anything else, ``(rows,)``."""
        if not self.nnz:
            return np.full(self.shape[0], -1, dtype=np.int64)
        first = np.minimum(self.indptr[:-1], self.nnz - 1)
        one = (np.diff(self.indptr) == 1) & (self.data[first] == 1)
        return np.where(one, self.indices[first], -1)

    def toarray(self) -> np.ndarray:
        out = np.zeros(self.shape, dtype=np.int64)
        out[self.row_of_entries(), self.indices] = self.data
        return out

    def transpose(self) -> Incidence:
        rows = self.row_of_entries()
        order = np.lexsort((rows, self.indices))  # by column, then row
        cols = self.indices[order]
        indptr = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=self.shape[1]))])
        return Incidence((self.shape[1], self.shape[0]), indptr, rows[order], self.data[order])

    def left_multiply(self, x: Any) -> np.ndarray:
        """``x @ A`` for ``x`` of shape ``(..., rows)`` (integers stay exact)."""
        x = np.asarray(x)
        if x.shape[-1:] != (self.shape[0],):
            raise ValueError(f"matmul: {x.shape} @ {self.shape}")
        contrib = x[..., self.row_of_entries()] * self.data  # (..., nnz)
        out = np.zeros((self.shape[1], *x.shape[:-1]), dtype=contrib.dtype)
        np.add.at(out, self.indices, np.moveaxis(contrib, -1, 0))
        return np.moveaxis(out, 0, -1)


def _incidence(a: Incidence | np.ndarray, shape: tuple[int, int], name: str) -> tuple[Incidence, np.ndarray | None]:
    """``a`` as an :class:`Incidence` and, when it came dense, its frozen dense array."""
    if isinstance(a, Incidence):
        if a.shape != shape:
            raise ValueError(f"D matrices must be {shape}")
        return a, None
    dense = _frozen(a)
    if dense.shape != shape:
        raise ValueError(f"D matrices must be {shape}")
    return Incidence.from_dense(dense), dense


@dataclass(frozen=True)
class Net:
    """A composed reward Petri net.

    ``pre`` (``D-``) and ``post`` (``D+``) may be given dense (``(transitions, places)``
    arrays, as before) or as :class:`Incidence`; the net keeps them sparse and
    :attr:`D_minus`, :attr:`D_plus` and :attr:`D` are their dense views.
    """

    places: tuple[Place, ...]
    transitions: tuple[Transition, ...]
    subnets: tuple[SubNet, ...]
    pre: Incidence = field(repr=False)
    """``D-`` in compressed rows: the places each transition takes a token from."""
    post: Incidence = field(repr=False)
    """``D+`` in compressed rows: the places each transition puts a token in."""
    M0: np.ndarray = field(repr=False)
    _cache: dict[str, Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        shape = (len(self.transitions), len(self.places))
        pre, dense_minus = _incidence(self.pre, shape, "D_minus")
        post, dense_plus = _incidence(self.post, shape, "D_plus")
        object.__setattr__(self, "pre", pre)
        object.__setattr__(self, "post", post)
        object.__setattr__(self, "M0", _frozen(self.M0))
        if dense_minus is not None:
            self._cache["D_minus"] = dense_minus
        if dense_plus is not None:
            self._cache["D_plus"] = dense_plus

    def _dense(self, name: str) -> np.ndarray:
        got = self._cache.get(name)
        if got is not None:
            return got
        T, P = self.pre.shape
        if T * P > MAX_DENSE_ENTRIES:
            raise CompileError(
                f"the net's {name} would be a dense {T:,} x {P:,} matrix ({T * P:,} entries, "
                f"{8 * T * P / 2**30:.1f} GiB), more than the {MAX_DENSE_ENTRIES:,} entries supported; "
                "its sparse form is net.pre / net.post"
            )
        if name == "D":
            d = self.D_plus - self.D_minus
        else:
            d = (self.pre if name == "D_minus" else self.post).toarray()
        d.setflags(write=False)
        self._cache[name] = d
        return d

    @property
    def D_minus(self) -> np.ndarray:
        """``D-`` dense, ``(transitions, places)``: computed on first use (refused past the size limit)."""
        return self._dense("D_minus")

    @property
    def D_plus(self) -> np.ndarray:
        """``D+`` dense, ``(transitions, places)``: computed on first use (refused past the size limit)."""
        return self._dense("D_plus")

    @property
    def D(self) -> np.ndarray:
        """The composite change matrix ``D = D+ - D-`` (transitions x places)."""
        return self._dense("D")

    @property
    def counters(self) -> tuple[int, ...]:
        """Indices of the counting places (``counted`` violation nets)."""
        return tuple(i for s in self.subnets for i in s.counters)

    @property
    def place_names(self) -> tuple[str, ...]:
        got = self._cache.get("place_names")
        if got is None:
            got = self._cache["place_names"] = tuple(p.name for p in self.places)
        return got

    @property
    def transition_names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.transitions)

    def place_index(self, name: str) -> int:
        index = self._cache.get("place_index")
        if index is None:
            index = {}
            for i, n in enumerate(self.place_names):
                index.setdefault(n, i)
            self._cache["place_index"] = index
        try:
            return index[name]
        except KeyError:
            raise ValueError(f"{name!r} is not a place of the net") from None

    def fire(self, marking: np.ndarray, fired: np.ndarray) -> np.ndarray:
        """``M' = T D + M`` for row vectors (or a batch of rows) ``fired`` and ``marking``."""
        fired = np.asarray(fired)
        return self.post.left_multiply(fired) - self.pre.left_multiply(fired) + marking

    def successors(self, place: int) -> tuple[int, ...]:
        """Places a token in ``place`` can move to in one transition."""
        by_input = self._cache.get("by_input")
        if by_input is None:
            by_input = self._cache["by_input"] = self.pre.transpose()
        out: list[int] = []
        for t in by_input.row(place)[0].tolist():
            out.extend(self.post.row(t)[0].tolist())
        return tuple(dict.fromkeys(out))

    def reachable_markings(self) -> list[np.ndarray]:
        """Markings reachable from ``M0`` ignoring guards (one token per sub-net)."""
        per_subnet = []
        for sub in self.subnets:
            start = next(i for i in sub.places if self.M0[i])
            own = set(sub.places)
            seen, stack = {start}, [start]
            while stack:
                for nxt in self.successors(stack.pop()):
                    if nxt in own and nxt not in seen:  # counters are not the token's places
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
