"""mitlc's plants as Gymnasium environments paying a spec's compiled reward: :class:`MitlPlantEnv`,
registered as ``mitlc/Pendulum-v0``, ``mitlc/MassDamper-v0`` and ``mitlc/Unicycle-v0``
(:data:`ENV_IDS`) when :mod:`mitlc.gym` is imported.
"""

from __future__ import annotations

import os
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mitlc.errors import InputError
from mitlc.gym.netenv import VERDICT, MitlNetEnv, reward_system_of
from mitlc.gym.observation import MARKING_OBS, plant_observation
from mitlc.petri.compile import RewardSystem
from mitlc.plants.base import PLANTS, make_integrator, wrap_angle
from mitlc.spec.model import Spec


class MitlPlantEnv(MitlNetEnv, gym.Env):
    """One of mitlc's plants as a Gymnasium environment that pays a spec's compiled reward.

    ``gymnasium.make("mitlc/Pendulum-v0", spec="pendulum/p2_avoid")`` (registered when
    :mod:`mitlc.gym` is imported; ``"mitlc.gym:mitlc/Pendulum-v0"`` imports it for you).
    ``spec`` is a :class:`RewardSystem`, a :class:`Spec`, a path or a shipped spec's name
    (default: the plant's default spec); its ``init`` box is the reset distribution (or
    ``reset(options={"x0": x})`` starts at ``x``), its ``horizon`` the episode length
    (truncated there). Observations are ``{"obs": x, "marking": M}`` (plus ``"clocks"`` with
    nested intervals), or one flat ``Box`` with ``marking_obs="box"``
    (:func:`plant_observation`); the action is the plant's inputs, a ``Box`` of ``m`` entries with
    each input's box (one entry in ``[-u_max, u_max]`` for a plant bounded by ``u_max``; the
    unicycle's ``[v, omega]`` in ``[-1, 1] x [-2, 2]``).

    ``info`` carries ``marking``, ``tau`` and the monitor's ``verdict`` as
    :class:`~mitlc.gym.MitlRewardWrapper`'s does, with the same ``verdict=`` option (``"step"``,
    ``"end"``, ``"off"``); a reward paid by the monitor (``sparse``, ``robustness``,
    ``robustness-window``) is paid by it here too. It is a :class:`MitlNetEnv` as the wrapper
    is: :class:`mitlc.gym.crm.CounterfactualReplayBuffer` takes it, and :class:`~mitlc.gym.Sb3Policy` rolls a
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
        rs = reward_system_of(spec)
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
        self.u_lo, self.u_hi = self.plant.input_box(self.params)
        """The inputs' boxes, ``(m,)`` each: the action space's bounds, and what an action is clipped to."""
        self.u_max = float(self.params["u_max"]) if "u_max" in self.params else None
        """The input bound of a plant bounded by ``u_max`` (None for one that declares its inputs)."""
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
        self.action_space = spaces.Box(
            self.u_lo.astype(np.float32), self.u_hi.astype(np.float32), (self.plant.n_inputs,), dtype=np.float32
        )
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
        m = self.plant.n_inputs
        a = np.asarray(action, dtype=float).reshape(-1)
        if m == 1:
            u = np.clip(a[:1], self.u_lo, self.u_hi)
        else:
            if a.shape != (m,):
                raise InputError(
                    f"the action has {a.size} entries; plant '{self.plant.name}' has {m} inputs "
                    f"({', '.join(self.plant.input_names)})"
                )
            u = np.clip(a, self.u_lo, self.u_hi)[None, :]
        self._integrate(self._x, u)
        truncated = self._k + 1 >= self.steps
        reward, info = self._net_step(self._x[0].tolist(), truncated)
        return self._obs(), reward, False, truncated, info


ENV_IDS = {"mitlc/Pendulum-v0": "pendulum", "mitlc/MassDamper-v0": "mass-damper", "mitlc/Unicycle-v0": "unicycle"}
"""The registered environments of mitlc's own plants (registered when this module is imported)."""

for _env_id, _plant in ENV_IDS.items():
    if _env_id not in gym.registry:
        gym.register(id=_env_id, entry_point="mitlc.gym.envs:MitlPlantEnv", kwargs={"plant": _plant})
