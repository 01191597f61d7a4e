"""Any Gymnasium environment paying a compiled reward: :class:`MitlRewardWrapper`.

:class:`MitlRewardWrapper` steps the reward net (one :class:`~mitlc.runtime.NetRuntime`
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

The spec's state variables are read off each observation by ``observe``:
a function ``obs -> {variable: value}`` such as :func:`~mitlc.gym.pendulum_v1_state`, or a
dict mapping each variable to an index into the flattened observation or to a
function ``obs -> float``.  The clock is ``tau_k = k * dt``, with ``dt`` the
environment's ``dt`` attribute (``Pendulum-v1``: 0.05 s) unless given, else the
spec plant's ``dt``.

>>> import gymnasium as gym
>>> from mitlc.gym import pendulum_v1_state
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

import math
import os
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mitlc.errors import InputError
from mitlc.gym.netenv import VERDICT, MitlNetEnv, reward_system_of
from mitlc.gym.observation import MARKING_OBS, Observe, spec_observe, state_reader
from mitlc.petri.compile import RewardSystem
from mitlc.plants.gym_env import MAX_RESETS, env_dt, outside_init
from mitlc.spec.model import Spec


def _positive_dt(value: Any, where: str) -> float:
    try:
        dt = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{where} must be a number of seconds, got {value!r}") from None
    if not (math.isfinite(dt) and dt > 0):
        raise InputError(f"{where} must be positive and finite, got {dt}")
    return dt


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
        rs = reward_system_of(spec)
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
        # an observation {"obs", "marking"} with the marking as it is (int8) and no clocks: built in step itself
        self._dict_rows = marking_obs == "dict" and self._marking_dtype == np.int8 and not self.n_clocks
        self.horizon = s.horizon if truncate_at_horizon else None
        if truncate_at_horizon and self.horizon is None:
            raise InputError("truncate_at_horizon=True but the spec has no horizon")

        if observe is None:
            if spec_plant is None or not spec_plant.stepped:
                raise InputError(
                    "observe= is needed: how to read the spec's state variables off an observation "
                    "(or a spec whose plant is gym:ID with 'state' lines)"
                )
            observe = spec_observe(spec_plant, base)
        self._periodic = np.array(
            [spec_plant is not None and spec_plant.var(n).periodic for n in self.state_names],
            dtype=bool,
        )
        self._read = state_reader(observe, base, self.state_names, self._needed, self._periodic)
        self._samples_checked = True  # the reader gives a value per column, every needed one finite
        # a gym:ID spec's init is a condition on the environment's starts (a reset outside is
        # redone); another plant's init describes that plant's starts, which an environment
        # cannot be put in (a point such as q = pi is never drawn): the env starts as it does
        own = spec_plant is not None and spec_plant.stepped
        self._init = [
            (self.state_names.index(r.var), r.lo, r.hi) for r in (s.init if own else ()) if r.var in self.state_names
        ]

    @property
    def horizon(self) -> float | None:
        """The clock at which a step truncates the episode (``truncate_at_horizon``), or None."""
        return self._horizon

    @horizon.setter
    def horizon(self, value: float | None) -> None:
        self._horizon = value
        # from this clock on a step truncates: the horizon, give or take 1e-9 relative
        self._truncate_at = None if value is None else value - 1e-9 * max(1.0, value)

    # ------------------------------------------------------------ observation -> state
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
        return not self._init or not bool(outside_init(x[None, :], self._init)[0])

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, env_reward, terminated, truncated, info = self.env.step(action)
        xs = self._read(obs)
        if self._truncate_at is not None and (self._k + 1) * self.dt >= self._truncate_at:
            truncated = True
        terminated, truncated = bool(terminated), bool(truncated)
        info = dict(info)
        info["env_reward"] = env_reward
        reward, info = self._net_step(xs, terminated or truncated, info)
        if self._dict_rows:  # the marking a row of the net's table, no clocks: the observation at once, its
            # marking the array info["marking"] holds (a copy of the table's row, made once a step)
            return {"obs": obs, "marking": info["marking"]}, reward, terminated, truncated, info
        return self._observation(obs), reward, terminated, truncated, info

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
