"""The reward net stepped beside an episode: :class:`MitlNetEnv`, what every environment of
:mod:`mitlc.gym` is (:class:`~mitlc.gym.MitlRewardWrapper` and :class:`~mitlc.gym.MitlPlantEnv`).

It drives one :class:`~mitlc.runtime.NetRuntime` run per episode: the net back at its
initial marking on ``reset`` (:meth:`MitlNetEnv._net_reset`), one step of the net per step of
the environment (:meth:`MitlNetEnv._net_step`, on the net's marking codes where its tables hold
the whole step), and the monitor's ``info["verdict"]`` on the states so far.
:class:`MarkingCodes` is the tabulated net that :class:`mitlc.gym.crm.CounterfactualReplayBuffer`
reads.
"""

from __future__ import annotations

import importlib
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.errors import InputError, MitlError
from mitlc.gym.observation import clock_high, n_clocks, token_bounds
from mitlc.petri.compile import RewardSystem, compile_spec
from mitlc.runtime import NetRuntime, scalar_atoms
from mitlc.runtime.netruntime import LIST_TABLE_LIMIT
from mitlc.spec import predicates as P
from mitlc.spec.model import Spec
from mitlc.spec.parse import load_spec

VERDICT = ("step", "end", "off")
"""When ``info["verdict"]`` is computed: every step, at the end of an episode, never."""


def reward_system_of(spec: RewardSystem | Spec | str | os.PathLike) -> RewardSystem:
    """``spec`` compiled: a :class:`RewardSystem` as it is, a :class:`Spec`, or the path of a ``.mitl``
    file (or a shipped spec's name)."""
    if isinstance(spec, RewardSystem):
        return spec
    if isinstance(spec, Spec):
        return compile_spec(spec)
    if isinstance(spec, (str, os.PathLike)):
        return compile_spec(load_spec(os.fspath(spec)))
    raise InputError(f"expected a RewardSystem, a Spec or the path of a .mitl file, got {type(spec).__name__}")


