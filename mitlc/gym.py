"""Use a compiled reward system with any Gymnasium environment: the edge to other learners.

In: a :class:`~mitlc.petri.RewardSystem` (or a :class:`~mitlc.spec.Spec`, or the path of a
``.mitl`` file) and a Gymnasium environment. Out: :class:`MitlRewardWrapper`, the environment
paying the compiled reward. May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`,
:mod:`mitlc.limits`, :mod:`mitlc.plants`, :mod:`mitlc.spec`, :mod:`mitlc.petri`, :mod:`mitlc.monitor`,
:mod:`mitlc.learn`.

:class:`MitlRewardWrapper` steps the reward net (one :class:`~mitlc.learn.runtime.NetRuntime`
run) alongside a Gymnasium environment:

=================  =====================================================================
what               with the wrapper
=================  =====================================================================
reward             ``r(M_k, M_k+1)``, the compiled reward; the environment's own reward
                   is kept in ``info["env_reward"]``
observation        ``{"obs": obs, "marking": M_k}`` (``Dict`` of the env's space and a
                   ``MultiBinary(places)``), or with ``marking_obs="box"`` one flat
                   ``Box``: the flattened observation followed by the marking.  A net
                   that counts (``violations = counted``) has an unbounded ``Box``
                   entry per counter instead of ``MultiBinary``.  A formula with
                   nested intervals adds ``"clocks"`` (after the marking in the
                   ``Box``): the live obligations' ages over their bounds
                   (:attr:`MitlRewardWrapper.clocks`), so that state, marking and
                   clocks together make the reward Markov
``info``           ``marking`` (``M_k``, int8, in ``net.place_names`` order), ``tau``
                   (``k * dt``), ``env_reward``, and ``verdict``: the monitor's verdict
                   on ``x_0 .. x_k`` (``satisfied``, ``robustness``; at the episode's
                   end also ``violation_time`` and ``failing``), when
                   :mod:`mitlc.monitor` is available
``reset``          the net goes back to its initial marking: timing tokens at ``M0``,
                   state tokens on the region of ``x_0``
=================  =====================================================================

:class:`MitlPlantEnv` (registered as ``mitlc/Pendulum-v0``, ``mitlc/MassDamper-v0``) is one of
mitlc's plants as an environment paying the same reward, with the same marking, clocks and
``info``. Both are a :class:`MitlNetEnv`: the interface :class:`mitlc.crm.CounterfactualReplayBuffer`
and :class:`Sb3Policy` (a Stable-Baselines3 model trained on them as a
:class:`mitlc.learn.policy.Policy`, for ``mitlc simulate --policy model.zip``) read.

The spec's state variables are read off each observation by ``observe``:
a function ``obs -> {variable: value}`` such as :func:`pendulum_v1_state`, or a
dict mapping each variable to an index into the flattened observation or to a
function ``obs -> float``.  The clock is ``tau_k = k * dt``, with ``dt`` the
environment's ``dt`` attribute (``Pendulum-v1``: 0.05 s) unless given, else the
spec plant's ``dt``.

Gymnasium is an optional dependency: ``pip install 'mitlc[gym]'``.

>>> import gymnasium as gym
>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec('''
... plant pendulum
... prop kappa = abs(q) < 0.3
... formula F G kappa''')
>>> env = MitlRewardWrapper(gym.make("Pendulum-v1"), spec, pendulum_v1_state)
>>> env.place_names
('p_kappa', 'p_not_kappa')
>>> obs, info = env.reset(seed=1)             # starts near upright: q = 0.074
>>> round(float(pendulum_v1_state(obs["obs"])["q"]), 3), obs["marking"].tolist()
(0.074, [1, 0])
>>> obs, reward, terminated, truncated, info = env.step(np.array([0.0], dtype=np.float32))
>>> reward, info["marking"].tolist(), info["tau"], bool(info["verdict"]["satisfied"])
(2.0, [1, 0], 0.05, True)
"""

from __future__ import annotations

import importlib
import json
import math
import os
import zipfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, SupportsFloat

import numpy as np

try:
    import gymnasium as gym
    from gymnasium import spaces
except ImportError as exc:  # pragma: no cover - exercised in a subprocess by tests/test_gym.py
    raise ImportError("mitlc.gym needs Gymnasium, an optional dependency: pip install 'mitlc[gym]'") from exc

from mitlc.errors import InputError
from mitlc.learn.policy import Policy
from mitlc.learn.runtime import NetRuntime
from mitlc.petri.compile import RewardSystem, compile_spec
from mitlc.plants.base import PLANTS, make_integrator, wrap_angle
from mitlc.plants.gym_env import MAX_RESETS, env_dt, outside_init
from mitlc.spec import predicates as P
from mitlc.spec.model import Spec
from mitlc.spec.parse import load_spec

__all__ = [
    "MitlRewardWrapper",
    "MitlPlantEnv",
    "MitlNetEnv",
    "MarkingCodes",
    "ENV_IDS",
    "pendulum_v1_state",
    "plant_observation",
    "Sb3Policy",
    "load_sb3",
    "sb3_algorithm",
    "SB3_EXTRA",
    "Observe",
    "MARKING_OBS",
    "VERDICT",
]

Observe = Callable[[Any], Mapping[str, float]] | Mapping[str, int | Callable[[Any], float]]
"""How to read the spec's state variables off an observation."""

MARKING_OBS = ("dict", "box")
"""How the marking joins the observation: a ``Dict`` space or one flat ``Box``."""

VERDICT = ("step", "end", "off")
"""When ``info["verdict"]`` is computed: every step, at the end of an episode, never."""

_SCALARS = (float, int, np.floating, np.integer)
_TWO_PI = 2 * np.pi


