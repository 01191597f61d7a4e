"""The fast path: the firing rule and the reward tabulated once, a step two look-ups.

Each sub-net holds one token, so a marking is one of finitely many *codes*, the guards see
the propositions through the atom code and the clock through which of the guards' clock
intervals hold; :func:`build_tables` tabulates ``next_code[clock, code, atom]`` and
``reward[code, code']`` from the runtime's own rule (:meth:`mitlc.runtime.NetRuntime._fire`), and
:func:`build_compact` does it over the reachable markings only when the product of the
sub-nets' places is too large.
"""

from __future__ import annotations

import math

import numpy as np

from mitlc.petri import reward as R
from mitlc.petri.compile import RewardSystem
from mitlc.runtime.rule import Rule, clock_ok, region_move

__all__ = ["MAX_TABLE", "Radix", "Tables", "build_compact", "build_tables"]

MAX_TABLE = 1 << 22
"""Largest transition or reward table (entries) the fast path builds."""


class Radix:
    """Mixed-radix marking codes: ``code = sum_s local_index_s * stride_s``, one token per sub-net.

    ``n_codes`` is a Python int (the product of the sub-nets' sizes may not fit in int64; past
    2**62 the strides are left 0 and the codes are not used: compact tables or none at all).
    """

    def __init__(self, subnet_places: tuple[np.ndarray, ...], n_places: int) -> None:
        self.subnet_places = subnet_places
        self.sizes = sizes = [len(p) for p in subnet_places]
        self.n_codes = n_codes = math.prod(sizes)
        big = [0] * len(sizes)
        if n_codes < 2**62:
            acc = 1
            for s in range(len(sizes) - 1, -1, -1):  # suffix products in one pass (500 sub-nets: not 250,000)
                big[s] = acc
                acc *= sizes[s]
        self.strides = strides = np.array(big, dtype=np.int64)
        self.n_places = n_places
        self.place_weight = np.zeros(n_places, dtype=np.int64)
        for s, places in enumerate(subnet_places):
            for local, p in enumerate(places):
                self.place_weight[p] = local * strides[s]

    def encode(self, M: np.ndarray) -> np.ndarray:
        """Markings ``(R, P)`` to codes ``(R,)``."""
        return np.asarray(M, dtype=np.int64) @ self.place_weight

    def decode(self, code: np.ndarray) -> np.ndarray:
        """Codes ``(R,)`` to markings ``(R, P)``."""
        code = np.asarray(code, dtype=np.int64)
        M = np.zeros((code.shape[0], self.n_places), dtype=np.int64)
        rows = np.arange(code.shape[0])
        for s, places in enumerate(self.subnet_places):
            M[rows, places[self.local(code, s)]] = 1
        return M

    def local(self, code: np.ndarray, s: int) -> np.ndarray:
        """The local index of sub-net ``s``'s marked place in each of ``code``."""
        return (np.asarray(code) // self.strides[s]) % self.sizes[s]

    def marked(self, code: np.ndarray) -> np.ndarray:
        """Codes ``(R,)`` to the marked place of every sub-net, ``(R, S)`` place indices."""
        if not self.subnet_places:
            return np.zeros((np.shape(code)[0], 0), dtype=np.intp)
        return np.stack([places[self.local(code, s)] for s, places in enumerate(self.subnet_places)], axis=1)


def build_tables(rule: Rule, radix: Radix, rs: RewardSystem) -> Tables | None:
    """The firing rule and the reward tabulated over all mixed-radix marking codes, or the compact
    tables of :func:`build_compact` when those would pass :data:`MAX_TABLE`; None when neither fits."""
    atoms, counters, graded = rs.atoms, np.array(rs.net.counters, dtype=np.intp), rs.grader is not None
    n_atoms, n_clocks, n_codes = len(atoms), len(rule.clocks), radix.n_codes
    n_atom_codes, n_clock_codes = 1 << n_atoms, 1 << n_clocks
    if n_clock_codes * n_codes * n_atom_codes > MAX_TABLE or n_codes * n_codes > MAX_TABLE:
        return build_compact(rule, rs)
    codes = np.arange(n_codes, dtype=np.int64)
    markings = radix.decode(codes)
    # every (code, atom code) pair in one batch
    pair_code = np.repeat(codes, n_atom_codes)
    pair_atom = np.tile(np.arange(n_atom_codes, dtype=np.int64), n_codes)
    M = markings[pair_code]
    truth = {a: ((pair_atom >> i) & 1).astype(bool) for i, a in enumerate(atoms)}
    next_code = np.empty((n_clock_codes, n_codes, n_atom_codes), dtype=np.int64)
    for ck in range(n_clock_codes):
        clock_truth = [bool((ck >> i) & 1) for i in range(n_clocks)]
        nxt = rule.fire(M, truth, clock_truth)
        next_code[ck] = radix.encode(nxt).reshape(n_codes, n_atom_codes)
    marked = radix.marked(codes)
    # a counter grows when a transition feeding it fires, i.e. when its sub-net's
    # token moves from the transition's input to its one-token output
    counter_inc = np.zeros((n_codes, n_codes, len(counters)), dtype=np.int64)
    counter_col = {int(p): j for j, p in enumerate(counters)}
    for t, tr in enumerate(rule.net.transitions):
        fed = [counter_col[rule.net.place_index(o)] for o in tr.outputs if rule.net.place_index(o) in counter_col]
        if not fed:
            continue
        s = rule.t_subnet[t]
        dst = next(rule.net.place_index(o) for o in tr.outputs if rule.net.place_index(o) not in counter_col)
        moved = (marked[:, s] == rule.src[t])[:, None] & (marked[:, s] == dst)[None, :]
        for j in fed:
            counter_inc[:, :, j] += moved
    # a graded reward reads the state too: no table of it (the charge reads markings only)
    if graded:
        exprs = [rs.charge if rs.charge is not None else R.ZERO]
    else:
        exprs = [rs.reward] + ([rs.charge] if rs.charge is not None else [])
    if not counters.size:
        tabs = _pair_tables(exprs, markings)
    else:
        prev = np.repeat(markings, n_codes, axis=0)
        now = np.tile(markings, (n_codes, 1))
        now[:, counters] = counter_inc.reshape(n_codes * n_codes, -1)
        tabs = [np.asarray(e.evaluate(prev, now), dtype=float).reshape(n_codes, n_codes) for e in exprs]
    if counters.size:  # the table assumes the reward sees counters only through p - ~p
        prev[:, counters] += 7
        now[:, counters] += 7
        for e, tab in zip(exprs, tabs, strict=True):
            if not np.array_equal(np.asarray(e.evaluate(prev, now), dtype=float).reshape(n_codes, n_codes), tab):
                return None
    reward: np.ndarray | None = tabs[0]
    charge = tabs[1] if len(tabs) > 1 else np.zeros_like(tabs[0])
    if graded:
        reward, charge = None, tabs[0]
    for a in (next_code, reward, charge, marked, counter_inc):
        if a is not None:
            a.setflags(write=False)
    return Tables(next_code, reward, charge, marked, counter_inc)


def _pair_tables(exprs: list[R.RExpr], markings: np.ndarray) -> list[np.ndarray]:
    """Each expression's value on every (previous, new) pair of ``markings`` ``(n, places)``, ``(n, n)``.

    An expression reads the markings only through its token counts (:class:`~mitlc.petri.reward.Tokens`),
    so it is evaluated on the distinct rows of the places they read (the state sub-nets' regions
    repeat in every combination of the other sub-nets' tokens: the cart-pole's sway, 1728 markings
    and 11 places read of 21, has far fewer) and spread to every pair: the same operations on
    the same numbers, without the ``n^2 x places`` arrays (3.6 million rows there)."""
    read: set[int] = set()
    stack = list(exprs)
    while stack:
        e = stack.pop()
        if isinstance(e, R.Tokens):
            read.update(e.places)
        stack.extend(e.children)
    cols = sorted(read)
    uniq, inverse = np.unique(markings[:, cols], axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    u = len(uniq)
    small = np.zeros((u, markings.shape[1]), dtype=markings.dtype)
    small[:, cols] = uniq
    prev, now = np.repeat(small, u, axis=0), np.tile(small, (u, 1))
    pick = np.ix_(inverse, inverse)
    return [np.asarray(e.evaluate(prev, now), dtype=float).reshape(u, u)[pick] for e in exprs]


def build_compact(rule: Rule, rs: RewardSystem) -> Tables | None:
    """Tables over the *reachable* markings only, with elementary clock segments.

    For nets whose sub-nets are many but move together (sixty bounded eventuallys of
    one proposition: 2^60 products, a few thousand reachable markings), the firing
    rule is tabulated by a breadth-first search from every initial marking
    :meth:`~mitlc.runtime.NetRuntime.reset` can produce (the state and timed sub-nets' tokens anywhere, the
    others at ``M0``), and a code is an index into the reachable markings.  The
    reward is tabulated too when the square of their number fits, and evaluated on
    the markings otherwise.  ``None`` when even that is too large.
    """
    atoms, graded = rs.atoms, rs.grader is not None
    n_atoms, n_places = len(atoms), len(rs.net.places)
    if n_atoms > 16 or rs.net.counters:
        return None
    n_atom_codes = 1 << n_atoms
    ends = sorted({c.lo for c in rule.clocks} | {c.hi for c in rule.clocks if math.isfinite(c.hi)})
    reps = [ends[0] - 1.0] if ends else [0.0]
    for j, e in enumerate(ends):
        reps += [e, (e + ends[j + 1]) / 2 if j + 1 < len(ends) else e + 1.0]
    n_segs = len(reps)
    seg_truth = np.array([[bool(clock_ok(c, t)) for c in rule.clocks] for t in reps], dtype=bool).reshape(
        n_segs, len(rule.clocks)
    )
    timed = {s for tn in rs.timed for _, s in tn.subnets}
    free = [s for s, sub in enumerate(rule.net.subnets) if sub.kind == "state" or s in timed]
    n_start = math.prod(len(rule.subnet_places[s]) for s in free)
    if n_start > MAX_TABLE // 64:
        return None
    # markings as local place indices per sub-net, (n, S); the same rule as NetRuntime._fire
    S = rule.n_subnets
    local_of = np.zeros(n_places, dtype=np.int64)
    for places in rule.subnet_places:
        local_of[places] = np.arange(len(places))
    src_local, dst_local = local_of[rule.src], local_of[rule.dst]
    m0 = np.asarray(rule.net.M0)
    base = np.array([local_of[places[np.argmax(m0[places])]] for places in rule.subnet_places], dtype=np.int64)
    grids = np.meshgrid(*[np.arange(len(rule.subnet_places[s])) for s in free], indexing="ij")
    start = np.tile(base, (n_start, 1))
    for s, g in zip(free, grids, strict=True):
        start[:, s] = g.reshape(-1)
    # rows are told apart by a 64-bit hash, checked to be exact (two markings never share one)
    weights = np.random.default_rng(20261201).integers(1, 2**63, size=S, dtype=np.uint64)
    index: dict[int, int] = {}
    rows: list[np.ndarray] = []

    def add(batch: np.ndarray) -> np.ndarray:
        with np.errstate(over="ignore"):
            keys = (batch.astype(np.uint64) * weights).sum(axis=1, dtype=np.uint64)
        uniq, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
        if not np.array_equal(batch, batch[first][inverse.reshape(-1)]):
            raise RuntimeError("marking hash collision")  # pragma: no cover - about 2^-40 here
        ids = np.empty(len(uniq), dtype=np.int64)
        for i, (key, j) in enumerate(zip(uniq.tolist(), first.tolist(), strict=True)):
            if key not in index:
                index[key] = len(rows)
                rows.append(batch[j])
            ids[i] = index[key]
        return ids[inverse.reshape(-1)]

    add(start)
    atom_of = np.tile(np.arange(n_atom_codes, dtype=np.int64), n_segs)
    seg_of = np.repeat(np.arange(n_segs), n_atom_codes)
    transitions: dict[int, np.ndarray] = {}  # code -> next codes (segs x atom codes)
    done = 0
    while done < len(rows):
        layer = np.arange(done, len(rows))
        done = len(rows)
        if done * n_segs * n_atom_codes > MAX_TABLE:
            return None
        L = np.repeat(np.array([rows[i] for i in layer], dtype=np.int64), n_segs * n_atom_codes, axis=0)
        reps_atom = np.tile(atom_of, len(layer))
        reps_seg = np.tile(seg_of, len(layer))
        truth = {a: ((reps_atom >> i) & 1).astype(bool) for i, a in enumerate(atoms)}
        clock_truth = [seg_truth[reps_seg, c] for c in range(len(rule.clocks))]
        guards = rule.guards(truth, clock_truth, L.shape[0], rule.scan)
        nxt = L.copy()
        for sub, formulas in rule.regions:
            nxt[:, sub] = region_move(formulas, L[:, sub], truth)
        taken = np.zeros(L.shape, dtype=bool)
        for k, t in enumerate(rule.scan.tolist()):
            sub = rule.t_subnet[t]
            fire = (L[:, sub] == src_local[t]) & guards[k] & ~taken[:, sub]
            nxt[fire, sub] = dst_local[t]
            taken[:, sub] |= fire
        ids = add(nxt).reshape(len(layer), n_segs, n_atom_codes)
        for i, code in enumerate(layer):
            transitions[int(code)] = ids[i]
    n_codes = len(rows)
    if n_segs * n_codes * n_atom_codes > MAX_TABLE:
        return None
    next_code = np.stack([transitions[c] for c in range(n_codes)], axis=1)  # (segs, codes, atoms)
    locals_ = np.array(rows, dtype=np.int64)
    marked = np.stack([places[locals_[:, s]] for s, places in enumerate(rule.subnet_places)], axis=1)
    markings = np.zeros((n_codes, n_places), dtype=np.int8)
    markings[np.arange(n_codes)[:, None], marked] = 1
    by_bytes = {m.tobytes(): c for c, m in enumerate(markings)}
    reward = charge = None
    pairs = n_codes * n_codes
    # evaluating every pair of a large net costs more than it saves: pairs, and pairs x places (what the
    # evaluation reads: 250 bounded G's, 750 places, would be 1.5 GB per marking array and a minute)
    if pairs <= MAX_TABLE // 16 and pairs * n_places <= 4 * MAX_TABLE:
        prev = np.repeat(markings, n_codes, axis=0).astype(np.int64)
        now = np.tile(markings, (n_codes, 1)).astype(np.int64)
        if not graded:
            reward = np.asarray(rs.reward.evaluate(prev, now), dtype=float).reshape(n_codes, n_codes)
        charge = (
            np.asarray(rs.charge.evaluate(prev, now), dtype=float).reshape(n_codes, n_codes)
            if rs.charge is not None
            else np.zeros((n_codes, n_codes))
        )
    counter_inc = np.zeros((0, 0, 0), dtype=np.int64)
    for a in (next_code, markings, marked):
        a.setflags(write=False)
    return Tables(next_code, reward, charge, marked, counter_inc, markings, by_bytes, np.array(ends, dtype=float))


class Tables:
    """The firing rule and the reward tabulated over marking, atom and clock codes."""

    __slots__ = ("next_code", "reward", "charge", "marked", "counter_inc", "markings", "index", "clock_ends")

    def __init__(
        self,
        next_code: np.ndarray,
        reward: np.ndarray | None,
        charge: np.ndarray | None,
        marked: np.ndarray,
        counter_inc: np.ndarray,
        markings: np.ndarray | None = None,
        index: dict[bytes, int] | None = None,
        clock_ends: np.ndarray | None = None,
    ) -> None:
        self.next_code = next_code  # (clock codes, marking codes, atom codes) -> marking code
        self.reward = reward  # (marking codes, marking codes) -> r(M_k, M_k+1); None: evaluate on markings
        self.charge = charge  # (marking codes, marking codes) -> what the penalty c multiplies (0 with off)
        self.marked = marked  # (marking codes, sub-nets) -> marked place index
        self.counter_inc = counter_inc  # (marking codes, marking codes, counters) -> tokens added
        self.markings = markings  # compact tables: (marking codes, places) int8, the reachable markings
        self.index = index  # compact tables: marking bytes -> code
        self.clock_ends = clock_ends  # compact tables: the clock intervals' ends, cutting time into segments

    @property
    def compact(self) -> bool:
        """Whether codes index the reachable markings (:func:`build_compact`) instead of the mixed radix."""
        return self.markings is not None
