"""Timed obligations: nested intervals read as standard MITL, with clocks on tokens.

A temporal operator nested under another one (``G (fast -> F[0,0.5] !fast)``,
``F[0,2] G goal``) is an *obligation* that starts again at every sample its
parent needs it: one instance per start time ``s``, whose token's *age* is
``t_k - t_s``.  An :class:`ObligationTree` is the formula part such a family of
obligations lives in (its root is a temporal operator with no temporal
ancestor, so it has exactly one instance, started at ``t = 0``);
the runtime's :class:`mitlc.runtime.obligations.TimedState` is the per-run state of its
tokens and steps them.

Semantics.  Every node instance ``n@s`` carries a three-valued value: true,
false or *pending*.  After sample ``k`` it is the Kleene value of the
finite-trace semantics of docs/monitor.md with the samples after ``k`` unknown
(and the trace's last sample ``N`` known, so windows are cut at the end as the
monitor cuts them).  Kleene values only ever go from pending to true or false,
never back; pending at the last sample cannot happen, so the value then is the
monitor's verdict.  A value is false only when every continuation makes it
false: the net never records a violation that could still be avoided.

Tokens.  An instance is *live* while it is pending and a live instance of its
parent needs it (the root: while pending).  Its token lies in one of three
places of its node's sub-net: ``open`` when the next sample falls inside its
interval (for until and release: inside the interval of the right side),
``wait`` otherwise (before its interval opens, or after it closed while its
value waits on nested obligations), ``idle`` when there is no live instance.
The learner's marking is this projection: one token per sub-net, in the most
urgent place any instance of the node occupies (open, then wait), so the
marking keeps one token per sub-net and live instances that are in the same
place are merged.  The root's sub-net has ``met`` and ``failed`` instead of
``idle``: absorbing places recording the verdict.

Live instances of one node number at most one per sample of the look-ahead
window that feeds them; :class:`~mitlc.runtime.obligations.TimedState` keeps a value per start time of the
trial, ``(R, N+1)`` per node, which holds every bound at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mitlc.errors import CompileError
from mitlc.spec import ast as A
from mitlc.spec.passes import is_state_formula

__all__ = [
    "FALSE",
    "PENDING",
    "TRUE",
    "TNode",
    "ObligationTree",
    "IDLE",
    "OPEN",
    "WAIT",
    "MET",
    "FAILED",
    "needs_obligations",
    "TimedNet",
    "ROOT_PLACES",
    "NODE_PLACES",
    "earliest_witness",
]

FALSE, PENDING, TRUE = 0, 1, 2
"""Three-valued truth, ordered so that ``and`` is min, ``or`` is max and ``not`` is ``2 - v``."""

IDLE, OPEN, WAIT, MET, FAILED = 0, 1, 2, 3, 4
"""Where a sub-net's token lies (``idle`` only below the root; ``met``, ``failed`` only at the root)."""

TEMPORAL = ("F", "G", "U", "R")


@dataclass(frozen=True)
class TNode:
    """One node of an obligation tree.

    ``op`` is ``state`` (a state formula, evaluated on the sample), ``and``,
    ``or`` or a temporal operator ``F``, ``G``, ``U``, ``R`` (``children`` are
    ``(left, right)`` for the binary ones).
    """

    op: str
    children: tuple[int, ...]
    formula: A.Formula
    interval: A.Interval = A.UNBOUNDED

    @property
    def temporal(self) -> bool:
        return self.op in TEMPORAL


def _strip(f: A.Formula) -> A.Formula:
    while isinstance(f, A.Weighted):
        f = f.child
    return f