def pendulum_v1_state(obs: Any) -> dict[str, Any]:
    """Gymnasium ``Pendulum-v1`` observation ``[cos th, sin th, thdot]`` -> ``{"q", "qdot"}``.

    Gymnasium's ``theta = 0`` is upright and positive ``thdot`` increases theta,
    as for the spec's pendulum (``q`` from upright).  ``q = atan2(sin, cos)``
    wrapped to ``[-pi, pi)``.  Works on one observation or a batch ``(..., 3)``.

    >>> pendulum_v1_state(np.array([-1.0, 0.0, 0.5], dtype=np.float32))
    {'q': -3.141592653589793, 'qdot': 0.5}
    >>> pendulum_v1_state(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -2.0]]))["q"].round(4)
    array([0.    , 1.5708])
    """
    o = np.asarray(obs, dtype=float)
    if o.shape[-1:] != (3,):
        raise InputError(f"a Pendulum-v1 observation has 3 entries [cos th, sin th, thdot], got shape {o.shape}")
    if o.ndim == 1:  # one observation: floats, the same numbers (wrap_angle's operations on a float)
        q = float(np.arctan2(o[1], o[0]))
        return {"q": (q + math.pi) % _TWO_PI - math.pi, "qdot": float(o[2])}
    return {"q": np.asarray(wrap_angle(np.arctan2(o[..., 1], o[..., 0]))), "qdot": o[..., 2]}


def _reward_system(spec: RewardSystem | Spec | str | os.PathLike) -> RewardSystem:
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


def _spec_observe(plant: Any, base: spaces.Space) -> Callable[[Any], dict[str, float]]:
    """A gym plant's ``state`` lines as an ``observe`` function of one observation."""
    cols = plant.observation

    def observe(obs: Any) -> dict[str, float]:
        flat = np.asarray(spaces.flatten(base, obs), dtype=float).reshape(1, -1)
        return {o.var.name: float(np.asarray(o.read(flat)).reshape(-1)[0]) for o in cols}

    return observe


def _positive_dt(value: Any, where: str) -> float:
    try:
        dt = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{where} must be a number of seconds, got {value!r}") from None
    if not (math.isfinite(dt) and dt > 0):
        raise InputError(f"{where} must be positive and finite, got {dt}")
    return dt


def _call_getter(f: Callable[[Any], float]) -> Callable[[Any, np.ndarray], float]:
    """A state variable read by a user function of the observation."""
    return lambda obs, flat: float(np.asarray(f(obs), dtype=float))


def _index_getter(i: int) -> Callable[[Any, np.ndarray], float]:
    """A state variable read at index ``i`` of the flattened observation."""
    return lambda obs, flat: float(flat[i])


@dataclass(frozen=True)
class MarkingCodes:
    """The net of a :class:`MitlNetEnv` on marking codes, one sample at a time: what
    :class:`mitlc.crm.CounterfactualReplayBuffer` steps every other marking with.

    ``markings[c]`` is the marking of code ``c`` ``(places,)`` (int64, ``place_names`` order),
    ``rewards[c, c1]`` the reward of the step from ``c`` to ``c1``, and ``step(c, x, tau)`` the
    code after ``c`` when the state becomes ``x`` (floats, ``state_names`` order) at ``tau``.
    """

    markings: np.ndarray
    rewards: np.ndarray
    step: Callable[[int, Sequence[float], float], int]


