"""Timed obligations of one run as flat arrays, stepped per sample by plain Python over scalars.

:class:`~mitlc.runtime.obligations.TimedState` keeps the three-valued value and the liveness of
every node of an obligation tree for every start time, ``(R, N+1)`` each, and recomputes all of
them from scratch at every sample (numpy over the runs). This module is the same engine for *one*
run, written as loops over integers and arrays only (no Python objects), so that a compiled trial
kernel (:mod:`mitlc.learn.sacpn.kernel`, through numba) can step it: :func:`build` compiles the
obligation trees of a net into arrays (:meth:`~mitlc.runtime.NetRuntime.obligation_arrays`), and
:func:`obligation_kernel` gives the per-sample function, which takes one sample into one run's
state and moves the sub-nets' tokens in a mixed-radix marking code as
:meth:`~mitlc.runtime.NetRuntime.advance_code` does (``code += (local - old) * stride``). It gives
the same values, liveness and places as :class:`~mitlc.runtime.obligations.TimedState` after every
sample (``tests/test_obligation_kernel.py`` checks it, plain and compiled, on random formulas and
traces).

Where the work goes.  Values only go from pending to true or false, and liveness only from live to
dead (:mod:`mitlc.petri.timed`), so the engine is *event driven*: a sample decides the state nodes'
value at its own position, and each value decided is pushed to the parent, whose value changes only
at the start times whose window holds that position:

* ``and``/``or``: the same position, recomputed;
* ``F``/``G``: a *hit* (a true child under ``F``, a false one under ``G``) decides every pending
  start time whose window holds it; a *miss* decides the other way every pending start time
  whose window now lies inside the run of misses around it. Skip lists (union-find forests
  whose links are only ever added) find the ends of that run and the pending start times in
  amortised constant time, so an unbounded window costs no more than a short one;
* ``U``/``R``: the start times the changed positions can reach are recomputed by a scan of their
  window (the left side's run from the start time, the right side's witness in the window).

Then the positions that died (decided, or no longer needed by a live instance of the parent) are
pushed down: each child keeps, per position, the number of live parent instances that need it.
The places of a sub-net (``open``, ``wait``, ``idle``) are found by two pointers per temporal node
that only move forward (dead positions stay dead). Only the start times that can matter are kept:
the root's value at start 0, and below it the positions its windows reach (``REL``).

The state a run starts from (nothing observed: only the constant state parts decided) is the same
for every run and trial: :func:`build` computes it once (``init``), and a run copies it. On the
shipped specs N1..N4 a sample costs about 0.15 us inside the trial kernel.

Adding a temporal operator to :class:`~mitlc.runtime.obligations.TimedState` means adding it here
too: an op code, its windows in :func:`build` (``VLO``/``VHI``, ``WLO``/``WHI``), its value in
:func:`initial_state` and its case in ``obl_step``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mitlc.petri.net import eval_state
from mitlc.petri.timed import FAILED, FALSE, IDLE, MET, NODE_LOCAL, OPEN, PENDING, ROOT_LOCAL, TRUE, WAIT, TimedNet
from mitlc.runtime.obligations import _constant
from mitlc.spec import ast as A

__all__ = [
    "NCOL",
    "ObligationArrays",
    "build",
    "empty",
    "no_obligations",
    "obligation_kernel",
    "scratch",
    "until_value",
]

# op codes
STATE, AND, OR, EVENTUALLY, GLOBALLY, UNTIL, RELEASE = range(7)
_OPS = {"state": STATE, "and": AND, "or": OR, "F": EVENTUALLY, "G": GLOBALLY, "U": UNTIL, "R": RELEASE}

# columns of the node table (one row per node of every tree, each tree in post-order)
OP, LEFT, RIGHT, LO, HI, REL, KNOWN, VLO, VHI, WLO, WHI = range(11)
NCOL = 11
"""``OP``: the op code; ``LEFT``, ``RIGHT``: children (-1: none); ``LO``, ``HI``: a temporal node's
interval as sample offsets, ``HI`` at most ``N + 1`` (an unbounded end is ``N + 1``: no window reaches
past the trial); ``REL``: the last start time whose value or liveness can matter (-1: none);
``KNOWN``: a state part with the same value on every sample; ``VLO``, ``VHI``: a value decided at
position ``t`` changes the parent's start times ``[t - VHI, t - VLO]``; ``WLO``, ``WHI``: a parent
instance at ``s`` needs this node's positions ``[s + WLO, s + WHI]``."""

