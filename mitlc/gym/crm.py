"""Counterfactual experience over markings for Stable-Baselines3's off-policy learners.

The Petri-net counterpart of counterfactual reasoning for reward machines (CRM, Toro Icarte et
al., JAIR 2022): a real transition ``(x, u, x')`` of the environment was taken with the net in
marking ``M``, but the same ``(x, u, x')`` would have been taken from every other marking the net
can be in at that state, and the net says where each of them goes and what it pays. A
:class:`CounterfactualReplayBuffer` stores, beside the real transition, the transition of every
such marking, so that SAC or TD3 learns the value of every marking from each step it takes.

Which markings: those that agree with the real one on the parts the state and the clock decide
(the region sub-nets, whose place is the region ``x`` lies in, and the timeline, whose place is
the clock's phase) and differ anywhere else (the formula's memory: done and recurrence places,
violation records). From each, the next marking and the reward are the net's own for ``x'`` at
the real clock (the environment's tables, :attr:`mitlc.gym.MitlNetEnv.marking_codes`). A
net with timed obligations (nested intervals) has no such tables and is refused, as is a
reward paid by the monitor (its value depends on the whole trace, not on the marking).

Use it with an environment of :mod:`mitlc.gym` (a :class:`~mitlc.gym.MitlNetEnv`: the
:class:`~mitlc.gym.MitlRewardWrapper` of any environment, or one of mitlc's plants registered
as ``mitlc/Pendulum-v0``, ``mitlc/MassDamper-v0``) with flat observations (``marking_obs="box"``:
the environment's observation, then the marking, then the clocks), and hand it to the buffer
(Gymnasium's wrappers around it, such as those ``gymnasium.make`` adds, are looked through)::

    env = MitlRewardWrapper(gym.make("Pendulum-v1"), "pendulum/p4_alternate", pendulum_v1_state,
                            marking_obs="box", verdict="off", truncate_at_horizon=True)
    # or: env = gym.make("mitlc/Pendulum-v0", spec="pendulum/p4_alternate", marking_obs="box")
    model = SAC("MlpPolicy", env, replay_buffer_class=CounterfactualReplayBuffer,
                replay_buffer_kwargs={"wrapper": env})

Needs ``pip install 'mitlc[sb3]'`` (Stable-Baselines3 and PyTorch).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from mitlc.errors import InputError

try:
    from stable_baselines3.common.buffers import ReplayBuffer
except ImportError as exc:  # pragma: no cover - the message names the extra
    raise ImportError("mitlc.gym.crm needs Stable-Baselines3: pip install 'mitlc[sb3]'") from exc

from mitlc.gym.netenv import MitlNetEnv

__all__ = ["CounterfactualReplayBuffer", "counterfactual_codes", "find_net_env"]


WHERE = "CounterfactualReplayBuffer(wrapper=)"
"""What the buffer's errors name: its ``wrapper=`` argument."""


def find_net_env(env: Any) -> MitlNetEnv:
    """The :class:`~mitlc.gym.MitlNetEnv` (a :class:`~mitlc.gym.MitlRewardWrapper` or
    :class:`~mitlc.gym.MitlPlantEnv`) in ``env``: ``env`` itself, or the one inside Gymnasium's
    wrappers (``TimeLimit``, ``OrderEnforcing``, ``PassiveEnvChecker`` that ``gymnasium.make`` adds)
    or a one-environment ``DummyVecEnv``."""
    seen = env
    for _ in range(100):  # a chain of wrappers, never a cycle
        if isinstance(seen, MitlNetEnv):
            return seen
        inner = getattr(seen, "envs", None)  # a vectorized environment of one
        if isinstance(inner, list) and len(inner) == 1:
            seen = inner[0]
        elif isinstance(seen, gym.Wrapper):
            seen = seen.env
        else:
            break
    raise InputError(
        "wrapper must be the environment the learner steps, a MitlRewardWrapper or a MitlPlantEnv "
        f"(gymnasium.make('mitlc/Pendulum-v0', ...)), or a Gymnasium wrapper of one; got {_describe(env)}",
        file=WHERE,
    )


def _describe(env: Any) -> str:
    """``TimeLimit<OrderEnforcing<CartPoleEnv>>``: the classes of a chain of wrappers."""
    names: list[str] = []
    seen = env
    while isinstance(seen, gym.Wrapper) and len(names) < 10:
        names.append(type(seen).__name__)
        seen = seen.env
    names.append(type(seen).__name__)
    return "<".join(names) + ">" * (len(names) - 1)