class MitlNetEnv:
    """What :class:`MitlRewardWrapper` and :class:`MitlPlantEnv` share: the reward net stepped
    beside an episode's states, its marking and clocks in the observation, and the monitor's
    ``info["verdict"]``.

    A learner or a tool that works with either reads these: ``reward_system``, ``mitl_spec``,
    ``runtime`` (the :class:`~mitlc.learn.runtime.NetRuntime` of the episode), ``state_names``,
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
        self.token_bounds = _token_bounds(rs)
        self._marking_dtype = np.int8 if bool(np.all(self.token_bounds == 1)) else np.int64
        self.n_clocks = _n_clocks(rs)
        self._clock_high = _clock_high(rs)
        self.dt = dt
        self.runtime = rt = NetRuntime(rs, self.state_names, dt=dt, steps=steps)
        self._monitor = None
        self._online = None
        if verdict != "off":
            try:
                self._monitor = importlib.import_module("mitlc.monitor").monitor
                if verdict == "step":  # each prefix's verdict in constant time per step
                    online = importlib.import_module("mitlc.monitor.online")
                    self._online = online.OnlineMonitor(spec, dt)
            except ImportError:  # the monitor is optional here: no verdict without it
                self._monitor = self._online = None
        self._verdict_mode = verdict
        self._judged = [(n, i) for i, n in enumerate(self.state_names) if n in self._needed]

        self._M = np.tile(np.asarray(rs.net.M0, dtype=np.int64), (1, 1))
        self._k = 0
        self._trace = np.zeros((64, len(self.state_names)))
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
        if self._step1 is not None:
            assert rt.tables is not None and rt.tables.reward is not None and self._marking_of is not None
            self._reward_of = rt.tables.reward
            self._M_of = self._marking_of[:, None, :]  # code -> (1, places), the shape of _M
            self._row_of = self._marking_of.astype(self._marking_dtype)

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
        self._trace[0] = x0
        self._M = self.runtime.reset(x0[None, :])
        if self._marking_of is not None:
            self._code = self.runtime.encode(self._M)
            self._code1 = int(self._code[0])
        info = self._info()
        if self._online is not None:
            self._online.reset()
            self._add_online_verdict(info, x0)
        if self._paid is not None:
            self._paid.reset(x0[None, :])
        return info

    @property
    def _tau_next(self) -> float:
        """The clock after the next step."""
        return (self._k + 1) * self.dt

    def _net_step(self, xs: list[float], done: bool) -> tuple[float, dict[str, Any]]:
        """The net's step to the state ``xs`` (floats, ``state_names`` order), the last of the
        episode when ``done``: the reward and the ``info`` entries ``marking``, ``tau``, ``verdict``."""
        k = self._k = self._k + 1
        if k >= self._trace.shape[0]:
            self._trace = np.concatenate([self._trace, np.zeros_like(self._trace)])
        self._trace[k] = xs
        if self.runtime.steps is not None and k > self.runtime.steps:
            raise InputError(
                f"the episode ran past the spec's horizon ({self.mitl_spec.horizon} s): the timed obligations "
                "end there; use truncate_at_horizon=True or a longer horizon",
                file=self.mitl_spec.path,
            )
        tau = k * self.dt
        if self._step1 is not None:  # one sample on Python numbers
            code = self._code1
            self._code1 = code1 = self._step1(code, xs, tau)
            reward = float(self._reward_of[code, code1])
            self._M = self._M_of[code1]
        else:
            x = self._trace[k : k + 1]
            if self._code is not None and self._marking_of is not None:
                code_next = self.runtime.step_code(self._code, x, tau)
                reward = float(self.runtime.reward_code(self._code, code_next, x)[0])
                self._code, self._M = code_next, self._marking_of[code_next]
            else:
                M_next = self.runtime.step(self._M, x, tau)
                reward = float(self.runtime.reward(self._M, M_next, x)[0])
                self._M = M_next
        if self._paid is not None:  # the monitor's reward of the trace so far (terminal ones at its end)
            reward = float(self._paid.step(self._trace[k : k + 1], done)[0])
        info = self._info()
        if done:  # the whole episode's verdict, with when and why it failed
            if self._verdict_mode != "off":
                self._add_verdict(info)
            if self._online is not None:
                self._online.update({n: self._trace[k : k + 1, i] for n, i in self._judged})
        elif self._online is not None:
            self._add_online_verdict(info, self._trace[k])
        return reward, info

    @property
    def marking(self) -> np.ndarray:
        """The current marking ``M_k`` ``(places,)`` in ``place_names`` order.

        int8 when every place holds at most one token; int64 when the net
        counts (the counters of ``violations = counted``).
        """
        if self._step1 is not None:
            return self._row_of[self._code1].copy()
        return self._M[0].astype(self._marking_dtype)

    @property
    def trace(self) -> np.ndarray:
        """The states ``x_0 .. x_k`` of this episode so far, ``(k+1, n)`` (a copy)."""
        return self._trace[: self._k + 1].copy()

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

    def _add_online_verdict(self, info: dict[str, Any], x: np.ndarray) -> None:
        assert self._online is not None
        v = self._online.update({n: x[i : i + 1] for n, i in self._judged})
        info["verdict"] = {"satisfied": bool(v.satisfied[0]), "robustness": float(v.robustness[0])}

    def _add_verdict(self, info: dict[str, Any]) -> None:
        if self._monitor is None:
            return
        states = {n: self._trace[: self._k + 1, i] for i, n in enumerate(self.state_names) if n in self._needed}
        res = self._monitor(self.mitl_spec, states, self.dt)
        violation = float(res.violation_time[0])
        info["verdict"] = {
            "satisfied": bool(res.satisfied[0]),
            "robustness": float(res.robustness[0]),
            "violation_time": None if math.isnan(violation) else violation,
            "failing": res.failing[0],
        }


class MitlRewardWrapper(MitlNetEnv, gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Replace an environment's reward by a compiled MITL reward and show the marking.

    Parameters
    ----------
    env:
        Any Gymnasium environment.
    spec:
        A compiled :class:`~mitlc.petri.compile.RewardSystem`, a :class:`~mitlc.spec.model.Spec`
        or the path of a ``.mitl`` file.
    observe:
        ``obs -> {variable: value}``, or ``{variable: index or (obs -> value)}``
        with indices into the flattened observation.  Every state variable a
        proposition reads must be given; angles of the spec's plant are wrapped
        to ``[-pi, pi)``.  Default (None): the ``state`` lines of a spec whose
        plant is ``gym:ID``.  Such a spec's ``init`` is a condition on the
        environment's starts: a reset outside it is redone (the environment's
        generator goes on from ``seed``, so a seed still fixes the start).  The
        ``init`` of a spec for another plant (``plant pendulum``) describes that
        plant's starts and is not applied: the environment starts as it does.
    marking_obs:
        ``"dict"``: observations ``{"obs": ..., "marking": ...}``; ``"box"``: one
        flat ``Box``, the flattened observation then the marking.
    dt:
        Seconds per step (the clock is ``tau_k = k * dt``); default: for a spec
        whose plant is ``gym:ID``, that plant's ``dt`` (the spec's, else the
        environment's); otherwise the environment's ``dt``, ``tau`` or
        ``metadata["dt"]``, else the spec plant's ``dt``.
    verdict:
        ``"step"``: ``info["verdict"]`` after every step, ``satisfied`` and
        ``robustness`` of ``x_0 .. x_k`` from the online monitor
        (:class:`mitlc.monitor.online.OnlineMonitor`, constant time per step for
        bounded formulas), and when the episode terminates or is truncated also
        ``violation_time`` and ``failing`` from the offline monitor; ``"end"``:
        the offline monitor's whole verdict only when the episode ends; ``"off"``:
        never.
    truncate_at_horizon:
        Also truncate the episode when ``tau`` reaches the spec's ``horizon``.
    """

    def __init__(
        self,
        env: gym.Env,
        spec: RewardSystem | Spec | str | os.PathLike,
        observe: Observe | None = None,
        marking_obs: str = "dict",
        dt: float | None = None,
        *,
        verdict: str = "step",
        truncate_at_horizon: bool = False,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self,
            spec=spec,
            observe=observe,
            marking_obs=marking_obs,
            dt=dt,
            verdict=verdict,
            truncate_at_horizon=truncate_at_horizon,
        )
        gym.Wrapper.__init__(self, env)
        rs = _reward_system(spec)
        s = rs.spec
        if marking_obs not in MARKING_OBS:
            raise InputError(f"marking_obs must be one of {', '.join(MARKING_OBS)}, got {marking_obs!r}")
        if verdict not in VERDICT:
            raise InputError(f"verdict must be one of {', '.join(VERDICT)}, got {verdict!r}")
        self.marking_obs = marking_obs

        spec_plant = s.plant
        if dt is None and spec_plant is not None and spec_plant.stepped:  # gym:ID: the spec's dt, else the env's
            dt, where = s.param("dt"), f"the dt of plant {spec_plant.name}"
        if dt is None:
            dt, where = env_dt(env)
            if dt is None:
                if s.plant is None:
                    raise InputError(
                        "no dt: the environment has no 'dt' or 'tau' attribute and no metadata['dt'], and the spec "
                        "names no plant; pass dt= (seconds per step)"
                    )
                dt, where = s.param("dt"), "the plant's dt"
        else:
            where = "dt"
        dt = _positive_dt(dt, where)
        steps = None
        if rs.timed:
            if s.horizon is None:
                raise InputError(
                    "the formula has timed obligations (nested intervals), which need the trial length: "
                    "give the spec a 'horizon'",
                    file=s.path,
                )
            steps = int(round(s.horizon / dt))
        self._setup_net(rs, dt, steps, verdict)

        base = env.observation_space
        n_places = len(self.place_names)
        binary = self._marking_dtype == np.int8
        clock_high = self._clock_high
        if marking_obs == "dict":
            marking_space = (
                spaces.MultiBinary(n_places)
                if binary
                else spaces.Box(np.zeros(n_places, np.float32), self.token_bounds.astype(np.float32), dtype=np.float32)
            )
            entries: dict[str, spaces.Space] = {"obs": base, "marking": marking_space}
            if self.n_clocks:
                entries["clocks"] = spaces.Box(np.zeros(self.n_clocks, np.float32), clock_high, dtype=np.float32)
            self.observation_space = spaces.Dict(entries)
            self.marking_offset = 0
        else:
            flat = spaces.flatten_space(base)
            if not isinstance(flat, spaces.Box):
                raise InputError(f"marking_obs='box' needs an observation space that flattens to a Box, got {base}")
            dtype = np.result_type(flat.dtype, np.float32)
            self.observation_space = spaces.Box(
                low=np.concatenate([flat.low.astype(dtype), np.zeros(n_places + self.n_clocks, dtype)]),
                high=np.concatenate(
                    [flat.high.astype(dtype), self.token_bounds.astype(dtype), clock_high.astype(dtype)]
                ),
                dtype=dtype,
            )
            self.marking_offset = int(flat.shape[0])
        self._flat_base = isinstance(base, spaces.Box) and len(base.shape) == 1
        self.horizon = s.horizon if truncate_at_horizon else None
        if truncate_at_horizon and self.horizon is None:
            raise InputError("truncate_at_horizon=True but the spec has no horizon")

        if observe is None:
            if spec_plant is None or not spec_plant.stepped:
                raise InputError(
                    "observe= is needed: how to read the spec's state variables off an observation "
                    "(or a spec whose plant is gym:ID with 'state' lines)"
                )
            observe = _spec_observe(spec_plant, base)
        self._periodic = np.array(
            [spec_plant is not None and spec_plant.var(n).periodic for n in self.state_names],
            dtype=bool,
        )
        self._read = self._reader(observe, base)
        # a gym:ID spec's init is a condition on the environment's starts (a reset outside is
        # redone); another plant's init describes that plant's starts, which an environment
        # cannot be put in (a point such as q = pi is never drawn): the env starts as it does
        own = spec_plant is not None and spec_plant.stepped
        self._init = [
            (self.state_names.index(r.var), r.lo, r.hi) for r in (s.init if own else ()) if r.var in self.state_names
        ]

    # ------------------------------------------------------------ observation -> state
    def _reader(self, observe: Observe, base: spaces.Space) -> Callable[[Any], list[float]]:
        names = self.state_names
        column = {n: i for i, n in enumerate(names)}
        needed = self._needed
        if callable(observe) and not isinstance(observe, Mapping):
            fn = observe

            seen: list[Any] = [None]  # the last key set found good: later samples check it in one comparison

            def read(obs: Any) -> list[float]:
                values = fn(obs)
                if not isinstance(values, Mapping):
                    raise InputError(
                        f"observe() must return a mapping from state variable to value, got {type(values).__name__}"
                    )
                if values.keys() != seen[0]:
                    missing = [n for n in needed if n not in values]
                    if missing:
                        raise InputError(
                            f"observe() gave no value for state variable '{missing[0]}' "
                            f"(the propositions read {', '.join(needed)})"
                        )
                    for key in values:
                        if key not in column:
                            raise InputError(
                                f"observe() gave '{key}', which is not a state variable of the spec "
                                f"({', '.join(names)})"
                            )
                    seen[0] = frozenset(values)
                x = [math.nan] * len(names)
                for key, v in values.items():
                    x[column[key]] = float(v) if isinstance(v, _SCALARS) else float(np.asarray(v, dtype=float))
                return x

        elif isinstance(observe, Mapping):
            unknown = [k for k in observe if k not in column]
            if unknown:
                raise InputError(
                    f"observe maps '{unknown[0]}', which is not a state variable of the spec ({', '.join(names)})"
                )
            missing = [n for n in needed if n not in observe]
            if missing:
                raise InputError(
                    f"observe gives no value for state variable '{missing[0]}' "
                    f"(the propositions read {', '.join(needed)})"
                )
            try:
                size: int | None = spaces.flatdim(base)
            except (NotImplementedError, ValueError, TypeError):
                size = None
            getters: list[tuple[int, Callable[[Any, np.ndarray], float]]] = []
            for key, how in observe.items():
                if callable(how):
                    getters.append((column[key], _call_getter(how)))
                elif isinstance(how, (int, np.integer)) and not isinstance(how, bool):
                    i = int(how)
                    if size is not None and not -size <= i < size:
                        raise InputError(
                            f"observe maps '{key}' to index {i}, outside the flattened observation of size {size}"
                        )
                    getters.append((column[key], _index_getter(i)))
                else:
                    raise InputError(f"observe maps '{key}' to {how!r}: expected an index or a function obs -> value")
            needs_flat = any(isinstance(h, (int, np.integer)) for h in observe.values())

            def read(obs: Any) -> list[float]:
                flat = np.asarray(spaces.flatten(base, obs), dtype=float).reshape(-1) if needs_flat else np.empty(0)
                x = [math.nan] * len(names)
                for col, get in getters:
                    x[col] = float(get(obs, flat))
                return x

        else:
            raise InputError(f"observe must be a function or a mapping, got {type(observe).__name__}")

        checks = [(n, column[n]) for n in needed]
        angles = [i for i, n in enumerate(names) if self._periodic[i]]

        def checked(obs: Any) -> list[float]:
            x = read(obs)
            for n, i in checks:
                if not math.isfinite(x[i]):
                    raise InputError(f"observe gave a non-finite value for '{n}': {x[i]}")
            for i in angles:  # wrap_angle's operations on one float (Python's % is numpy's remainder)
                x[i] = (x[i] + math.pi) % _TWO_PI - math.pi
            return x

        return checked

    def state(self, obs: Any) -> np.ndarray:
        """The spec's state ``(n,)`` (``state_names`` order) read off ``obs``; angles wrapped."""
        return np.array(self._read(obs), dtype=float)

    def flat_state(self, flat: np.ndarray) -> np.ndarray:
        """The spec's state ``(n,)`` read off the environment's observation flattened (the first
        :attr:`marking_offset` entries of a ``marking_obs="box"`` observation)."""
        base = self.env.observation_space
        return self.state(flat if self._flat_base else spaces.unflatten(base, np.asarray(flat, dtype=base.dtype)))

    # ------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        x0 = self.state(obs)
        tries = 0
        while not self._inside_init(x0):
            tries += 1
            if tries > MAX_RESETS:
                ranges = ", ".join(f"{self.state_names[i]} in [{lo:g}, {hi:g}]" for i, lo, hi in self._init)
                raise InputError(
                    f"the environment did not start inside the spec's init ({ranges}) in {MAX_RESETS} resets",
                    file=self.mitl_spec.path,
                )
            obs, info = self.env.reset(options=options)  # the env's generator goes on from seed
            x0 = self.state(obs)
        info = dict(info)
        info.update(self._net_reset(x0))
        return self._observation(obs), info

    def _inside_init(self, x: np.ndarray) -> bool:
        return not bool(outside_init(x[None, :], self._init)[0])

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, env_reward, terminated, truncated, info = self.env.step(action)
        xs = self._read(obs)
        tau = self._tau_next
        if self.horizon is not None and tau >= self.horizon - 1e-9 * max(1.0, self.horizon):
            truncated = True
        reward, net_info = self._net_step(xs, bool(terminated or truncated))
        info = dict(info)
        info["env_reward"] = env_reward
        info.update(net_info)
        return self._observation(obs), reward, bool(terminated), bool(truncated), info

    # ------------------------------------------------------------ helpers
    def _observation(self, obs: Any) -> Any:
        marking = self.marking
        if self.marking_obs == "dict":
            if self._marking_dtype != np.int8:
                marking = marking.astype(np.float32)
            out = {"obs": obs, "marking": marking}
            if self.n_clocks:
                out["clocks"] = self.clocks
            return out
        space = self.observation_space
        flat = np.asarray(spaces.flatten(self.env.observation_space, obs), dtype=space.dtype).reshape(-1)
        return np.concatenate([flat, marking.astype(space.dtype), self.clocks.astype(space.dtype)])


