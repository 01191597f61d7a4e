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
the real clock (the wrapper's tables, :meth:`mitlc.learn.runtime.NetRuntime.sample_stepper`). A
net with timed obligations (nested intervals) has no such tables and is refused, as is a
reward paid by the monitor (its value depends on the whole trace, not on the marking).

Use it with the wrapper's flat observations (``marking_obs="box"``: the environment's
observation, then the marking, then the clocks) and hand the wrapper to the buffer::

    env = MitlRewardWrapper(gym.make("Pendulum-v1"), "pendulum/p4_alternate", pendulum_v1_state,
                            marking_obs="box", verdict="off", truncate_at_horizon=True)
    model = SAC("MlpPolicy", env, replay_buffer_class=CounterfactualReplayBuffer,
                replay_buffer_kwargs={"wrapper": env})

Needs ``pip install 'mitlc[sb3]'`` (Stable-Baselines3 and PyTorch).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from mitlc.errors import InputError

try:
    from stable_baselines3.common.buffers import ReplayBuffer
except ImportError as exc:  # pragma: no cover - the message names the extra
    raise ImportError("mitlc.crm needs Stable-Baselines3: pip install 'mitlc[sb3]'") from exc

from mitlc.gym import MitlRewardWrapper

__all__ = ["CounterfactualReplayBuffer", "counterfactual_codes"]


def counterfactual_codes(wrapper: MitlRewardWrapper) -> dict[int, np.ndarray]:
    """For every marking code of the wrapper's net, the other codes that agree with it on the
    region and timeline sub-nets (the markings the same state and clock allow)."""
    rt = wrapper.runtime
    marking_of = wrapper._marking_of  # noqa: SLF001 - the wrapper's code -> marking table
    assert marking_of is not None
    fixed = [
        i
        for s in rt.net.subnets
        if s.role in ("region", "timeline")
        for i in np.asarray(s.places, dtype=np.intp).tolist()
    ]
    keys = marking_of[:, fixed] if fixed else np.zeros((len(marking_of), 0), dtype=marking_of.dtype)
    groups: dict[bytes, list[int]] = {}
    for c, key in enumerate(keys):
        groups.setdefault(key.tobytes(), []).append(c)
    return {c: np.array([o for o in groups[k.tobytes()] if o != c], dtype=np.int64) for c, k in enumerate(keys)}


class CounterfactualReplayBuffer(ReplayBuffer):
    """A :class:`stable_baselines3.common.buffers.ReplayBuffer` that adds, with each real
    transition, the transition of every counterfactual marking (module text). ``wrapper`` is
    the :class:`~mitlc.gym.MitlRewardWrapper` the learner steps (``marking_obs="box"``); the other
    arguments are the buffer's own. :attr:`added` counts the counterfactual transitions stored.
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
        wrapper: MitlRewardWrapper,
    ) -> None:
        if not isinstance(wrapper, MitlRewardWrapper):
            raise InputError(f"wrapper must be the MitlRewardWrapper the learner steps, got {type(wrapper).__name__}")
        if wrapper.marking_obs != "box":
            raise InputError("counterfactual markings need the wrapper's flat observations: marking_obs='box'")
        base = wrapper.env.observation_space
        if not isinstance(base, spaces.Box) or len(base.shape) != 1:
            raise InputError(f"counterfactual markings need an environment with flat Box observations, got {base}")
        if wrapper.reward_system.paid_by_monitor:
            raise InputError(
                f"reward {wrapper.reward_system.options.reward} is paid by the monitor: it has no value per marking"
            )
        step1 = wrapper._step1  # noqa: SLF001 - the wrapper's one-sample step on the tables
        if step1 is None:
            raise InputError(
                "counterfactual markings need the net tabulated without timed obligations (nested intervals)"
            )
        if n_envs != 1:
            raise InputError(f"counterfactual markings are added for one environment (n_envs=1), got n_envs={n_envs}")
        if optimize_memory_usage:
            raise InputError("counterfactual markings need optimize_memory_usage=False (next observations are stored)")
        super().__init__(
            buffer_size,
            observation_space,
            action_space,
            device=device,
            n_envs=n_envs,
            optimize_memory_usage=optimize_memory_usage,
            handle_timeout_termination=handle_timeout_termination,
        )
        self.wrapper = wrapper
        self._step1 = step1
        self._reward_of: np.ndarray = wrapper._reward_of  # noqa: SLF001
        assert wrapper._marking_of is not None  # noqa: SLF001 - a tabulated net (step1 is not None)
        self._marking_of: np.ndarray = wrapper._marking_of  # noqa: SLF001
        self._others = counterfactual_codes(wrapper)
        self._base_dim = int(spaces.flatdim(base))
        self._n_places = len(wrapper.place_names)
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
            x_next = self.wrapper.state(next_obs[i, :b]).tolist()
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
