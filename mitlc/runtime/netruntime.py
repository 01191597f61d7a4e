"""Run a batch of reward nets in lock-step with a batch of plants.

A :class:`NetRuntime` holds one compiled :class:`~mitlc.petri.compile.RewardSystem`
and steps ``R`` independent copies of its net at once.  Markings are integer
arrays of shape ``(R, P)`` (runs x places); states are ``(R, n)`` in the
plant's ``state_names`` order.

Firing rule (one step, ``M_k -> M_k+1``)
----------------------------------------
Given the marking ``M_k``, the next state ``x_k+1`` and the clock
``tau_k+1``:

1. every proposition is evaluated on ``x_k+1`` (:meth:`NetRuntime.truth`);
2. every guard is evaluated on those truth values and on ``tau_k+1``
   (:meth:`mitlc.petri.net.Guard.evaluate`);
3. in every sub-net *at most one* transition fires: the first one, in net
   order (``t1, t2, ...``), whose input place is marked in ``M_k`` and whose
   guard holds.  A sub-net whose enabled transitions all have false guards
   keeps its token where it is.  Tokens never move twice in one step, so a
   chain of transitions whose guards hold at once takes one step per arc;
4. ``M_k+1 = T D + M_k`` with ``T`` the 0/1 row vector of fired transitions.

In a region sub-net (a transition from every place to every other, in that order, each
guarded by its target's region) the rule moves the token to the first other place whose
region holds, and leaves it where it is when none does; the runtime computes that
directly instead of scanning the sub-net's ``n (n - 1)`` transitions, and adds the fired
rows of ``D`` from the net's sparse ``D-`` and ``D+`` (``NetRuntime.step_scanning`` is
the rule as written above, kept as the reference the tests compare with).

Time-triggered transitions (the timeline of an interval, the deadline of a
bounded until) are ordinary transitions whose guard is a clock condition; they
fire on the first step whose ``tau_k+1`` satisfies it.

The reward of the step is ``r_k+1 = r(M_k, M_k+1)`` (:meth:`NetRuntime.reward`).

Fast path
---------
Each sub-net holds one token, so a marking is one of finitely many
*codes* (mixed radix over the sub-nets' local place indices), the guards see
the propositions only through a finite *atom code* (one bit per proposition)
and the clock only through which of the guards' clock intervals contain
``tau``.  When those sets are small, the runtime tabulates the rule above once
(``next_code[clock, code, atom]`` and ``reward[code, code']``), and a step is
two table look-ups.  The tables are built *from* the direct rule, and
:meth:`NetRuntime.step` gives the same markings either way (tested).  When the
product of the sub-nets' places is too large, only the markings reachable from
those :meth:`NetRuntime.reset` can produce are tabulated (*compact* tables, codes
index them), and the reward is evaluated on the markings if its table of pairs
would be too large.

Timed obligations
-----------------
The sub-nets of a formula part with nested intervals (``clock = standard``,
:mod:`mitlc.petri.timed`) are moved by per-run obligation state (:mod:`mitlc.runtime.obligations`), not by the
tables: :meth:`NetRuntime.reset` starts it, :meth:`NetRuntime.step` and
:meth:`NetRuntime.step_code` advance it (one sample per call, in order), and a
trainer that looks ``next_code`` up itself calls :meth:`NetRuntime.advance_code`.
A compiled trainer steps its own copy instead: :meth:`NetRuntime.obligation_arrays`
gives the trees as the arrays of :mod:`mitlc.runtime.obligation_kernel`, and
``reset(x0, obligations=False)`` leaves their tokens to it.

>>> from mitlc.spec.parse import parse_spec
>>> from mitlc.petri.compile import compile_spec
>>> rs = compile_spec(parse_spec('''
... plant pendulum(u_max = 3)
... prop kappa = abs(q) < 0.3
... formula F G kappa'''))
>>> rt = NetRuntime(rs)
>>> x0 = np.array([[np.pi, 0.0], [0.1, 0.0]])
>>> M0 = rt.reset(x0); M0.tolist()              # places: p_kappa, p_not_kappa
[[0, 1], [1, 0]]
>>> M1 = rt.step(M0, np.array([[0.2, 0.0], [0.5, 0.0]]), 0.03); M1.tolist()
[[1, 0], [0, 1]]
>>> rt.reward(M0, M1).tolist()                   # (1 + ~p_kappa)(p_kappa - p_not_kappa)
[1.0, -2.0]
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from mitlc.petri.compile import RewardSystem
from mitlc.petri.net import eval_state
from mitlc.runtime import obligation_kernel
from mitlc.runtime import tables as tables_module
from mitlc.runtime.atoms import compile_predicate, pack_atoms, scalar_atoms
from mitlc.runtime.obligation_kernel import ObligationArrays
from mitlc.runtime.obligations import Obligations
from mitlc.runtime.rule import Rule, clock_ok
from mitlc.runtime.tables import Radix, Tables, build_tables
from mitlc.spec import ast as A
from mitlc.spec import predicates as P

__all__ = ["NetRuntime"]


_LAST_TABLES: tuple[RewardSystem, int, Tables | None] | None = None
"""The last reward system a :class:`NetRuntime` tabulated in this process, the table limit then
(:data:`mitlc.runtime.tables.MAX_TABLE`) and its tables: a training builds one runtime per design it
races, per search it judges and for the training itself, all on the one compiled net (the cart-pole's
sway, 1728 markings: 3.4 s a table), and the tables depend on nothing else; a forked race process
inherits them. The tables are read, never written, by every user. (``tables_cache``'s runtimes, one
per ``mitlc check --net``, read the disk's.)"""


def _tables_of(rs: RewardSystem, build: Callable[[], Tables | None]) -> Tables | None:
    """``build()`` (the tables of ``rs``'s net), or what it gave for this very ``rs`` (and limit) last time."""
    global _LAST_TABLES
    limit = tables_module.MAX_TABLE
    if _LAST_TABLES is not None and _LAST_TABLES[0] is rs and _LAST_TABLES[1] == limit:
        return _LAST_TABLES[2]
    tables = build()
    _LAST_TABLES = (rs, limit, tables)
    return tables


LIST_TABLE_LIMIT = 1 << 16
"""Most entries of a table that one-sample callers (:meth:`NetRuntime.sample_stepper`, the Gymnasium
wrapper) copy into nested Python lists: a list look-up costs a tenth of numpy's scalar indexing."""


class NetRuntime:
    """Step ``R`` copies of a reward net together with ``R`` plant states.

    ``state_names`` maps the columns of a state array to variables; by default
    the spec's plant's ``state_names``.
    """

    def __init__(
        self,
        rs: RewardSystem,
        state_names: Sequence[str] | None = None,
        dt: float | None = None,
        steps: int | None = None,
        *,
        tables_cache: bool = False,
    ) -> None:
        self.rs = rs
        self.net = net = rs.net
        if state_names is None:
            plant = rs.spec.plant
            if plant is None:
                raise ValueError("the spec names no plant: pass state_names")
            state_names = plant.state_names
        self.state_names = tuple(state_names)
        self.atoms: tuple[str, ...] = rs.atoms
        self.graded = rs.grader is not None
        """Whether the reward reads the new state too (``reward = shaped``): then no reward table."""
        self.preds: tuple[P.Pred, ...] = tuple(rs.spec.prop(a).pred for a in self.atoms)
        """The atoms' predicates, in atom order (bit ``i`` of an atom code is ``preds[i]``)."""
        self.columns: dict[str, int] = {name: i for i, name in enumerate(self.state_names)}
        """State variable -> column of a state array."""
        for pred in self.preds:
            for v in P.variables(pred):
                if v.name not in self.columns:
                    raise ValueError(f"state variable '{v.name}' is not among {self.state_names}")
        self._fast_preds = tuple(compile_predicate(p, self.columns) for p in self.preds)

        self.rule = rule = Rule(net)
        self.n_places = len(net.places)
        self.n_subnets = rule.n_subnets
        self.subnet_places = rule.subnet_places
        self.clocks: tuple[A.Interval, ...] = rule.clocks
        self._radix = Radix(self.subnet_places, self.n_places)
        self.n_codes = self._radix.n_codes

        # state sub-nets: the region of each place (the state guard into it)
        self._region_of: dict[int, A.Formula] = {}
        regions = dict(rule.regions)
        for s_index, sub in enumerate(net.subnets):
            if sub.kind != "state":
                continue
            if s_index in regions:  # every transition into a place has the one guard, its region
                self._region_of.update(
                    (int(p), f) for p, f in zip(sub.places, regions[s_index], strict=True) if f is not None
                )
                continue
            for t_index in sub.transitions:
                tr = net.transitions[t_index]
                p = net.place_index(tr.outputs[0])
                terms = [term.state for term in tr.guard.terms if term.state is not None and term.clock is None]
                if p not in self._region_of and terms:
                    self._region_of[p] = terms[0]

        # counting places (violations = counted) are outside the one-token codes:
        # their increments are tabulated per (code, next code) pair
        self.counters = np.array(net.counters, dtype=np.intp)
        self.timed = rs.timed
        if tables_cache:  # read from the disk cache, else built and written there (mitlc.runtime.tablefile)
            from mitlc.runtime.tablefile import cached_tables

            radix = self._radix
            self.tables = cached_tables(rs, lambda: build_tables(rule, radix, rs), radix.n_codes, len(rule.clocks))
        else:  # a training's runtimes share one net's tables (_LAST_TABLES)
            self.tables = _tables_of(rs, lambda: build_tables(rule, self._radix, rs))
        self.compact = self.tables is not None and self.tables.compact
        """Whether codes index the reachable markings (compact tables) instead of the mixed radix."""
        self._clock_ends = np.zeros(0)
        if self.tables is not None and self.tables.compact:
            assert self.tables.markings is not None and self.tables.clock_ends is not None
            self.n_codes = len(self.tables.markings)
            self._clock_ends = self.tables.clock_ends

        # timed obligation sub-nets (clock = standard with nested intervals): their tokens
        # are moved by the obligation state (one TimedState per tree), not by the tables
        self.dt: float | None = None
        self.steps: int | None = None
        self._obligations: Obligations | None = None
        if self.timed:
            plant = rs.spec.plant
            if dt is None and plant is not None:
                dt = float(rs.spec.param("dt"))
            if steps is None and dt is not None and rs.spec.horizon is not None:
                steps = int(round(rs.spec.horizon / dt))
            if dt is None or steps is None:
                raise ValueError(
                    "the net has timed obligations: give the spec a plant and a horizon, or pass dt and steps"
                )
            self.dt, self.steps = float(dt), int(steps)
            self._obligations = Obligations(self.timed, self.atoms, self.dt, self.steps)

    # ------------------------------------------------------------ truth
    def truth(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Proposition truth on states ``x`` ``(R, n)``: ``{atom: (R,) bool}``."""
        x = np.asarray(x, dtype=float)
        env = {name: x[:, i] for name, i in self.columns.items()}
        out = {}
        for atom, pred in zip(self.atoms, self.preds, strict=True):
            out[atom] = np.broadcast_to(np.asarray(P.evaluate(pred, env), dtype=bool), x.shape[:1])
        return out

    def atom_code(self, x: np.ndarray) -> np.ndarray:
        """The propositions' truth on ``x`` packed into one integer per run (bit i = atom i)."""
        preds = self._fast_preds
        if not preds:
            return np.zeros(np.shape(x)[0], dtype=np.int64)
        with np.errstate(all="ignore"):  # IEEE arithmetic, as the monitor reads it: exp(exp(q)) > 5 holds at inf
            return pack_atoms(preds, x)

    def clock_code(self, tau: np.ndarray | float) -> np.ndarray | int:
        """Which of the guards' clock intervals contain ``tau``, packed into an integer.

        With compact tables (:func:`mitlc.runtime.tables.build_compact`) the index of the elementary clock
        segment holding ``tau`` instead (the intervals' ends cut the time line into
        points and open stretches on which every clock condition is constant).
        """
        if self.compact:
            ends = self._clock_ends
            j = np.searchsorted(ends, tau, side="left")
            on = (j < len(ends)) & (ends[np.minimum(j, len(ends) - 1)] == tau) if len(ends) else False
            seg = 2 * j + np.asarray(on, dtype=np.int64)
            return int(seg) if np.ndim(tau) == 0 else seg
        if np.ndim(tau) == 0:
            tau = float(tau)
            return sum(1 << i for i, c in enumerate(self.clocks) if clock_ok(c, tau))
        tau = np.asarray(tau, dtype=float)
        code = np.zeros(tau.shape, dtype=np.int64)
        for i, c in enumerate(self.clocks):
            code += np.asarray(clock_ok(c, tau), dtype=np.int64) << i
        return code

    # ------------------------------------------------------------ markings and codes
    def _check_marking(self, M: np.ndarray) -> np.ndarray:
        M = np.asarray(M)
        if M.ndim != 2 or M.shape[1] != self.n_places:
            raise ValueError(f"marking must be (R, {self.n_places}), got {M.shape}")
        for s, places in enumerate(self.subnet_places):
            if not np.all(M[:, places].sum(axis=1) == 1):
                raise ValueError(f"sub-net {self.net.subnets[s].name!r} must hold exactly one token")
        return M

    def encode(self, M: np.ndarray) -> np.ndarray:
        """Marking ``(R, P)`` (one token per sub-net) to codes ``(R,)``."""
        if self.compact:
            assert self.tables is not None and self.tables.index is not None
            index, rows = self.tables.index, np.ascontiguousarray(np.asarray(M, dtype=np.int8))
            try:
                return np.array([index[r.tobytes()] for r in rows], dtype=np.int64)
            except KeyError:
                raise ValueError("marking outside the net's reachable markings") from None
        return self._radix.encode(M)

    def decode(self, code: np.ndarray) -> np.ndarray:
        """Codes ``(R,)`` to markings ``(R, P)``."""
        if self.compact:
            assert self.tables is not None and self.tables.markings is not None
            return self.tables.markings[np.asarray(code, dtype=np.int64)].astype(np.int64)
        return self._radix.decode(code)

    def marked_places(self, code: np.ndarray) -> np.ndarray:
        """Codes ``(R,)`` to the marked place of every sub-net, ``(R, S)`` place indices."""
        return self.tables.marked[np.asarray(code)] if self.tables is not None else self._radix.marked(code)

    # ------------------------------------------------------------ the rule itself
    def step_direct(self, M: np.ndarray, x_next: np.ndarray, tau_next: np.ndarray | float) -> np.ndarray:
        """:meth:`step` computed from the rule (no tables); the reference."""
        M = self._check_marking(M)
        n = M.shape[0]
        truth = self.truth(x_next)
        tau = np.broadcast_to(np.asarray(tau_next, dtype=float), (n,))
        clock_truth = [clock_ok(c, tau) for c in self.clocks]
        return self.rule.fire(M, truth, clock_truth)

    def step_scanning(self, M: np.ndarray, x_next: np.ndarray, tau_next: np.ndarray | float) -> np.ndarray:
        """:meth:`step_direct` by the transition-scanning rule everywhere
        (:meth:`~mitlc.runtime.rule.Rule.fire_scanning`): the reference the faster rule is tested against."""
        M = self._check_marking(M)
        n = M.shape[0]
        truth = self.truth(x_next)
        tau = np.broadcast_to(np.asarray(tau_next, dtype=float), (n,))
        clock_truth = [clock_ok(c, tau) for c in self.clocks]
        return self.rule.fire_scanning(M, self.rule.guards(truth, clock_truth, n))

    # ------------------------------------------------------------ timed obligations
    def _timed_observe(self, x: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """Feed sample ``x`` to every obligation tree: ``(sub-net, local place (R,))`` pairs."""
        assert self._obligations is not None
        return self._obligations.observe(self.atom_code(x))

    def _timed_reset(self, x0: np.ndarray) -> list[tuple[int, np.ndarray]]:
        assert self._obligations is not None
        return self._obligations.start(self.atom_code(x0))

    def _timed_markings(self, M: np.ndarray, moves: list[tuple[int, np.ndarray]]) -> np.ndarray:
        rows = np.arange(M.shape[0])
        for s, local in moves:
            places = self.subnet_places[s]
            M[:, places] = 0
            M[rows, places[local]] = 1
        return M

    def _timed_codes(self, code: np.ndarray, moves: list[tuple[int, np.ndarray]]) -> np.ndarray:
        if self.compact:
            return self.encode(self._timed_markings(self.decode(code), moves))
        code = np.array(code, dtype=np.int64)
        for s, local in moves:
            code += (local - self._radix.local(code, s)) * self._radix.strides[s]
        return code

    def advance_code(self, code_next: np.ndarray, x_next: np.ndarray) -> np.ndarray:
        """Move the timed obligation tokens of codes ``code_next`` for sample ``x_next``.

        The tables keep those tokens where they are; a trainer that looks
        ``next_code`` up itself calls this after every look-up (a no-op, returning
        ``code_next``, when the net has no timed obligations).
        """
        if not self.timed:
            return code_next
        return self._timed_codes(code_next, self._timed_observe(np.asarray(x_next, dtype=float)))

    def obligation_arrays(self) -> ObligationArrays:
        """The timed obligation trees as the arrays of a compiled per-run engine
        (:mod:`mitlc.runtime.obligation_kernel`), for trials of :attr:`steps` samples of :attr:`dt`;
        empty ones without timed obligations. Its tokens move by mixed-radix code arithmetic: not
        with compact tables (ValueError)."""
        if not self.timed:
            return obligation_kernel.empty()
        if self.compact:
            raise ValueError("compact tables: a code indexes the reachable markings, a token cannot move by arithmetic")
        assert self.dt is not None and self.steps is not None
        sizes = [len(p) for p in self.subnet_places]
        return obligation_kernel.build(self.timed, self.atoms, self.dt, self.steps, self._radix.strides, sizes)

    def obligation_clocks(self) -> np.ndarray:
        """Per run, the age of each timed node's oldest live obligation divided by its interval's
        upper end (the trial length when unbounded), 0 where none lives: ``(R, timed nodes)``."""
        return self._obligations.clocks() if self._obligations is not None else np.zeros((0, 0))

    def verdicts(self) -> np.ndarray:
        """Per run, each obligation tree's value so far (``timed.TRUE``, ``FALSE``, ``PENDING``), ``(R, trees)``."""
        return self._obligations.verdicts() if self._obligations is not None else np.zeros((0, 0))

    # ------------------------------------------------------------ public API
    def reset(self, x0: np.ndarray, obligations: bool = True) -> np.ndarray:
        """Initial markings ``(R, P)``: timing places from ``net.M0``, state tokens on x0's region.

        The timed obligations are started on ``x0`` and their tokens placed; with ``obligations=False``
        they are neither (their tokens stay at ``net.M0``): for a caller that steps its own copy of
        them (SACPN's fused kernel, :mod:`mitlc.runtime.obligation_kernel`).
        """
        x0 = np.asarray(x0, dtype=float)
        n = x0.shape[0]
        M = np.tile(np.asarray(self.net.M0, dtype=np.int64), (n, 1))
        truth = self.truth(x0)
        for sub, places in zip(self.net.subnets, self.subnet_places, strict=True):
            if sub.kind != "state":
                continue
            placed = np.zeros(n, dtype=bool)
            new = np.zeros((n, len(places)), dtype=np.int64)
            for j, p in enumerate(places):
                region = self._region_of.get(int(p))
                if region is None:
                    continue
                here = eval_state(region, truth) & ~placed
                new[:, j] = here
                placed |= here
            new[~placed] = M[~placed][:, places]  # no region holds: keep M0 (cannot happen for region nets)
            M[:, places] = new
        if self.timed and obligations:
            M = self._timed_markings(M, self._timed_reset(x0))
        return M

    def step(self, M: np.ndarray, x_next: np.ndarray, tau_next: np.ndarray | float) -> np.ndarray:
        """``M_k+1`` from ``M_k`` ``(R, P)``, ``x_k+1`` ``(R, n)`` and ``tau_k+1`` (scalar or ``(R,)``)."""
        if self.tables is None:
            M_next = self.step_direct(M, x_next, tau_next)
            if self.timed:
                M_next = self._timed_markings(M_next, self._timed_observe(np.asarray(x_next, dtype=float)))
            return M_next
        M = self._check_marking(M)
        code = self.encode(M)
        code_next = self.step_code(code, np.asarray(x_next, dtype=float), tau_next)
        M_next = self.decode(code_next)
        if self.counters.size:
            M_next[:, self.counters] = M[:, self.counters] + self.tables.counter_inc[code, code_next]
        return M_next

    def reward(self, M_prev: np.ndarray, M_next: np.ndarray, x_next: np.ndarray | None = None) -> np.ndarray:
        """``r(M_k, M_k+1)`` for every run, ``(R,)`` floats; a graded reward (``reward = shaped``) also
        reads the new states ``x_next`` ``(R, n)``."""
        grades = self.grades(x_next) if self.graded else None
        return np.asarray(self.rs.reward.evaluate(np.asarray(M_prev), np.asarray(M_next), grades), dtype=float)

    def grades(self, x: np.ndarray | None) -> np.ndarray:
        """The propositions' grades ``(R, atoms)`` at states ``x`` ``(R, n)`` (``reward = shaped``)."""
        if self.rs.grader is None:
            raise ValueError("the reward has no graded propositions (reward = net)")
        if x is None:
            raise ValueError("a graded reward (reward = shaped) needs the new states x_next")
        x = np.asarray(x, dtype=float)
        return self.rs.grader.grades({name: x[:, i] for name, i in self.columns.items()})

    # ------------------------------------------------------------ fast path on codes
    def reset_code(self, x0: np.ndarray, obligations: bool = True) -> np.ndarray:
        """:meth:`reset` as marking codes ``(R,)``."""
        return self.encode(self.reset(x0, obligations))

    def step_code(self, code: np.ndarray, x_next: np.ndarray, tau_next: np.ndarray | float) -> np.ndarray:
        """:meth:`step` on marking codes (needs the tables)."""
        tables = self.tables
        if tables is None:
            code_next = self.encode(self.step_direct(self.decode(code), x_next, tau_next))
        else:
            code_next = tables.next_code[self.clock_code(tau_next), code, self.atom_code(x_next)]
        return self.advance_code(code_next, x_next)

    def trace_codes(self, x: np.ndarray, taus: np.ndarray) -> np.ndarray | None:
        """The marking codes ``(N+1,)`` of one run over a whole recorded trace: :meth:`reset_code` on
        ``x[0]``, then :meth:`step_code` on each ``x[k]`` at ``taus[k]``, ``x`` ``(N+1, n)``. The
        propositions and clock conditions of every sample are evaluated at once, then one table
        look-up per sample (what ``mitlc check --net`` steps a long trace with). None where a step
        needs more than the tables: no tables, or timed obligations.

        >>> from mitlc.spec.parse import parse_spec
        >>> from mitlc.petri.compile import compile_spec
        >>> rt = NetRuntime(compile_spec(parse_spec("prop a = x < 1\\nformula F[0,1] a")), ["x"])
        >>> x, taus = np.array([[2.0], [0.5], [3.0]]), np.array([0.0, 0.6, 1.2])
        >>> codes = [rt.reset_code(x[:1])]
        >>> for k in (1, 2):
        ...     codes.append(rt.step_code(codes[-1], x[k : k + 1], taus[k]))
        >>> rt.trace_codes(x, taus).tolist() == np.concatenate(codes).tolist()
        True
        """
        tables = self.tables
        if tables is None or self.timed:
            return None
        x = np.asarray(x, dtype=float)
        code = int(self.reset_code(x[:1])[0])
        if len(x) == 1:
            return np.array([code], dtype=np.int64)
        atoms = np.asarray(self.atom_code(x[1:]), dtype=np.int64)
        clocks = np.asarray(self.clock_code(np.asarray(taus[1:], dtype=float)), dtype=np.int64)
        clocks = np.broadcast_to(clocks, atoms.shape)
        table = np.ascontiguousarray(tables.next_code, dtype=np.int64)
        n_codes, n_atoms = table.shape[1], table.shape[2]
        flat = table.reshape(-1).data  # a memoryview, whose items are Python ints: the loop stays in plain Python
        out = [code]
        append = out.append
        for base in (clocks * n_codes * n_atoms + atoms).tolist():
            code = flat[base + code * n_atoms]
            append(code)
        return np.array(out, dtype=np.int64)

    def sample_stepper(self) -> Callable[[int, Sequence[float], float], int] | None:
        """:meth:`step_code` for one run on Python numbers, ``step(code, x, tau) -> code``, with ``x`` the
        state as a sequence of floats (``state_names`` order): the propositions in plain Python
        (:func:`mitlc.runtime.atoms.scalar_atoms`, numpy's truths) and one table look-up, for callers
        that step one sample at a time (the Gymnasium wrapper). None where a step needs more than
        the tables: no tables, timed obligations, or counting places.
        """
        tables = self.tables
        if tables is None or self.timed or self.counters.size:
            return None
        atoms = scalar_atoms(self.preds, self.columns)
        table = tables.next_code
        if not self.compact and not self.clocks:
            if table[0].size <= LIST_TABLE_LIMIT:  # nested lists of ints: a look-up without numpy
                rows = table[0].tolist()

                def step(code: int, x: Sequence[float], tau: float) -> int:
                    return rows[code][atoms(x)]

            else:

                def step(code: int, x: Sequence[float], tau: float) -> int:
                    return int(table[0, code, atoms(x)])

        else:
            clock = self.clock_code

            def step(code: int, x: Sequence[float], tau: float) -> int:
                return int(table[clock(tau), code, atoms(x)])

        return step

    def trace_markings(self, codes: np.ndarray) -> np.ndarray:
        """Full markings ``(R, N+1, P)`` of code sequences ``(R, N+1)``, counters included.

        Codes leave out the counting places; their tokens are the running sum of
        the increments of each step.
        """
        codes = np.asarray(codes, dtype=np.int64)
        R, K = codes.shape
        M = self.decode(codes.reshape(-1)).reshape(R, K, self.n_places)
        if self.counters.size and K > 1:
            if self.tables is None:  # pragma: no cover - counted nets small enough to tabulate
                raise ValueError("counter tokens need the tables; use step() markings instead")
            inc = self.tables.counter_inc[codes[:, :-1], codes[:, 1:]]  # (R, K-1, C)
            M[:, 1:, self.counters] = np.cumsum(inc, axis=1)
        return M

    def reward_code(self, code_prev: np.ndarray, code_next: np.ndarray, x_next: np.ndarray | None = None) -> np.ndarray:
        """:meth:`reward` on marking codes (a graded reward reads ``x_next`` too)."""
        if self.tables is None or self.tables.reward is None:
            shape = np.shape(code_prev)
            prev, nxt = np.ravel(code_prev), np.ravel(code_next)
            return self.reward(self.decode(prev), self.decode(nxt), x_next).reshape(shape)
        return self.tables.reward[code_prev, code_next]

    def charge_code(self, code_prev: np.ndarray, code_next: np.ndarray) -> np.ndarray:
        """What the violation penalty ``c`` multiplies on these steps (0 without violations)."""
        if self.tables is not None and self.tables.charge is not None:
            return self.tables.charge[code_prev, code_next]
        if self.rs.charge is None:
            return np.zeros(np.shape(code_prev))
        shape = np.shape(code_prev)
        prev, nxt = self.decode(np.ravel(code_prev)), self.decode(np.ravel(code_next))
        return np.asarray(self.rs.charge.evaluate(prev, nxt), dtype=float).reshape(shape)