def _state_names(spec: Spec) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(columns of a state vector, the variables the propositions read)."""
    used = {v.name for p in spec.props for v in P.variables(p.pred)}
    plant = spec.plant
    columns = plant.state_names if plant is not None else tuple(sorted(used))
    return tuple(columns), tuple(n for n in columns if n in used)


@dataclass(frozen=True)
class MarkingCodes:
    """The net of a :class:`MitlNetEnv` on marking codes, one sample at a time: what
    :class:`mitlc.gym.crm.CounterfactualReplayBuffer` steps every other marking with.

    ``markings[c]`` is the marking of code ``c`` ``(places,)`` (int64, ``place_names`` order),
    ``rewards[c, c1]`` the reward of the step from ``c`` to ``c1``, and ``step(c, x, tau)`` the
    code after ``c`` when the state becomes ``x`` (floats, ``state_names`` order) at ``tau``.
    """

    markings: np.ndarray
    rewards: np.ndarray
    step: Callable[[int, Sequence[float], float], int]


class MitlNetEnv:
    """What :class:`~mitlc.gym.MitlRewardWrapper` and :class:`~mitlc.gym.MitlPlantEnv` share: the reward net stepped
    beside an episode's states, its marking and clocks in the observation, and the monitor's
    ``info["verdict"]``.

    A learner or a tool that works with either reads these: ``reward_system``, ``mitl_spec``,
    ``runtime`` (the :class:`~mitlc.runtime.NetRuntime` of the episode), ``state_names``,
    ``place_names``, ``dt``, ``marking_obs``, ``marking`` and ``clocks`` (now), ``trace`` (the
    states so far), :attr:`marking_codes` (the tabulated net, or None) and the observation's
    layout: with ``marking_obs="box"`` a flat observation is the environment's own (flattened,
    :attr:`marking_offset` entries), then the marking, then the clocks;
    :meth:`flat_state` reads the spec's state off its first part.
    """

    reward_system: RewardSystem
    mitl_spec: Spec
    runtime: NetRuntime
    state_names: tuple[str, ...]
    place_names: tuple[str, ...]
    dt: float
    marking_obs: str
    marking_offset: int
    """Where the marking starts in a flat observation (``marking_obs="box"``)."""
    token_bounds: np.ndarray
    n_clocks: int

    def _setup_net(self, rs: RewardSystem, dt: float, steps: int | None, verdict: str) -> None:
        """The net, its tables and the monitors for an environment of ``dt`` seconds per step
        (``steps``: the episode's length where the net has timed obligations)."""
        self.reward_system = rs
        self.mitl_spec = spec = rs.spec
        self.state_names, self._needed = _state_names(spec)
        self.place_names = rs.net.place_names
        self.token_bounds = token_bounds(rs)
        self._marking_dtype = np.int8 if bool(np.all(self.token_bounds == 1)) else np.int64
        self.n_clocks = n_clocks(rs)
        self._clock_high = clock_high(rs)
        self.dt = dt
        self.runtime = rt = NetRuntime(rs, self.state_names, dt=dt, steps=steps)
        self._steps = rt.steps
        self._monitor = None
        self._judge: Any = None  # the episode's verdict on Python numbers (a ScalarTraceMonitor)
        self._online: Any = None
        self._online_scalar = False  # a ScalarOnlineMonitor, fed lists of floats
        if verdict != "off":
            try:
                self._monitor = importlib.import_module("mitlc.monitor").monitor
                scalar_offline = importlib.import_module("mitlc.monitor.scalar_offline")
                try:
                    self._judge = scalar_offline.ScalarTraceMonitor(spec, dt, columns=self.state_names)
                except MitlError:  # nothing to judge by (no formula line): the offline monitor says so, at the end
                    self._judge = None
                if verdict == "step":  # each prefix's verdict in constant time per step, on Python floats
                    scalar = importlib.import_module("mitlc.monitor.scalar")
                    self._online = scalar.ScalarOnlineMonitor(spec, dt, columns=self.state_names)
                    self._online_scalar = True
                    if not self._online.constant_time:  # the prefix read again: numpy's loops are the faster
                        online = importlib.import_module("mitlc.monitor.online")
                        self._online = online.OnlineMonitor(spec, dt)
                        self._online_scalar = False
            except ImportError:  # the monitor is optional here: no verdict without it
                self._monitor = self._online = self._judge = None
        self._verdict_mode = verdict
        self._samples_checked = False  # whether every sample comes from a reader that checks it (the wrapper's)
        self._judged = [(n, i) for i, n in enumerate(self.state_names) if n in self._needed]

        self._M = np.tile(np.asarray(rs.net.M0, dtype=np.int64), (1, 1))
        self._k = 0
        self._rows: list[list[float]] = [[0.0] * len(self.state_names)]  # the states x_0 .. x_k so far
        # a tabulated net steps on its marking code: two table look-ups, no marking checks
        self._code: np.ndarray | None = None
        self._marking_of: np.ndarray | None = None
        if rt.tables is not None and not rt.counters.size and rt.n_codes * rt.n_places <= 1 << 20:
            table = rt.tables.markings if rt.tables.markings is not None else rt.decode(np.arange(rt.n_codes))
            self._marking_of = np.asarray(table, dtype=np.int64)
        # one sample in plain Python where the tables hold the whole step (no timed obligations):
        # the propositions on floats, then look-ups by int; the marking as a row of a table
        self._step1 = rt.sample_stepper() if self._marking_of is not None and not rs.paid_by_monitor else None
        # sparse, robustness, robustness-window: the monitor pays (mitlc.monitor.rewards), the net still runs
        self._paid: Any = None
        if rs.paid_by_monitor:
            rewards = importlib.import_module("mitlc.monitor.rewards")
            self._paid = rewards.TraceReward(spec, rs.options.reward, dt, self.state_names)
        if self._step1 is not None and (rt.tables is None or rt.tables.reward is None):
            self._step1 = None
        self._code1 = 0
        self._rewards1: list[list[float]] | None = None
        self._rows1: list[np.ndarray] = []
        self._start1: dict[int, int] = {}  # atom code of x_0 -> marking code of the start, as reset finds it
        self._atoms1: Callable[[Sequence[float]], int] | None = None
        if self._step1 is not None:
            assert rt.tables is not None and rt.tables.reward is not None and self._marking_of is not None
            self._reward_of = rt.tables.reward
            self._M_of = self._marking_of[:, None, :]  # code -> (1, places), the shape of _M
            self._row_of = self._marking_of.astype(self._marking_dtype)
            # one sample on Python numbers: the rewards as nested lists of floats, a marking row per code
            if self._reward_of.size <= LIST_TABLE_LIMIT:
                self._rewards1 = self._reward_of.tolist()
            self._rows1 = list(self._row_of)
            if not rt.timed and not rt.counters.size:  # the start's marking: a function of x_0's atoms
                self._atoms1 = scalar_atoms(rt.preds, rt.columns)

    @property
    def marking_codes(self) -> MarkingCodes | None:
        """The net on marking codes one sample at a time, or None where a step needs more than its
        tables (timed obligations, counting places, a net too large to tabulate, a reward paid by
        the monitor)."""
        if self._step1 is None or self._marking_of is None:
            return None
        return MarkingCodes(self._marking_of, self._reward_of, self._step1)

    def flat_state(self, flat: np.ndarray) -> np.ndarray:  # pragma: no cover - interface
        """The spec's state ``(n,)`` read off the first :attr:`marking_offset` entries of a flat
        observation (``marking_obs="box"``)."""
        raise NotImplementedError

    # ------------------------------------------------------------ the episode
    def _net_reset(self, x0: np.ndarray) -> dict[str, Any]:
        """A new episode from the state ``x0`` ``(n,)``: the ``info`` entries of its start."""
        self._k = 0
        self._rows = [x0.tolist()]
        atoms1 = self._atoms1
        if atoms1 is not None and self._step1 is not None:  # the start of x_0's atoms, found once
            atom = atoms1(x0.tolist())
            code1 = self._start1.get(atom)
            if code1 is None:
                code1 = self._start1[atom] = int(self.runtime.encode(self.runtime.reset(x0[None, :]))[0])
            self._code1 = code1
            self._code = np.array([code1], dtype=np.int64)
            self._M = self._M_of[code1]
        else:
            self._M = self.runtime.reset(x0[None, :])
            if self._marking_of is not None:
                self._code = self.runtime.encode(self._M)
                self._code1 = int(self._code[0])
        info = self._info()
        if self._online is not None:
            self._online.reset()
            self._add_online_verdict(info, x0.tolist())
        if self._paid is not None:
            self._paid.reset(x0[None, :])
        return info

    @property
    def _tau_next(self) -> float:
        """The clock after the next step."""
        return (self._k + 1) * self.dt

    def _net_step(
        self, xs: list[float], done: bool, info: dict[str, Any] | None = None
    ) -> tuple[float, dict[str, Any]]:
        """The net's step to the state ``xs`` (floats, ``state_names`` order), the last of the
        episode when ``done``: the reward and the ``info`` entries ``marking``, ``tau``, ``verdict``
        (added to ``info`` where given, else in a dict of their own)."""
        k = self._k = self._k + 1
        self._rows.append(xs)
        steps = self._steps
        if steps is not None and k > steps:
            raise InputError(
                f"the episode ran past the spec's horizon ({self.mitl_spec.horizon} s): the timed obligations "
                "end there; use truncate_at_horizon=True or a longer horizon",
                file=self.mitl_spec.path,
            )
        tau = k * self.dt
        step1 = self._step1
        if step1 is not None:  # one sample on Python numbers
            code = self._code1
            self._code1 = code1 = step1(code, xs, tau)
            rewards1 = self._rewards1
            reward = rewards1[code][code1] if rewards1 is not None else float(self._reward_of[code, code1])
            marking = self._rows1[code1].copy()  # (_M, the array path's marking, is not kept up here)
        else:
            x = np.array([xs], dtype=float)
            if self._code is not None and self._marking_of is not None:
                code_next = self.runtime.step_code(self._code, x, tau)
                reward = float(self.runtime.reward_code(self._code, code_next, x)[0])
                self._code, self._M = code_next, self._marking_of[code_next]
            else:
                M_next = self.runtime.step(self._M, x, tau)
                reward = float(self.runtime.reward(self._M, M_next, x)[0])
                self._M = M_next
            marking = self.marking
        if self._paid is not None:  # the monitor's reward of the trace so far (terminal ones at its end)
            reward = float(self._paid.step(np.array([xs], dtype=float), done)[0])
        if info is None:
            info = {}
        info["marking"] = marking
        info["tau"] = tau
        online = self._online
        if done:  # the whole episode's verdict, with when and why it failed
            if online is not None:
                satisfied, robustness = self._online_update(xs)
                if satisfied:  # the offline monitor's verdict to the bit, and nothing failed
                    info["verdict"] = {
                        "satisfied": True,
                        "robustness": robustness,
                        "violation_time": None,
                        "failing": None,
                    }
                else:
                    self._add_verdict(info)
            elif self._verdict_mode != "off":
                self._add_verdict(info)
        elif online is not None:
            if self._online_scalar:  # a sample the reader checked (finite, one value per column) or not
                satisfied, robustness = online.update_checked(xs) if self._samples_checked else online.update(xs)
            else:
                satisfied, robustness = self._online_update(xs)
            info["verdict"] = {"satisfied": satisfied, "robustness": robustness}
        return reward, info

    @property
    def marking(self) -> np.ndarray:
        """The current marking ``M_k`` ``(places,)`` in ``place_names`` order.

        int8 when every place holds at most one token; int64 when the net
        counts (the counters of ``violations = counted``).
        """
        if self._step1 is not None:
            return self._rows1[self._code1].copy()
        return self._M[0].astype(self._marking_dtype)

    @property
    def trace(self) -> np.ndarray:
        """The states ``x_0 .. x_k`` of this episode so far, ``(k+1, n)`` (a copy)."""
        return np.array(self._rows, dtype=float).reshape(len(self._rows), len(self.state_names))

    @property
    def clocks(self) -> np.ndarray:
        """The live obligations' clocks ``(timed nodes,)``: for each timed obligation sub-net (in net
        order), the age of its oldest live obligation divided by its interval's upper end (by the
        horizon when unbounded), 0 when none lives. Empty without nested intervals."""
        if not self.n_clocks:
            return np.zeros(0, np.float32)
        return np.minimum(self.runtime.obligation_clocks()[0], self._clock_high).astype(np.float32)

    def _info(self) -> dict[str, Any]:
        return {"marking": self.marking, "tau": self._k * self.dt}

    def _online_update(self, x: Sequence[float]) -> tuple[bool, float]:
        """The online monitor's verdict and robustness after the sample ``x`` (``state_names`` order)."""
        if self._online_scalar:
            return self._online.update(x)
        v = self._online.update({n: np.asarray(x[i : i + 1], dtype=float) for n, i in self._judged})
        return bool(v.satisfied[0]), float(v.robustness[0])

    def _add_online_verdict(self, info: dict[str, Any], x: Sequence[float]) -> None:
        satisfied, robustness = self._online_update(x)
        info["verdict"] = {"satisfied": satisfied, "robustness": robustness}

    def _add_verdict(self, info: dict[str, Any]) -> None:
        if self._monitor is None:
            return
        judge = self._judge
        if judge is not None:  # one run on Python numbers: the offline monitor's verdict
            truth, rob = self._online.signals() if self._online_scalar else ({}, {})
            if self._online_scalar and all(n in truth for n in judge.names):  # the signals the online monitor kept
                verdict = judge.judge_signals(truth, rob, self._k + 1)
            else:
                verdict = judge.judge(self._rows)
            satisfied, robustness, violation, failing = verdict
            if robustness and violation != 0.0:  # a zero's sign is numpy's: the offline monitor says it
                info["verdict"] = {
                    "satisfied": satisfied,
                    "robustness": robustness,
                    "violation_time": violation,
                    "failing": failing,
                }
                return
        trace = self.trace
        states = {n: trace[:, i] for i, n in enumerate(self.state_names) if n in self._needed}
        res = self._monitor(self.mitl_spec, states, self.dt)
        violation = float(res.violation_time[0])
        info["verdict"] = {
            "satisfied": bool(res.satisfied[0]),
            "robustness": float(res.robustness[0]),
            "violation_time": None if math.isnan(violation) else violation,
            "failing": res.failing[0],
        }