def _token_bounds(rs: RewardSystem) -> np.ndarray:
    """Most tokens each place can hold: 1, or inf for a counting place (``violations = counted``).

    >>> from mitlc.spec.parse import parse_spec
    >>> from mitlc.petri.compile import CompileOptions
    >>> spec = parse_spec("plant pendulum\\nhorizon 3\\nprop a = q < 1\\nformula G a")
    >>> _token_bounds(compile_spec(spec, CompileOptions(violations="counted")))
    array([ 1.,  1.,  1.,  1., inf])
    """
    bounds = np.ones(len(rs.net.places))
    bounds[list(rs.net.counters)] = np.inf
    return bounds


def _n_clocks(rs: RewardSystem) -> int:
    """The live obligations' clocks an observation shows: one per timed obligation sub-net."""
    return sum(len(tn.subnets) for tn in rs.timed)


def _clock_high(rs: RewardSystem) -> np.ndarray:
    """The most each clock can show ``(clocks,)``: the horizon over its interval's upper end (1 when
    unbounded), inf without a horizon."""
    high = np.full(_n_clocks(rs), np.inf, np.float32)
    if rs.timed and rs.spec.horizon is not None:
        h = float(rs.spec.horizon)
        his = [tn.tree.nodes[node].interval.hi for tn in rs.timed for node, _ in tn.subnets]
        high[:] = [h / hi if math.isfinite(hi) and hi > 0 else 1.0 for hi in his]
    return high