# rows of a run's state (4, nodes, N+1)
VAL, LIVE, NEED, PENDING_FROM, MISS_TO, MISS_FROM = range(6)
ROWS = 6
# a run's working memory (MEM_ROWS, nodes, N+2): its state, then the state it starts from (INIT ..
# INIT + ROWS - 1), then per node the positions decided and died at the latest sample
INIT, DECIDED, DIED = ROWS, 2 * ROWS, 2 * ROWS + 1
MEM_ROWS = 2 * ROWS + 2
# rows of its registers (4, max(nodes, sub-nets)): how many positions DECIDED and DIED hold per
# node, and per timed sub-net the two forward pointers of its places (OPEN_FROM, STARTED_FROM)
N_DECIDED, N_DIED, OPEN_FROM, STARTED_FROM = range(4)

# columns of the temporal table (one row per timed sub-net)
T_NODE, T_ROOT, T_STRIDE, T_SIZE, T_LOCAL = range(5)
TCOL = T_LOCAL + 5


@dataclass(frozen=True)
class ObligationArrays:
    """The obligation trees of a net as arrays (:func:`build`)."""

    nodes: np.ndarray
    """``(nodes, NCOL)`` int64: the node table."""
    truth: np.ndarray
    """``(nodes, atom codes)`` uint8: each state part's truth per atom code (0 for other nodes)."""
    temporal: np.ndarray
    """``(sub-nets, TCOL)`` int64: per timed sub-net its node, whether it is a root, its marking code's
    stride and size (mixed radix), and the local place index of each engine place (``IDLE .. FAILED``)."""
    init: np.ndarray
    """``(ROWS, nodes, N+2)`` int32: a run's state before its first sample (:func:`initial_state`)."""
    subnets: np.ndarray
    """``(sub-nets,)`` int64: the net's sub-net of each row of :attr:`temporal`."""

    @property
    def steps(self) -> int:
        return self.init.shape[2] - 2


def empty() -> ObligationArrays:
    """Arrays of a net without timed obligations (what a kernel is given then: the same types)."""
    return ObligationArrays(
        np.zeros((0, NCOL), dtype=np.int64),
        np.zeros((0, 1), dtype=np.uint8),
        np.zeros((0, TCOL), dtype=np.int64),
        np.zeros((ROWS, 0, 2), dtype=np.int32),
        np.zeros(0, dtype=np.int64),
    )