def counterfactual_codes(env: Any) -> dict[int, np.ndarray]:
    """For every marking code of the environment's net (a :class:`~mitlc.gym.MitlNetEnv`, or a
    Gymnasium wrapper of one), the other codes that agree with it on the region and timeline
    sub-nets (the markings the same state and clock allow)."""
    net_env = find_net_env(env)
    codes = net_env.marking_codes
    if codes is None:
        raise InputError(_untabulated(net_env), file=WHERE)
    marking_of = codes.markings
    fixed = [
        i
        for s in net_env.runtime.net.subnets
        if s.role in ("region", "timeline")
        for i in np.asarray(s.places, dtype=np.intp).tolist()
    ]
    keys = marking_of[:, fixed] if fixed else np.zeros((len(marking_of), 0), dtype=marking_of.dtype)
    groups: dict[bytes, list[int]] = {}
    for c, key in enumerate(keys):
        groups.setdefault(key.tobytes(), []).append(c)
    return {c: np.array([o for o in groups[k.tobytes()] if o != c], dtype=np.int64) for c, k in enumerate(keys)}


def _untabulated(env: MitlNetEnv) -> str:
    """Why a net has no marking codes to step one sample at a time."""
    rs = env.reward_system
    if rs.paid_by_monitor:
        return f"reward {rs.options.reward} is paid by the monitor: it has no value per marking"
    if rs.timed:
        return "counterfactual markings need the net tabulated without timed obligations (nested intervals)"
    if env.runtime.counters.size:
        return "counterfactual markings need a net without counting places (violations = counted)"
    return "counterfactual markings need the net tabulated: this one is too large for its tables"


class CounterfactualReplayBuffer(ReplayBuffer):
    """A :class:`stable_baselines3.common.buffers.ReplayBuffer` that adds, with each real
    transition, the transition of every counterfactual marking (module text). ``wrapper`` is
    the environment the learner steps, with ``marking_obs="box"``: a
    :class:`~mitlc.gym.MitlRewardWrapper`, a :class:`~mitlc.gym.MitlPlantEnv` (``gymnasium.make(
    "mitlc/Pendulum-v0", ...)``), or Gymnasium's wrappers of one; the other arguments are the
    buffer's own. :attr:`added` counts the counterfactual transitions stored.
    """

    def __init__(
        self,
        buffer_size: int,
        observation_space: Any,
        action_space: Any,
        device: Any = "auto",
        n_envs: int = 1,
        optimize_memory_usage: bool = False,
        handle_timeout_termination: bool = True,
        *,
        wrapper: Any,
    ) -> None:
        env = find_net_env(wrapper)
        if env.marking_obs != "box":
            raise InputError(
                "counterfactual markings need the environment's flat observations: marking_obs='box'", file=WHERE
            )
        if env.reward_system.paid_by_monitor or env.marking_codes is None:
            raise InputError(_untabulated(env), file=WHERE)
        codes = env.marking_codes
        if n_envs != 1:
            raise InputError(
                f"counterfactual markings are added for one environment (n_envs=1), got n_envs={n_envs}", file=WHERE
            )
        if optimize_memory_usage:
            raise InputError(
                "counterfactual markings need optimize_memory_usage=False (next observations are stored)", file=WHERE
            )
        super().__init__(
            buffer_size,
            observation_space,
            action_space,
            device=device,
            n_envs=n_envs,
            optimize_memory_usage=optimize_memory_usage,
            handle_timeout_termination=handle_timeout_termination,
        )
        self.wrapper = env
        self._step1 = codes.step
        self._reward_of: np.ndarray = codes.rewards
        self._marking_of: np.ndarray = codes.markings
        self._others = counterfactual_codes(env)
        self._base_dim = env.marking_offset
        self._n_places = len(env.place_names)
        self._code_of = {m.tobytes(): c for c, m in enumerate(np.asarray(self._marking_of, dtype=np.int64))}
        self.added = 0

    def add(
        self,
        obs: np.ndarray,
        next_obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        super().add(obs, next_obs, action, reward, done, infos)
        b, p = self._base_dim, self._n_places
        for i in range(1):  # one environment (checked in __init__)
            m = np.asarray(np.rint(obs[i, b : b + p]), dtype=np.int64)
            code = self._code_of.get(m.tobytes())
            others = self._others.get(code, ()) if code is not None else ()
            if not len(others):
                continue
            x_next = self.wrapper.flat_state(next_obs[i, :b]).tolist()
            tau = float(infos[i]["tau"])
            for c in others:
                c = int(c)
                c1 = self._step1(c, x_next, tau)
                o, o1 = obs[i : i + 1].copy(), next_obs[i : i + 1].copy()
                o[0, b : b + p] = self._marking_of[c]
                o1[0, b : b + p] = self._marking_of[c1]
                r = np.array([self._reward_of[c, c1]], dtype=np.float32)
                super().add(o, o1, action[i : i + 1], r, done[i : i + 1], [infos[i]])
                self.added += 1