def plant_observation(x: np.ndarray, marking: np.ndarray, clocks: np.ndarray, marking_obs: str) -> Any:
    """What :class:`MitlPlantEnv` observes, for a batch: states ``x`` ``(B, n)``, markings ``(B, places)``
    and clocks ``(B, clocks)`` as ``{"obs", "marking"[, "clocks"]}`` of ``(B, ...)`` arrays, or one
    ``(B, n + places + clocks)`` float32 array with ``marking_obs="box"``. In the ``Dict`` an int8
    marking (one-token places) stays int8, any other becomes float32.

    >>> o = plant_observation(np.array([[0.5, -1.0]]), np.array([[0, 1]]), np.zeros((1, 0)), "box")
    >>> o.tolist(), o.dtype
    ([[0.5, -1.0, 0.0, 1.0]], dtype('float32'))
    """
    x = np.asarray(x, dtype=np.float32)
    marking = np.asarray(marking)
    clocks = np.asarray(clocks, dtype=np.float32)
    if marking_obs == "box":
        return np.concatenate([x, marking.astype(np.float32), clocks], axis=1)
    out: dict[str, np.ndarray] = {
        "obs": x,
        "marking": marking if marking.dtype == np.int8 else marking.astype(np.float32),
    }
    if clocks.shape[1]:
        out["clocks"] = clocks
    return out