def build(
    timed: Sequence[TimedNet],
    atoms: Sequence[str],
    dt: float,
    steps: int,
    strides: Sequence[int] | np.ndarray,
    sizes: Sequence[int],
) -> ObligationArrays:
    """The obligation trees ``timed`` of a net over propositions ``atoms`` (bit ``i`` of an atom code is
    ``atoms[i]``), for trials of ``steps`` steps of ``dt``; ``strides`` and ``sizes`` are the mixed-radix
    marking code's, per sub-net of the net (:class:`~mitlc.runtime.tables.Radix`)."""
    N = int(steps)
    L = N + 1
    rows: list[list[int]] = []
    formulas: list[A.Formula | None] = []
    temporal: list[list[int]] = []
    subnets: list[int] = []
    for tn in timed:
        base = len(rows)
        tree = tn.tree
        parent = [-1] * len(tree.nodes)
        for i, n in enumerate(tree.nodes):
            for c in n.children:
                parent[c] = i
        for n in tree.nodes:
            row = [0] * NCOL
            row[OP] = _OPS[n.op]
            row[LEFT] = base + n.children[0] if n.children else -1
            row[RIGHT] = base + n.children[1] if len(n.children) > 1 else -1
            if n.temporal:
                lo, hi = A.offsets(n.interval, dt)
                row[LO] = min(int(lo), L)
                row[HI] = L if not hi < L else int(hi)  # inf, or past the trial: as far as the trial
            row[KNOWN] = 0
            if n.op == "state" and _constant(n.formula) is not None:
                row[KNOWN] = 1
            rows.append(row)
            formulas.append(n.formula if n.op == "state" else None)
        # relevance, and the windows each node is seen through by its parent (root first)
        for i in range(len(tree.nodes) - 1, -1, -1):
            row = rows[base + i]
            p = parent[i]
            if p < 0:
                row[REL] = 0
                continue
            prow = rows[base + p]
            if prow[OP] in (AND, OR):
                row[REL] = prow[REL]
                continue
            left = i == tree.nodes[p].children[0]
            lo, hi = prow[LO], prow[HI]
            row[REL] = min(prow[REL] + hi, N) if prow[REL] >= 0 else -1
            if prow[OP] in (UNTIL, RELEASE) and left:
                row[VLO], row[VHI] = 0, hi
                row[WLO], row[WHI] = 0, hi - 1
            else:
                row[VLO], row[VHI] = lo, hi
                row[WLO], row[WHI] = lo, hi
        for node, s in tn.subnets:
            local = ROOT_LOCAL if node == tree.root else NODE_LOCAL
            temporal.append([base + node, int(node == tree.root), int(strides[s]), int(sizes[s]), *map(int, local)])
            subnets.append(int(s))
    nodes = np.array(rows, dtype=np.int64).reshape(len(rows), NCOL)
    codes = np.arange(1 << len(atoms), dtype=np.int64)
    bits = {a: ((codes >> i) & 1).astype(bool) for i, a in enumerate(atoms)}
    truth = np.zeros((len(rows), len(codes)), dtype=np.uint8)
    for g, f in enumerate(formulas):
        if f is not None:
            truth[g] = np.broadcast_to(eval_state(f, bits), codes.shape)
    temp = np.array(temporal, dtype=np.int64).reshape(len(temporal), TCOL)
    return ObligationArrays(nodes, truth, temp, initial_state(nodes, truth, N), np.array(subnets, dtype=np.int64))


def until_value(st: np.ndarray, left: int, right: int, s: int, lo: int, hi: int, N: int, neg: bool) -> int:
    """The value of ``left U[lo,hi] right`` started at ``s`` (``R`` with ``neg``: both sides and the
    result negated) from its children's values ``st[VAL]``: :meth:`TimedState._until` for one start time."""
    e = s + hi
    if e > N:
        e = N
    ls = s + lo
    for t in range(s, e + 1):  # a witness of the right side, the left side holding before it
        b = st[VAL, right, t]
        if neg:
            b = TRUE - b
        if t >= ls and b == TRUE:
            return FALSE if neg else TRUE
        a = st[VAL, left, t]
        if neg:
            a = TRUE - a
        if a != TRUE:
            break
    for t in range(s, e + 1):  # every possible witness false, up to the left side's first failure
        b = st[VAL, right, t]
        if neg:
            b = TRUE - b
        if t >= ls and b != FALSE:
            return PENDING
        a = st[VAL, left, t]
        if neg:
            a = TRUE - a
        if a == FALSE:
            break
    return TRUE if neg else FALSE