@dataclass(frozen=True)
class ObligationTree:
    """A formula part in normal form as nodes in post-order (children first, the root last)."""

    nodes: tuple[TNode, ...]

    @property
    def root(self) -> int:
        return len(self.nodes) - 1

    @property
    def temporal(self) -> tuple[int, ...]:
        """Indices of the temporal nodes, the ones with a sub-net."""
        return tuple(i for i, n in enumerate(self.nodes) if n.temporal)

    @property
    def formula(self) -> A.Formula:
        return self.nodes[-1].formula

    @staticmethod
    def build(formula: A.Formula) -> ObligationTree:
        return ObligationTree.build_indexed(formula)[0]

    @staticmethod
    def build_indexed(formula: A.Formula) -> tuple[ObligationTree, dict[int, int]]:
        """The tree of ``formula`` (in normal form; weights are dropped: they do not change truth),
        and the node index of every visited subformula object (by ``id``, weights peeled).

        >>> from mitlc.spec.parse import parse_formula
        >>> t, _ = ObligationTree.build_indexed(parse_formula("F[0,2] G goal"))
        >>> [(n.op, n.children) for n in t.nodes]
        [('state', ()), ('G', (0,)), ('F', (1,))]
        """
        nodes: list[TNode] = []
        index: dict[int, int] = {}

        def visit(f: A.Formula) -> int:
            i = add(f)
            index[id(_strip(f))] = i
            return i

        def add(f: A.Formula) -> int:
            f = _strip(f)
            if is_state_formula(f):
                nodes.append(TNode("state", (), f))
            elif isinstance(f, (A.And, A.Or)):
                kids = (visit(f.left), visit(f.right))
                nodes.append(TNode("and" if isinstance(f, A.And) else "or", kids, f))
            elif isinstance(f, (A.Eventually, A.Globally)):
                kid = visit(f.child)
                nodes.append(TNode("F" if isinstance(f, A.Eventually) else "G", (kid,), f, f.interval))
            elif isinstance(f, (A.Until, A.Release)):
                kids = (visit(f.left), visit(f.right))
                nodes.append(TNode("U" if isinstance(f, A.Until) else "R", kids, f, f.interval))
            else:
                raise CompileError(f"cannot track {type(f).__name__} as an obligation (run normal_form first)")
            return len(nodes) - 1

        visit(formula)
        return ObligationTree(tuple(nodes)), index


def _temporal_nodes(f: A.Formula) -> bool:
    return isinstance(f, (A.Eventually, A.Globally, A.Until, A.Release))


def needs_obligations(f: A.Formula) -> bool:
    """Whether the trial clock and the obligation clocks differ for the temporal part ``f``.

    They differ when an interval other than ``[0, inf)`` sits below another
    temporal operator (it restarts with every obligation) or above one (its
    window must not cut off the nested part's reward once the nested part has
    started). ``f`` is a temporal operator with no temporal ancestor.

    >>> from mitlc.spec.parse import parse_formula
    >>> [needs_obligations(parse_formula(s)) for s in ("F G k", "F[0,2] G k", "G (a -> F[0,1] b)", "G[0,3] a")]
    [False, True, True, False]
    """

    def timed(g: A.Formula) -> bool:
        return _temporal_nodes(g) and not g.interval.is_unbounded  # type: ignore[attr-defined]

    def below(g: A.Formula) -> list[A.Formula]:
        return [n for c in g.children for n in A.walk(c) if _temporal_nodes(n)]

    for node in A.walk(f):
        if not _temporal_nodes(node):
            continue
        nested = below(node)
        if nested and (timed(node) or any(timed(n) for n in nested)):
            return True
    return False


def earliest_witness(f: A.Formula, dt: float) -> float:
    """The earliest sample offset (seconds) at which a trace can satisfy ``f``, ``inf`` if never.

    A lower bound used for the compiler's warning: strong operators need a
    witness at least ``inf I`` after they start; ``G`` and ``R`` need nothing.
    """
    f = _strip(f)
    if is_state_formula(f):
        return 0.0
    if isinstance(f, A.And):
        return max(earliest_witness(f.left, dt), earliest_witness(f.right, dt))
    if isinstance(f, A.Or):
        return min(earliest_witness(f.left, dt), earliest_witness(f.right, dt))
    if isinstance(f, (A.Eventually, A.Until)):
        lo, hi = A.offsets(f.interval, dt)
        if lo > hi:
            return math.inf
        right = f.child if isinstance(f, A.Eventually) else f.right
        return lo * dt + earliest_witness(right, dt)
    return 0.0


@dataclass(frozen=True)
class TimedNet:
    """An obligation tree inside a compiled net: which sub-net shows each temporal node."""

    tree: ObligationTree
    subnets: tuple[tuple[int, int], ...]
    """``(tree node, net sub-net)`` for every temporal node."""

    def local(self, node: int) -> np.ndarray:
        """Engine place code (``IDLE .. FAILED``) -> local place index in the node's sub-net."""
        return ROOT_LOCAL if node == self.tree.root else NODE_LOCAL


ROOT_PLACES = ("open", "wait", "met", "failed")
NODE_PLACES = ("idle", "open", "wait")
ROOT_LOCAL = np.array([-1, 0, 1, 2, 3], dtype=np.int64)
NODE_LOCAL = np.array([0, 1, 2, -1, -1], dtype=np.int64)