class MitlPlantEnv(MitlNetEnv, gym.Env):
    """One of mitlc's plants as a Gymnasium environment that pays a spec's compiled reward.

    ``gymnasium.make("mitlc/Pendulum-v0", spec="pendulum/p2_avoid")`` (registered when
    :mod:`mitlc.gym` is imported; ``"mitlc.gym:mitlc/Pendulum-v0"`` imports it for you).
    ``spec`` is a :class:`RewardSystem`, a :class:`Spec`, a path or a shipped spec's name
    (default: the plant's default spec); its ``init`` box is the reset distribution (or
    ``reset(options={"x0": x})`` starts at ``x``), its ``horizon`` the episode length
    (truncated there). Observations are ``{"obs": x, "marking": M}`` (plus ``"clocks"`` with
    nested intervals), or one flat ``Box`` with ``marking_obs="box"``
    (:func:`plant_observation`); the action is the input ``u`` in ``[-u_max, u_max]``.

    ``info`` carries ``marking``, ``tau`` and the monitor's ``verdict`` as
    :class:`MitlRewardWrapper`'s does, with the same ``verdict=`` option (``"step"``,
    ``"end"``, ``"off"``); a reward paid by the monitor (``sparse``, ``robustness``,
    ``robustness-window``) is paid by it here too. It is a :class:`MitlNetEnv` as the wrapper
    is: :class:`mitlc.crm.CounterfactualReplayBuffer` takes it, and :class:`Sb3Policy` rolls a
    model trained on it out for ``mitlc simulate``.
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(
        self,
        spec: RewardSystem | Spec | str | os.PathLike | None = None,
        plant: str = "pendulum",
        marking_obs: str = "dict",
        render_mode: str | None = None,
        *,
        verdict: str = "step",
    ) -> None:
        if plant not in PLANTS:
            raise InputError(f"unknown plant '{plant}' (known: {', '.join(sorted(PLANTS))})")
        if spec is None:
            default = PLANTS[plant].default_spec
            if not default:
                raise InputError(f"plant '{plant}' has no default spec: pass spec=")
            spec = default.removesuffix(".mitl")
        rs = _reward_system(spec)
        s = rs.spec
        if s.plant_name != plant:
            raise InputError(f"the spec is for plant '{s.plant_name}', not '{plant}'", file=s.path)
        if s.horizon is None:
            raise InputError("the spec has no 'horizon': the episode length", file=s.path)
        if marking_obs not in MARKING_OBS:
            raise InputError(f"marking_obs must be one of {', '.join(MARKING_OBS)}, got {marking_obs!r}")
        if verdict not in VERDICT:
            raise InputError(f"verdict must be one of {', '.join(VERDICT)}, got {verdict!r}")
        self.marking_obs = marking_obs
        self.plant = PLANTS[plant]
        self.params = self.plant.params({k: v for k, v in s.plant_params})
        dt = float(self.params["dt"])
        self.u_max = float(self.params["u_max"])
        self.steps = max(1, int(round(s.horizon / dt)))
        self._setup_net(rs, dt, self.steps, verdict)
        self._integrate = make_integrator(self.plant, self.params)
        init = {r.var: (r.lo, r.hi) for r in s.init}
        self._init = np.array([init.get(v, (0.0, 0.0)) for v in self.plant.state_names], dtype=float)
        self._periodic = np.array([v.periodic for v in self.plant.state])
        high = np.array([np.pi if v.periodic else np.inf for v in self.plant.state], dtype=np.float32)
        state_space = spaces.Box(-high, high, dtype=np.float32)
        n_places = len(self.place_names)
        binary = self._marking_dtype == np.int8
        if marking_obs == "dict":
            marking_space: spaces.Space = (
                spaces.MultiBinary(n_places)
                if binary
                else spaces.Box(np.zeros(n_places, np.float32), self.token_bounds.astype(np.float32), dtype=np.float32)
            )
            entries: dict[str, spaces.Space] = {"obs": state_space, "marking": marking_space}
            if self.n_clocks:
                entries["clocks"] = spaces.Box(0.0, np.inf, (self.n_clocks,), dtype=np.float32)
            self.observation_space = spaces.Dict(entries)
        else:
            low = np.concatenate([-high, np.zeros(n_places + self.n_clocks, np.float32)])
            top = np.concatenate(
                [high, self.token_bounds.astype(np.float32), np.full(self.n_clocks, np.inf, np.float32)]
            )
            self.observation_space = spaces.Box(low, top, dtype=np.float32)
        self.marking_offset = len(self.plant.state_names)
        self.action_space = spaces.Box(-self.u_max, self.u_max, (1,), dtype=np.float32)
        self.render_mode = render_mode
        self._x = np.zeros((1, len(self.plant.state)))

    def state(self, obs: Any) -> np.ndarray:
        """The plant's state ``(n,)`` read off an observation's ``"obs"`` entry (float64; angles wrapped)."""
        x = np.array(obs, dtype=float).reshape(-1)
        x[self._periodic] = wrap_angle(x[self._periodic])
        return x

    def flat_state(self, flat: np.ndarray) -> np.ndarray:
        """The plant's state ``(n,)``: the first :attr:`marking_offset` entries of a flat observation."""
        return self.state(np.asarray(flat)[: self.marking_offset])

    def _obs(self) -> Any:
        o = plant_observation(self._x, self.marking[None, :], self.clocks[None, :], self.marking_obs)
        return o[0] if self.marking_obs == "box" else {k: v[0] for k, v in o.items()}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """A new episode from a start drawn from the spec's ``init`` box, or from ``options={"x0": x}``
        (the plant's state, ``state_names`` order), such as a start ``mitlc simulate`` printed."""
        super().reset(seed=seed)
        lo, hi = self._init[:, 0], self._init[:, 1]
        x = self.np_random.uniform(lo, hi)[None, :]
        if options and "x0" in options:
            try:
                given = np.array(options["x0"], dtype=float).reshape(-1)
            except (TypeError, ValueError):
                given = np.array([np.nan])
            if given.shape != (len(self.state_names),) or not np.all(np.isfinite(given)):
                raise InputError(
                    f"options['x0'] must be {len(self.state_names)} finite numbers ({', '.join(self.state_names)}), "
                    f"got {options['x0']!r}"
                )
            x = given[None, :]
            out = self._periodic & ((x[0] < -np.pi) | (x[0] >= np.pi))  # an angle in range stays as given
            x[:, out] = wrap_angle(x[:, out])
        else:
            x[:, self._periodic] = wrap_angle(x[:, self._periodic])
        self._x = x
        info = self._net_reset(x[0])
        return self._obs(), info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        u = np.clip(np.asarray(action, dtype=float).reshape(-1)[:1], -self.u_max, self.u_max)
        self._integrate(self._x, u)
        truncated = self._k + 1 >= self.steps
        reward, info = self._net_step(self._x[0].tolist(), truncated)
        return self._obs(), reward, False, truncated, info