def initial_state(nodes: np.ndarray, truth: np.ndarray, N: int) -> np.ndarray:
    """A run's state before its first sample, ``(ROWS, nodes, N+2)`` int32: every value from the
    constant state parts alone, liveness and need counts from the roots down, and the skip lists.

    Rows: ``VAL`` the values (start times ``0..N``); ``LIVE`` liveness; ``NEED`` how many live
    instances of the parent need each position; then three skip lists (union-find forests whose
    links only ever get added) of an ``F`` or ``G`` node: ``PENDING_FROM`` over its own start
    times (``find(s)``: the first pending start time from ``s``), ``MISS_TO`` over its child's
    positions (the first position from ``t`` that is not a miss) and ``MISS_FROM`` (shifted by one:
    ``find(t + 1)`` is one past the last position up to ``t`` that is not a miss).
    """
    G, L = nodes.shape[0], N + 1
    st = np.zeros((ROWS, G, L + 1), dtype=np.int32)
    val, live, need = st[VAL], st[LIVE], st[NEED]
    val[...] = PENDING
    st[PENDING_FROM:] = np.arange(L + 1, dtype=np.int32)  # every skip list without links
    for g in range(G):
        op, left, right, rel = (int(v) for v in nodes[g, [OP, LEFT, RIGHT, REL]])
        lo, hi = int(nodes[g, LO]), int(nodes[g, HI])
        if op == STATE:
            if nodes[g, KNOWN]:
                val[g, :L] = TRUE if truth[g, 0] else FALSE
        elif op in (AND, OR):
            pick = np.minimum if op == AND else np.maximum
            val[g, : rel + 1] = pick(val[left, : rel + 1], val[right, : rel + 1])
        elif op in (EVENTUALLY, GLOBALLY):
            hit = TRUE if op == EVENTUALLY else FALSE
            for s in range(rel + 1):
                w = val[left, s + lo : min(s + hi, N) + 1]  # empty past the end
                if np.any(w == hit):
                    val[g, s] = hit
                elif np.all(w == TRUE - hit):
                    val[g, s] = TRUE - hit
                if val[g, s] != PENDING:
                    st[PENDING_FROM, g, s] = s + 1
            for t in range(L):
                if val[left, t] == TRUE - hit:
                    st[MISS_TO, g, t] = t + 1
                    st[MISS_FROM, g, t + 1] = t
        else:
            for s in range(rel + 1):
                val[g, s] = until_value(st, left, right, s, lo, hi, N, op == RELEASE)
    roots = set(range(G)) - {int(c) for c in nodes[:, [LEFT, RIGHT]].ravel() if c >= 0}
    for g in roots:
        need[g, 0] = 1
        live[g, 0] = val[g, 0] == PENDING
    for g in range(G - 1, -1, -1):
        for c in (int(nodes[g, LEFT]), int(nodes[g, RIGHT])):
            if c < 0 or nodes[c, OP] == STATE:
                continue
            wlo, whi = int(nodes[c, WLO]), int(nodes[c, WHI])
            for t in range(int(nodes[c, REL]) + 1):
                first, last = max(t - whi, 0), t - wlo
                need[c, t] = int(live[g, first : last + 1].sum()) if last >= first else 0
                live[c, t] = need[c, t] > 0 and val[c, t] == PENDING
    return st


def find(st: np.ndarray, row: int, g: int, x: int) -> int:
    """The root of ``x`` in skip list ``st[row, g]`` (the first position not skipped), halving the path."""
    while st[row, g, x] != x:
        st[row, g, x] = st[row, g, st[row, g, x]]
        x = st[row, g, x]
    return x


def scratch(arrays: ObligationArrays) -> tuple[np.ndarray, np.ndarray]:
    """``(mem, regs)``: a run's working memory for :func:`obligation_kernel`'s ``step`` (its state
    to start from in place), and its registers."""
    _, G, W = arrays.init.shape
    mem = np.zeros((MEM_ROWS, G, W), dtype=np.int32)
    mem[INIT : INIT + ROWS] = arrays.init
    return mem, np.zeros((4, max(G, arrays.temporal.shape[0], 1)), dtype=np.int64)


def no_obligations(k, ac, code, nodes, truth, temporal, mem, regs):
    """:func:`obligation_kernel`'s ``step`` for a net without timed obligations: ``code`` itself."""
    return code


