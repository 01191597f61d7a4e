"""Stable-Baselines3 models as mitlc policies: :class:`Sb3Policy` rolls a model trained on a
:mod:`mitlc.gym` environment out on the spec's plant, judged as a trained SACPN policy is
(``mitlc simulate --policy model.zip``); :func:`load_sb3` loads a saved one.

Stable-Baselines3 (and PyTorch) are imported only when a model is loaded: ``pip install 'mitlc[sb3]'``.
"""

from __future__ import annotations

import importlib
import json
import os
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from mitlc.errors import InputError
from mitlc.gym.netenv import reward_system_of
from mitlc.gym.observation import clock_high, n_clocks, plant_observation, token_bounds
from mitlc.learn.policy import Policy
from mitlc.petri.compile import RewardSystem
from mitlc.plants.base import PLANTS, Plant, make_integrator
from mitlc.runtime import NetRuntime
from mitlc.spec.model import Spec


@dataclass(frozen=True)
class PlantEpisode:
    """What an episode on one of mitlc's own plants needs from a spec (:func:`plant_episode`)."""

    plant: Plant
    params: dict[str, float]
    dt: float
    n_steps: int
    """The horizon in steps of ``dt``."""
    init_ranges: list[tuple[float, float]]
    """The spec's ``init`` box, ``(lo, hi)`` per state variable (0 where it says nothing)."""


def plant_episode(s: Spec, refusal: str, length: str) -> PlantEpisode:
    """The plant, its parameters, step, horizon in steps and ``init`` box of a spec on one of mitlc's
    plants, which SB3 models train and roll out on; a spec that names no plant or a Gymnasium
    environment is refused with ``refusal`` (``{plants}``: the plants' names), one with no horizon
    says it is ``length``."""
    plant = s.plant
    if plant is None or plant.stepped or s.plant_name not in PLANTS:
        what = "names no plant" if plant is None else f"is for plant {s.plant_name}, a Gymnasium environment"
        raise InputError(f"the spec {what}: " + refusal.format(plants=", ".join(sorted(PLANTS))), file=s.path)
    if s.horizon is None:
        raise InputError(f"the spec has no 'horizon': {length}", file=s.path)
    own = PLANTS[s.plant_name]
    params = own.params(dict(s.plant_params))
    dt = float(params["dt"])
    init = {r.var: (r.lo, r.hi) for r in s.init}
    return PlantEpisode(
        plant=own,
        params=params,
        dt=dt,
        n_steps=max(1, int(round(s.horizon / dt))),
        init_ranges=[init.get(v, (0.0, 0.0)) for v in own.state_names],
    )


class Sb3Policy(Policy):
    """A Stable-Baselines3 model as a :class:`mitlc.learn.policy.Policy` on a spec's plant, so that it
    is rolled out and judged as a trained SACPN policy is (``mitlc simulate --policy model.zip``).

    ``model`` was trained on a :class:`~mitlc.gym.MitlPlantEnv` of the spec (``gymnasium.make(
    "mitlc/Pendulum-v0", spec=...)``, either ``marking_obs``), or on a
    :class:`~mitlc.gym.MitlRewardWrapper` whose environment observes ``obs_of(x)``: a function of
    the plant's states ``(B, n) -> (B, ...)``, by default the states themselves, as
    :class:`~mitlc.gym.MitlPlantEnv` shows them. Its state is the reward net's marking
    ``(B, places)``, as for SACPN; :meth:`act` builds the observation the environment would give
    from ``x``, the marking and the obligations' clocks, and asks the model for its
    deterministic action, clipped to the inputs' boxes (``[-u_max, u_max]`` for a plant with one
    input bounded by ``u_max``). One model: ``runs`` is 1.
    """

    def __init__(
        self,
        model: Any,
        spec: RewardSystem | Spec | str | os.PathLike,
        obs_of: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        rs = reward_system_of(spec)
        s = rs.spec
        ep = plant_episode(
            s,
            "an SB3 model is rolled out on one of mitlc's plants ({plants}); judge it on a Gymnasium environment "
            "with MitlRewardWrapper's info['verdict']",
            "the rollouts' length",
        )
        self.model, self.reward_system, self.spec, self.runs = model, rs, s, 1
        self.plant, self.params, self.dt, self.n_steps = ep.plant, ep.params, ep.dt, ep.n_steps
        self.u_lo, self.u_hi = self.plant.input_box(self.params)
        self.u_max = float(self.params["u_max"]) if "u_max" in self.params else None
        self.init_ranges = ep.init_ranges
        """The spec's ``init`` box, ``(lo, hi)`` per state variable (0 where it says nothing)."""
        self.runtime = NetRuntime(rs, self.plant.state_names, dt=self.dt, steps=self.n_steps)
        self.place_names = rs.net.place_names
        self._obs_of = obs_of
        bounds = token_bounds(rs)
        self._marking_dtype = np.int8 if bool(np.all(bounds == 1)) else np.int64
        self.n_clocks = n_clocks(rs)
        self._clock_high = clock_high(rs)
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
        """The model's deterministic inputs ``(B,)`` (``(B, m)`` for a plant with ``m > 1`` inputs),
        asked one row at a time: the same numbers as in the environment (a batch goes through
        torch's matrix products, which round otherwise)."""
        obs = self.observation(x, state)
        B, m = np.atleast_2d(x).shape[0], self.plant.n_inputs
        u = np.empty((B, m))
        for b in range(B):
            row = obs[b : b + 1] if isinstance(obs, np.ndarray) else {k: v[b : b + 1] for k, v in obs.items()}
            action, _ = self.model.predict(row, deterministic=True)
            a = np.asarray(action, dtype=float).reshape(-1)
            if a.size < m:
                raise InputError(
                    f"the model's action has {a.size} entries; plant '{self.plant.name}' has {m} inputs "
                    f"({', '.join(self.plant.input_names)})",
                    file=self.spec.path,
                )
            u[b] = a[:m]
        u = np.clip(u, self.u_lo, self.u_hi)
        return u[:, 0] if m == 1 else u

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
        actions = np.empty((B, N) if self.plant.n_inputs == 1 else (B, N, self.plant.n_inputs))
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