class Sb3Policy(Policy):
    """A Stable-Baselines3 model as a :class:`mitlc.learn.policy.Policy` on a spec's plant, so that it
    is rolled out and judged as a trained SACPN policy is (``mitlc simulate --policy model.zip``).

    ``model`` was trained on a :class:`MitlPlantEnv` of the spec (``gymnasium.make(
    "mitlc/Pendulum-v0", spec=...)``, either ``marking_obs``), or on a :class:`MitlRewardWrapper`
    whose environment observes ``obs_of(x)``: a function of the plant's states ``(B, n) -> (B, ...)``,
    by default the states themselves, as :class:`MitlPlantEnv` shows them. Its state is the reward
    net's marking ``(B, places)``, as for SACPN; :meth:`act` builds the observation the environment
    would give from ``x``, the marking and the obligations' clocks, and asks the model for its
    deterministic action, clipped to ``[-u_max, u_max]``. One model: ``runs`` is 1.
    """

    def __init__(
        self,
        model: Any,
        spec: RewardSystem | Spec | str | os.PathLike,
        obs_of: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        rs = _reward_system(spec)
        s = rs.spec
        plant = s.plant
        if plant is None or plant.stepped or s.plant_name not in PLANTS:
            what = "names no plant" if plant is None else f"is for plant {s.plant_name}, a Gymnasium environment"
            raise InputError(
                f"the spec {what}: an SB3 model is rolled out on one of mitlc's plants "
                f"({', '.join(sorted(PLANTS))}); judge it on a Gymnasium environment with MitlRewardWrapper's "
                "info['verdict']",
                file=s.path,
            )
        if s.horizon is None:
            raise InputError("the spec has no 'horizon': the rollouts' length", file=s.path)
        self.model, self.reward_system, self.spec, self.runs = model, rs, s, 1
        self.plant = PLANTS[s.plant_name]
        self.params = self.plant.params(dict(s.plant_params))
        self.dt = float(self.params["dt"])
        self.u_max = float(self.params["u_max"])
        self.n_steps = max(1, int(round(s.horizon / self.dt)))
        init = {r.var: (r.lo, r.hi) for r in s.init}
        self.init_ranges = [init.get(v, (0.0, 0.0)) for v in self.plant.state_names]
        """The spec's ``init`` box, ``(lo, hi)`` per state variable (0 where it says nothing)."""
        self.runtime = NetRuntime(rs, self.plant.state_names, dt=self.dt, steps=self.n_steps)
        self.place_names = rs.net.place_names
        self._obs_of = obs_of
        bounds = _token_bounds(rs)
        self._marking_dtype = np.int8 if bool(np.all(bounds == 1)) else np.int64
        self.n_clocks = _n_clocks(rs)
        self._clock_high = _clock_high(rs)
        self.marking_obs = self._layout(getattr(model, "observation_space", None))
        self._k = 0

    def _layout(self, space: Any) -> str:
        """``"dict"`` or ``"box"``: how the model's observations hold the marking; checked against the net."""
        n = len(self.plant.state_names)
        probe = np.zeros((1, n))
        own = np.asarray(self._obs_of(probe) if self._obs_of is not None else probe)
        width, p, c = int(np.prod(own.shape[1:])), len(self.place_names), self.n_clocks
        net = f"the spec's net has {p} places" + (f" and {c} clocks" if c else "")
        if isinstance(space, spaces.Dict) and {"obs", "marking"} <= set(space.spaces):
            got_p = int(np.prod(space["marking"].shape or (0,)))
            got_c = int(np.prod(space["clocks"].shape or (0,))) if "clocks" in space.spaces else 0
            if (got_p, got_c) != (p, c):
                raise InputError(
                    f"the model observes {got_p} marking entries and {got_c} clocks, {net}: "
                    "was it trained on another spec, or with other compile options?",
                    file=self.spec.path,
                )
            return "dict"
        if isinstance(space, spaces.Box) and len(space.shape) == 1:
            if space.shape[0] != width + p + c:
                raise InputError(
                    f"the model observes {space.shape[0]} numbers, and the plant's {width} with the marking "
                    f"make {width + p + c} ({net}): was it trained on another spec, or with other compile options?",
                    file=self.spec.path,
                )
            return "box"
        raise InputError(
            f"the model's observation space {space} is not one a mitlc environment gives: "
            "{'obs', 'marking'[, 'clocks']} or one flat Box (marking_obs='box')",
            file=self.spec.path,
        )

    def observation(self, x: np.ndarray, marking: np.ndarray) -> Any:
        """The observation the environment gives in the states ``x`` ``(B, n)`` with the net in
        ``marking`` ``(B, places)`` (the clocks: the runtime's, after :meth:`reset` and :meth:`step`)."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        own = np.asarray(self._obs_of(x)) if self._obs_of is not None else x
        if self.n_clocks:
            clocks = np.minimum(self.runtime.obligation_clocks(), self._clock_high)
        else:
            clocks = np.zeros((x.shape[0], 0))
        M = np.atleast_2d(marking).astype(self._marking_dtype)
        if self.marking_obs == "box":
            own = own.reshape(x.shape[0], -1)
        return plant_observation(own, M, clocks, self.marking_obs)

    def reset(self, x0: np.ndarray) -> np.ndarray:
        self._k = 0
        return self.runtime.reset(np.atleast_2d(np.asarray(x0, dtype=float)))

    def act(self, x: np.ndarray, state: np.ndarray) -> np.ndarray:
        """The model's deterministic inputs ``(B,)``, asked one row at a time: the same numbers as in
        the environment (a batch goes through torch's matrix products, which round otherwise)."""
        obs = self.observation(x, state)
        B = np.atleast_2d(x).shape[0]
        u = np.empty(B)
        for b in range(B):
            row = obs[b : b + 1] if isinstance(obs, np.ndarray) else {k: v[b : b + 1] for k, v in obs.items()}
            action, _ = self.model.predict(row, deterministic=True)
            u[b] = float(np.asarray(action, dtype=float).reshape(-1)[0])
        return np.clip(u, -self.u_max, self.u_max)

    def step(self, state: np.ndarray, x_next: np.ndarray) -> np.ndarray:
        self._k += 1
        return self.runtime.step(
            np.atleast_2d(state), np.atleast_2d(np.asarray(x_next, dtype=float)), self._k * self.dt
        )

    def rollout(self, x0: np.ndarray) -> Any:
        """The model's rollouts from the starts ``x0`` ``(B, n)`` over the spec's horizon on the plant,
        as a :class:`mitlc.learn.sacpn.Rollout` (states, inputs, marking codes, the net's rewards, or
        the monitor's where it pays)."""
        from mitlc.learn.sacpn import Rollout

        x = np.array(np.atleast_2d(x0), dtype=float)
        B, N = x.shape[0], self.n_steps
        integrate = make_integrator(self.plant, self.params)
        states = np.empty((B, N + 1, x.shape[1]))
        actions = np.empty((B, N))
        codes = np.empty((B, N + 1), dtype=np.int64)
        rewards = np.empty((B, N))
        rt = self.runtime
        M = self.reset(x)
        paid: Any = None
        if self.reward_system.paid_by_monitor:
            paid = importlib.import_module("mitlc.monitor.rewards").TraceReward(
                self.spec, self.reward_system.options.reward, self.dt, self.plant.state_names
            )
            paid.reset(x)
        states[:, 0], codes[:, 0] = x, rt.encode(M)
        for k in range(N):
            u = self.act(x, M)
            integrate(x, u)
            M1 = self.step(M, x)
            rewards[:, k] = rt.reward(M, M1, x) if paid is None else paid.step(x, k == N - 1)
            M = M1
            states[:, k + 1], codes[:, k + 1], actions[:, k] = x, rt.encode(M), u
        return Rollout(states, actions, codes, rewards, self.dt)


SB3_EXTRA = "pip install 'mitlc[sb3]'"
"""How to install what loading a Stable-Baselines3 model needs."""


def sb3_algorithm(path: str | os.PathLike) -> Any:
    """The Stable-Baselines3 class (``SAC``, ``PPO``, ...) that saved the model ``path``, read off the
    policy class its ``.zip`` names (``sb3_contrib``'s too, where installed)."""
    where = os.fspath(path)
    try:
        with zipfile.ZipFile(where) as z:
            data = json.loads(z.read("data"))
        module = str(data["policy_class"]["__module__"])
    except (OSError, zipfile.BadZipFile, KeyError, TypeError, ValueError):
        raise InputError("not a Stable-Baselines3 model: a .zip that model.save() writes", file=where) from None
    package, _, rest = module.partition(".")
    kind = rest.split(".", 1)[0]
    try:
        lib = importlib.import_module(package)
    except ImportError:
        raise InputError(f"the model was saved by {package}, which is not installed", file=where) from None
    if kind == "common":  # the actor-critic policies PPO and A2C share: PPO's data has its clip range
        kind = "ppo" if "clip_range" in data else "a2c"
    for name in dir(lib):
        cls = getattr(lib, name)
        if isinstance(cls, type) and name.lower() == kind.replace("_", "") and hasattr(cls, "load"):
            return cls
    raise InputError(f"no algorithm of {package} saves policies of {module}", file=where)


def load_sb3(path: str | os.PathLike, spec: RewardSystem | Spec | str | os.PathLike, **kwargs: Any) -> Sb3Policy:
    """The Stable-Baselines3 model saved at ``path`` (``model.save(path)``) as an :class:`Sb3Policy` on
    ``spec`` (keywords go to it). Loading unpickles what the file holds, as SB3 does: load only
    models you trust. Needs ``pip install 'mitlc[sb3]'``."""
    where = os.fspath(path)
    try:
        import stable_baselines3  # noqa: F401 - PyTorch with it: seconds, once
    except ImportError:
        raise InputError(
            f"loading a Stable-Baselines3 model needs Stable-Baselines3: {SB3_EXTRA}", file=where
        ) from None
    if not os.path.isfile(where):
        raise InputError("no such file", file=where)
    algorithm = sb3_algorithm(where)
    try:
        model = algorithm.load(where, device="cpu")
    except Exception as exc:  # a damaged or foreign file: SB3 raises anything from pickle to torch
        raise InputError(f"cannot load it as a {algorithm.__name__} model: {exc}", file=where) from None
    return Sb3Policy(model, spec, **kwargs)


ENV_IDS = {"mitlc/Pendulum-v0": "pendulum", "mitlc/MassDamper-v0": "mass-damper"}
"""The registered environments of mitlc's own plants (registered when this module is imported)."""

for _env_id, _plant in ENV_IDS.items():
    if _env_id not in gym.registry:
        gym.register(id=_env_id, entry_point="mitlc.gym:MitlPlantEnv", kwargs={"plant": _plant})