def obligation_kernel(jit_fn: Callable) -> Callable:
    """``step`` compiled by ``jit_fn`` (the identity: plain Python).

    ``step(k, ac, code, nodes, truth, temporal, mem, regs)`` takes sample ``k`` (atom code ``ac``)
    into one run's state (sample 0: a new run) and returns marking code ``code`` with every timed
    sub-net's token moved to its place after it (what :meth:`~mitlc.runtime.NetRuntime.advance_code`
    does): ``nodes``, ``truth`` and ``temporal`` are :class:`ObligationArrays`'s, ``mem`` and ``regs``
    :func:`scratch`'s. One run at a time: the samples of a run in order, from 0. (One function, few
    arrays: a call from the trial kernel costs little.)
    """
    until = jit_fn(until_value)
    find_j = jit_fn(find)

    def obl_step(k, ac, code, nodes, truth, temporal, mem, regs):
        if k == 0:  # a new run: the state before any sample
            for i in range(ROWS):
                for g in range(mem.shape[1]):
                    for t in range(mem.shape[2]):
                        mem[i, g, t] = mem[INIT + i, g, t]
            for j in range(regs.shape[1]):
                regs[OPEN_FROM, j] = 0
                regs[STARTED_FROM, j] = 0
        G = nodes.shape[0]
        N = mem.shape[2] - 2
        for g in range(G):
            regs[N_DECIDED, g] = 0
            regs[N_DIED, g] = 0
        # values, children first
        for g in range(G):
            op = nodes[g, OP]
            rel = nodes[g, REL]
            if op == STATE:  # its value at k
                if nodes[g, KNOWN] == 0 and k <= rel:
                    mem[VAL, g, k] = TRUE if truth[g, ac] else FALSE
                    mem[DECIDED, g, 0] = k
                    regs[N_DECIDED, g] = 1
                continue
            left, right = nodes[g, LEFT], nodes[g, RIGHT]
            n = 0
            if op in (AND, OR):  # the positions decided below, again
                for side in range(2):
                    c = left if side == 0 else right
                    for j in range(regs[N_DECIDED, c]):
                        t = mem[DECIDED, c, j]
                        if t > rel or mem[VAL, g, t] != PENDING:
                            continue
                        a, b = mem[VAL, left, t], mem[VAL, right, t]
                        if op == AND:
                            v = a if a < b else b
                        else:
                            v = a if a > b else b
                        if v != PENDING:
                            mem[VAL, g, t] = v
                            mem[DECIDED, g, n] = t
                            n += 1
            elif op in (EVENTUALLY, GLOBALLY):
                # a hit decides every pending start time whose window holds it; a miss decides those
                # whose window now lies inside the run of misses around it
                lo, hi = nodes[g, LO], nodes[g, HI]
                hit = TRUE if op == EVENTUALLY else FALSE
                for j in range(regs[N_DECIDED, left]):
                    t = mem[DECIDED, left, j]
                    s0 = t - hi
                    if s0 < 0:
                        s0 = 0
                    s1 = t - lo
                    if s1 > rel:
                        s1 = rel
                    if mem[VAL, left, t] == hit:
                        v = hit
                    else:
                        v = TRUE - hit
                        mem[MISS_TO, g, t] = t + 1
                        mem[MISS_FROM, g, t + 1] = t
                        a = find_j(mem, MISS_FROM, g, t + 1)  # the run of misses: [a, b]
                        b = find_j(mem, MISS_TO, g, t) - 1
                        if s0 < a - lo:
                            s0 = a - lo
                        if b < N and s1 > b - hi:
                            s1 = b - hi
                    if s0 > s1:
                        continue
                    s = find_j(mem, PENDING_FROM, g, s0)
                    while s <= s1:
                        mem[VAL, g, s] = v
                        mem[DECIDED, g, n] = s
                        n += 1
                        mem[PENDING_FROM, g, s] = s + 1
                        s = find_j(mem, PENDING_FROM, g, s + 1)
            else:  # U, R: the start times the changed positions reach, scanned again
                lo, hi = nodes[g, LO], nodes[g, HI]
                d0, d1 = N + 1, -1
                for j in range(regs[N_DECIDED, left]):
                    t = mem[DECIDED, left, j]
                    if t - hi < d0:
                        d0 = t - hi
                    if t > d1:
                        d1 = t
                for j in range(regs[N_DECIDED, right]):
                    t = mem[DECIDED, right, j]
                    if t - hi < d0:
                        d0 = t - hi
                    if t - lo > d1:
                        d1 = t - lo
                if d0 < 0:
                    d0 = 0
                if d1 > rel:
                    d1 = rel
                for s in range(d0, d1 + 1):
                    if mem[VAL, g, s] == PENDING:
                        v = until(mem, left, right, s, lo, hi, N, op == RELEASE)
                        if v != PENDING:
                            mem[VAL, g, s] = v
                            mem[DECIDED, g, n] = s
                            n += 1
            regs[N_DECIDED, g] = n
        # deaths, parents first: decided now, or no longer needed by a live instance of the parent
        for g in range(G - 1, -1, -1):
            if nodes[g, OP] == STATE:
                continue
            nd = regs[N_DIED, g]
            for j in range(regs[N_DECIDED, g]):
                s = mem[DECIDED, g, j]
                if mem[LIVE, g, s] != 0:
                    mem[LIVE, g, s] = 0
                    mem[DIED, g, nd] = s
                    nd += 1
            regs[N_DIED, g] = nd
            if nd == 0:
                continue
            for side in range(2):
                c = nodes[g, LEFT + side]
                if c < 0 or nodes[c, OP] == STATE:  # a state part's liveness is never read
                    continue
                wlo, whi, relc = nodes[c, WLO], nodes[c, WHI], nodes[c, REL]
                m = regs[N_DIED, c]
                for j in range(nd):
                    s = mem[DIED, g, j]
                    t1 = s + whi
                    if t1 > relc:
                        t1 = relc
                    for t in range(s + wlo, t1 + 1):
                        x = mem[NEED, c, t] - 1
                        mem[NEED, c, t] = x
                        if x == 0 and mem[LIVE, c, t] != 0:
                            mem[LIVE, c, t] = 0
                            mem[DIED, c, m] = t
                            m += 1
                regs[N_DIED, c] = m
        # the places of the tokens after sample k, into the marking code
        nxt = k + 1
        for j in range(temporal.shape[0]):
            g = temporal[j, T_NODE]
            lo, hi = nodes[g, LO], nodes[g, HI]
            opened = False
            if nxt <= N:  # a live instance whose window holds the next sample (the window only moves on)
                a = nxt - hi
                if a < 0:
                    a = 0
                b = nxt - lo
                p = regs[OPEN_FROM, j]
                if p < a:
                    p = a
                while p <= b and mem[LIVE, g, p] == 0:
                    p += 1
                regs[OPEN_FROM, j] = p
                opened = p <= b
            q = regs[STARTED_FROM, j]  # a live instance started by now
            while q <= k and mem[LIVE, g, q] == 0:
                q += 1
            regs[STARTED_FROM, j] = q
            if temporal[j, T_ROOT] != 0:
                v = mem[VAL, g, 0]
                if v == TRUE:
                    place = MET
                elif v == FALSE:
                    place = FAILED
                else:
                    place = OPEN if opened else WAIT
                here = temporal[j, T_LOCAL + place]
            else:
                if opened:
                    place = OPEN
                elif q <= k:
                    place = WAIT
                else:
                    place = IDLE
                here = temporal[j, T_LOCAL + place]
            stride = temporal[j, T_STRIDE]
            code += (here - (code // stride) % temporal[j, T_SIZE]) * stride
        return code

    return jit_fn(obl_step)
