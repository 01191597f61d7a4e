"""Numpy twins of Gymnasium's continuous classic-control environments: all copies stepped at once.

A trainer steps ``B`` copies of an environment through Gymnasium's synchronous vector API, one
Python ``step`` per copy: 24 us a copy-step for ``Pendulum-v1`` and 7 us for
``MountainCarContinuous-v0`` on the machine of docs/suite.md, which makes a policy search that rolls
out a thousand copies a generation cost seconds a generation. A twin steps every copy in a handful
of numpy operations and gives **the same observations and terminations, to the bit**, as the
environment's own ``step`` (its float32 and float64 arithmetic reproduced, NumPy 2's promotion rules
included): the environment still resets its copies (its own random starts, seeds and ``init``
rejection as before), and the twin reads their states after each reset.

A twin is used only after :func:`twin_for` has checked it against a fresh instance of the environment
(every observation and termination of a few hundred steps from several seeded starts, with actions
inside, on and beyond the action's bounds): a Gymnasium release whose dynamics differ, or an
environment registered under the id with other code, is stepped through Gymnasium as before.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["TWINS", "Twin", "PendulumTwin", "MountainCarTwin", "twin_for", "agrees", "compare"]


def _identity(f: Callable) -> Callable:
    return f


class Twin:
    """``B`` copies of one environment as arrays: :meth:`load` reads the copies' states after a reset
    (rows where ``mask`` is true), :meth:`step` applies actions ``(B, 1)`` and returns the observations
    ``(B, k)`` (float32, as the environment's) and the terminations ``(B,)``."""

    module = ""
    cls = ""

    def __init__(self, env: Any, B: int) -> None:
        self.B = B

    @classmethod
    def fits(cls, env: Any) -> bool:
        """Whether ``env`` (unwrapped) is the environment this twin reproduces."""
        return type(env).__module__ == cls.module and type(env).__name__ == cls.cls

    def load(self, envs: Sequence[Any], mask: np.ndarray | None = None) -> None:
        raise NotImplementedError

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def kernel_physics(self, jit: Callable = _identity) -> tuple[Callable, np.ndarray, int, int] | None:
        """One copy's step for SACPN's fused kernel, as plain Python (compiled by the kernel's jit, which
        compiles the functions it calls), or None where the twin has none: ``(physics, consts, h, k)``.
        ``physics(s, a, c, o)`` steps the copy's hidden state ``s`` (``h`` numbers: :meth:`hidden`) by
        the action ``a`` (the float32 the vector environment is given) with the constants ``c``, writes
        the float64 of its float32 observation (``k`` entries) into ``o`` and returns True: the numbers
        of :meth:`step`, to the bit. A copy whose episode has ended (a termination) is not stepped
        again: it returns False, and the trainer keeps the copy's last state
        (:class:`~mitlc.plants.gym_env.GymSimulator`)."""
        return None

    def hidden(self) -> np.ndarray:
        """The copies' states as :meth:`kernel_physics` steps them, ``(B, h)`` (after :meth:`load`)."""
        raise NotImplementedError


class PendulumTwin(Twin):
    """``Pendulum-v1`` (gymnasium.envs.classic_control.pendulum): the state ``(th, thdot)`` in
    float64, the torque clipped in float32, the observation ``(cos th, sin th, thdot)`` in float32."""

    module, cls = "gymnasium.envs.classic_control.pendulum", "PendulumEnv"

    def __init__(self, env: Any, B: int) -> None:
        super().__init__(env, B)
        g, m, l = env.g, env.m, env.l  # noqa: E741 (the environment's names)
        self.c_sin = 3 * g / (2 * l)  # Python arithmetic, as the environment's
        self.c_u = 3.0 / (m * l**2)
        self.dt, self.max_speed, self.max_torque = env.dt, env.max_speed, env.max_torque
        self.th = np.zeros(B)
        self.thdot = np.zeros(B)

    def load(self, envs: Sequence[Any], mask: np.ndarray | None = None) -> None:
        for b, e in enumerate(envs):
            if mask is None or mask[b]:
                s = e.unwrapped.state
                self.th[b], self.thdot[b] = s[0], s[1]

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u = np.clip(action[:, 0], -self.max_torque, self.max_torque)  # the action's dtype, as np.clip on it
        newthdot = self.thdot + (self.c_sin * np.sin(self.th) + self.c_u * u) * self.dt
        newthdot = np.clip(newthdot, -self.max_speed, self.max_speed)
        self.th = self.th + newthdot * self.dt
        self.thdot = newthdot
        obs = np.empty((self.B, 3), dtype=np.float32)
        obs[:, 0], obs[:, 1], obs[:, 2] = np.cos(self.th), np.sin(self.th), self.thdot
        return obs, np.zeros(self.B, dtype=bool)

    def kernel_physics(self, jit: Callable = _identity) -> tuple[Callable, np.ndarray, int, int]:
        consts = np.array([self.max_torque, self.c_sin, self.c_u, self.dt, self.max_speed])

        def physics(s: np.ndarray, a: Any, c: np.ndarray, o: np.ndarray) -> bool:
            """:meth:`step` for one copy: ``s = (th, thdot)``; the torque clipped and scaled in float32
            (NumPy 2's rule for a Python float beside a float32), the rest in float64. It never ends."""
            bound = np.float32(c[0])
            torque = np.minimum(np.maximum(a, -bound), bound)
            push = np.float32(c[2]) * torque
            thdot = s[1] + (c[1] * np.sin(s[0]) + np.float64(push)) * c[3]
            thdot = np.minimum(np.maximum(thdot, -c[4]), c[4])
            s[0] = s[0] + thdot * c[3]
            s[1] = thdot
            o[0] = np.float64(np.float32(np.cos(s[0])))
            o[1] = np.float64(np.float32(np.sin(s[0])))
            o[2] = np.float64(np.float32(thdot))
            return True

        return physics, consts, 2, 3

    def hidden(self) -> np.ndarray:
        return np.stack([self.th, self.thdot], axis=1)


class MountainCarTwin(Twin):
    """``MountainCarContinuous-v0`` (gymnasium.envs.classic_control.continuous_mountain_car).

    The environment keeps its state in float64 after a reset and in float32 after a step, and its
    step mixes NumPy scalars with Python floats: a float32 force times the power is a float32
    product, a Python float beside a float32 is rounded to float32 first (NumPy 2's promotion), the
    cosine is ``math.cos`` of a double. A copy's first step after a reset is computed in float64,
    every later one in float32, with the same rules; the state is stored as float32 after each."""

    module, cls = "gymnasium.envs.classic_control.continuous_mountain_car", "Continuous_MountainCarEnv"

    def __init__(self, env: Any, B: int) -> None:
        super().__init__(env, B)
        self.e = env
        self.pos = np.zeros(B)
        self.vel = np.zeros(B)
        self.fresh = np.ones(B, dtype=bool)  # the state is float64 (just reset)

    def load(self, envs: Sequence[Any], mask: np.ndarray | None = None) -> None:
        for b, e in enumerate(envs):
            if mask is None or mask[b]:
                s = e.unwrapped.state
                self.pos[b], self.vel[b] = s[0], s[1]
                self.fresh[b] = np.asarray(s).dtype == np.float64

    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = np.asarray(action)[:, 0]
        obs = np.empty((self.B, 2), dtype=np.float32)
        term = np.zeros(self.B, dtype=bool)
        for fresh in (True, False):
            rows = np.flatnonzero(self.fresh == fresh)
            if rows.size:
                p, v, t = self._step(a[rows], self.pos[rows], self.vel[rows], np.float64 if fresh else np.float32)
                obs[rows, 0], obs[rows, 1], term[rows] = p, v, t
        self.pos[:] = obs[:, 0]
        self.vel[:] = obs[:, 1]
        self.fresh[:] = False
        return obs, term

    def kernel_physics(self, jit: Callable = _identity) -> tuple[Callable, np.ndarray, int, int] | None:
        e = self.e
        if np.dtype(e.action_space.dtype) != np.float32:  # the rules below are a float32 action's
            return None
        consts = np.array(
            [e.min_action, e.max_action, e.power, e.max_speed, e.min_position, e.max_position]
            + [e.goal_position, e.goal_velocity]
        )
        step64, step32 = jit(_mountain_car_float64), jit(_mountain_car_float32)

        def physics(s: np.ndarray, a: Any, c: np.ndarray, o: np.ndarray) -> bool:
            """:meth:`step` for one copy: ``s = (pos, vel, fresh, ended)``; the first step after a reset
            in float64, every later one in float32 (:meth:`_step`'s rules, one number at a time)."""
            if s[3] != 0.0:
                return False
            if s[2] != 0.0:
                pos, vel, end = step64(s[0], s[1], a, c)
            else:
                pos, vel, end = step32(s[0], s[1], a, c)
            s[0], s[1], s[2], s[3] = pos, vel, 0.0, 1.0 if end else 0.0
            o[0], o[1] = pos, vel
            return True

        return physics, consts, 4, 2

    def hidden(self) -> np.ndarray:
        return np.stack([self.pos, self.vel, self.fresh.astype(float), np.zeros(self.B)], axis=1)

    def _step(self, a: np.ndarray, pos: np.ndarray, vel: np.ndarray, T: Any) -> tuple[np.ndarray, ...]:
        """One step of copies whose state has dtype ``T``; ``a`` is the action's first entry."""
        e = self.e
        pos, vel = pos.astype(T), vel.astype(T)
        # force = min(max(a, min_action), max_action): a clipped force is the Python float bound
        lo, hi = a < e.min_action, a > e.max_action
        bound = lo | hi
        f_bound = np.where(lo, e.min_action * e.power, e.max_action * e.power)  # Python floats: double
        f_own = (a * e.power).astype(np.float64)  # the action's dtype times a Python float: that dtype
        arg = 3 * pos  # a NumPy scalar of dtype T times 3
        # the environment's math.cos of a double: numpy's float64 cosine gives libm's numbers here (4 million
        # draws compared); where a build's did not, the cosine goes through float32 rounding (f32(c)) before
        # it reaches the state, and the check of twin_for stands behind it
        c = 0.0025 * np.cos(arg.astype(np.float64))
        if a.dtype == np.float64:
            d_own = f_own - c
        else:  # a float32 force minus a Python float: in the force's dtype
            d_own = (f_own.astype(a.dtype) - c.astype(a.dtype)).astype(np.float64)
        delta = np.where(bound, f_bound - c, d_own)
        if T is np.float64:
            vel = vel + delta
        else:  # a float32 velocity plus a double (or Python float): rounded to float32 first
            vel = vel + delta.astype(np.float32)
        fast, slow = vel > T(e.max_speed), vel < T(-e.max_speed)
        v_set = np.where(fast, e.max_speed, np.where(slow, -e.max_speed, 0.0))  # Python floats where clipped
        clipped_v = fast | slow
        vel = np.where(clipped_v, v_set.astype(T), vel)
        pos = pos + vel
        over, under = pos > T(e.max_position), pos < T(e.min_position)
        pos = np.where(over, T(e.max_position), np.where(under, T(e.min_position), pos))
        wall = (pos == T(e.min_position)) & np.where(clipped_v, v_set < 0, vel < 0)
        vel = np.where(wall, T(0), vel)
        # terminated: position >= goal_position and velocity >= goal_velocity, each compared in the
        # dtype of the value it has (a Python float where it was clipped)
        at_goal = np.where(over, e.max_position >= e.goal_position, pos >= T(e.goal_position))
        v_own = np.where(clipped_v, v_set >= e.goal_velocity, vel >= T(e.goal_velocity))
        v_ok = np.where(wall, e.goal_velocity <= 0, v_own)
        return pos.astype(np.float32), vel.astype(np.float32), at_goal & v_ok


def _mountain_car_float64(pos: float, vel: float, a: Any, c: np.ndarray) -> tuple[float, float, bool]:
    """One step of :meth:`MountainCarTwin._step` from a float64 state (just reset), for one copy: ``a`` the
    float32 action, ``c`` the constants of :meth:`MountainCarTwin.kernel_physics`. The new position and
    velocity (float32 values) and whether the episode terminated."""
    bound = a < np.float32(c[0]) or a > np.float32(c[1])
    cosine = 0.0025 * np.cos(3.0 * pos)
    if bound:
        delta = (c[0] * c[2] if a < np.float32(c[0]) else c[1] * c[2]) - cosine
    else:  # a float32 force less a double in float32 (a Python float beside a float32)
        delta = np.float64(np.float32(a * np.float32(c[2])) - np.float32(cosine))
    vel = vel + delta
    fast, slow = vel > c[3], vel < -c[3]
    clipped = fast or slow
    v_set = c[3] if fast else -c[3] if slow else 0.0
    if clipped:
        vel = v_set
    pos = pos + vel
    over = pos > c[5]
    if over:
        pos = c[5]
    elif pos < c[4]:
        pos = c[4]
    wall = pos == c[4] and ((v_set < 0.0) if clipped else (vel < 0.0))
    if wall:
        vel = 0.0
    at_goal = (c[5] >= c[6]) if over else (pos >= c[6])
    v_ok = (c[7] <= 0.0) if wall else ((v_set >= c[7]) if clipped else (vel >= c[7]))
    return np.float64(np.float32(pos)), np.float64(np.float32(vel)), at_goal and v_ok


def _mountain_car_float32(pos: float, vel: float, a: Any, c: np.ndarray) -> tuple[float, float, bool]:
    """:func:`_mountain_car_float64` from a float32 state (every step after the first): the state's
    arithmetic and comparisons in float32, the environment's Python floats where it clips."""
    p, v = np.float32(pos), np.float32(vel)
    bound = a < np.float32(c[0]) or a > np.float32(c[1])
    cosine = 0.0025 * np.cos(np.float64(np.float32(3.0) * p))
    if bound:
        delta = (c[0] * c[2] if a < np.float32(c[0]) else c[1] * c[2]) - cosine
    else:
        delta = np.float64(np.float32(a * np.float32(c[2])) - np.float32(cosine))
    v = v + np.float32(delta)
    fast, slow = v > np.float32(c[3]), v < np.float32(-c[3])
    clipped = fast or slow
    v_set = c[3] if fast else -c[3] if slow else 0.0
    if clipped:
        v = np.float32(v_set)
    p = p + v
    over = p > np.float32(c[5])
    if over:
        p = np.float32(c[5])
    elif p < np.float32(c[4]):
        p = np.float32(c[4])
    wall = p == np.float32(c[4]) and ((v_set < 0.0) if clipped else (v < np.float32(0.0)))
    if wall:
        v = np.float32(0.0)
    at_goal = (c[5] >= c[6]) if over else (p >= np.float32(c[6]))
    v_ok = (c[7] <= 0.0) if wall else ((v_set >= c[7]) if clipped else (v >= np.float32(c[7])))
    return np.float64(p), np.float64(v), at_goal and v_ok


TWINS: dict[str, type[Twin]] = {"Pendulum-v1": PendulumTwin, "MountainCarContinuous-v0": MountainCarTwin}
"""The environments with a twin, by Gymnasium id."""

_CHECKED: dict[tuple[str, tuple[tuple[str, Any], ...]], bool] = {}


def agrees(env_id: str, kwargs: Mapping[str, Any], steps: int = 300, copies: int = 6) -> bool:
    """Whether the twin of ``env_id`` gives the environment's own observations and terminations, to
    the bit, over ``steps`` steps of ``copies`` seeded copies (:func:`compare`)."""
    return compare(env_id, kwargs, steps, copies)[0]


def compare(env_id: str, kwargs: Mapping[str, Any], steps: int = 300, copies: int = 6) -> tuple[bool, int]:
    """Step ``copies`` seeded copies of ``env_id`` and its twin side by side for ``steps`` steps: whether
    every observation and termination is the same to the bit, and how many terminations there were.

    Copy ``b`` acts by ``b % 3``: uniform actions over 1.5 times the action's box; pumping (the bound
    in the direction of the last observation entry, a velocity in both environments, at 1 or 1.2 times
    it), which reaches the mountain car's goal and the pendulum's speed limit; or pushing against the
    lower bound (the mountain car's wall), every seventh step on the upper one. A copy that terminates
    is reset with a new seed, and the twin reads its new state."""
    import gymnasium as gym

    twin_cls = TWINS.get(env_id)
    if twin_cls is None:
        return False, 0
    envs = [gym.make(env_id, disable_env_checker=True, max_episode_steps=10**9, **kwargs) for _ in range(copies)]
    try:
        if not twin_cls.fits(envs[0].unwrapped):
            return False, 0
        space: Any = envs[0].action_space
        low: np.ndarray = np.asarray(space.low, dtype=np.float64)
        high: np.ndarray = np.asarray(space.high, dtype=np.float64)
        shape: tuple[int, ...] = tuple(space.shape)
        rng = np.random.default_rng(20261207)
        last = np.stack([np.asarray(env.reset(seed=b)[0], dtype=float).ravel() for b, env in enumerate(envs)])
        twin = twin_cls(envs[0].unwrapped, copies)
        twin.load(envs)
        ends = 0
        for k in range(steps):
            a = rng.uniform(1.5 * low, 1.5 * high, size=(copies, *shape))
            pump = np.where(last[:, -1] >= 0, high[0], low[0]) * (1.2 if k % 2 else 1.0)
            push = np.full(copies, high[0] if k % 7 == 0 else low[0])
            kind = np.arange(copies) % 3
            a[:, 0] = np.where(kind == 1, pump, np.where(kind == 2, push, a[:, 0]))
            a = a.astype(space.dtype)
            obs, term = twin.step(a)
            for b, env in enumerate(envs):
                o, _, t, _, _ = env.step(a[b])
                if not (np.array_equal(np.asarray(o, dtype=np.float32), obs[b]) and bool(t) == bool(term[b])):
                    return False, ends
                last[b] = np.asarray(o, dtype=float).ravel()
                if t:
                    ends += 1
                    last[b] = np.asarray(env.reset(seed=1000 * b + k)[0], dtype=float).ravel()
                    twin.load(envs, np.arange(copies) == b)
        return True, ends
    finally:
        for env in envs:
            env.close()


def twin_for(env_id: str, kwargs: Mapping[str, Any], vec: Any) -> Twin | None:
    """A twin of the vector environment ``vec`` (``gymnasium.make_vec(env_id, ..., **kwargs)``, synchronous),
    or None where ``env_id`` has none or its twin did not agree with the environment (:func:`agrees`,
    checked once per id and arguments in a process)."""
    twin_cls = TWINS.get(env_id)
    if twin_cls is None or not hasattr(vec, "envs") or not twin_cls.fits(vec.envs[0].unwrapped):
        return None
    key = (env_id, tuple(sorted(kwargs.items())))
    if key not in _CHECKED:
        _CHECKED[key] = agrees(env_id, kwargs)
    return twin_cls(vec.envs[0].unwrapped, len(vec.envs)) if _CHECKED[key] else None
