"""Gymnasium environments as plants: ``plant gym:MountainCarContinuous-v0`` in a spec.

A spec names the environment's id after ``gym:`` and maps the state variables its
propositions read to the observation, one ``state`` line each::

    plant gym:MountainCarContinuous-v0(dt = 1)
    state x = obs[0], v = obs[1]

    plant gym:Pendulum-v1                 # dt = 0.05 s, the environment's
    state q = atan2(obs[1], obs[0]), w = obs[2]

``obs[i]`` is entry ``i`` of the flattened observation; a state variable is any
arithmetic of them. Its bounds (for the compiler's interval analysis and the
learner's features) are the observation space's for a bare ``obs[i]``,
``[-pi, pi)`` for an ``atan2(...)`` (an angle: periodic features), else given
with ``in [lo, hi]``. The plant's parameters are keyword arguments of
``gymnasium.make`` (integral values as ``int``), except ``dt``, the sample time in
seconds: the spec's, else the environment's (``dt``, ``tau`` or ``metadata["dt"]``).

An environment cannot be set to a state, so a trainer does not integrate it: it
asks the plant for a :class:`~mitlc.plants.base.Simulator` and resets and steps
that (:class:`GymSimulator`: ``R`` copies through Gymnasium's vector API). The
spec's ``init`` is then a condition on the environment's own reset distribution:
a copy that starts outside it is reset again (rejection sampling). The registered
time limit is lifted (the trial is the spec's horizon); a copy whose episode
terminates keeps its last state to the end of the trial (MountainCar's goal is
absorbing).

Gymnasium is imported only when such a plant is used (``pip install 'mitlc[gym]'``).

A spec never causes an import: Gymnasium reads an id ``module:Env`` as "import ``module``,
then make ``Env``", so an id with a ``:`` is refused (:func:`check_env_id`, before Gymnasium
sees it) and a spec names registered ids only. The environments of a module of the user's are
registered by naming it on the command line, ``--gym-module MODULE``
(:func:`import_gym_module`), which imports it before the spec is read; a training records it,
and a run folder says which option to pass again rather than importing it.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.errors import InputError, TrainingError
from mitlc.plants.base import InputVar, Plant, StateVar, wrap_angle

__all__ = [
    "GYM_PREFIX",
    "GYM_MODULES",
    "MAX_ID",
    "check_env_id",
    "import_gym_module",
    "ObsVar",
    "EnvInfo",
    "open_env",
    "env_dt",
    "env_info",
    "action_bound",
    "action_inputs",
    "gym_plant",
    "GymSimulator",
    "MAX_RESETS",
    "outside_init",
]

GYM_PREFIX = "gym:"
"""A plant name starting with this names a Gymnasium environment id."""

GYM_MODULES: list[str] = []
"""The modules ``--gym-module`` imported in this process, in order: a training records them and a
sweep's workers import them again (:mod:`mitlc.sweep.task`)."""

MAX_ID = 200
"""The longest Gymnasium id accepted, in characters (Gymnasium's own are under 50)."""

_MODULE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")

MAX_RESETS = 1000
"""Resets a copy may take to start inside the spec's ``init`` before training stops."""

_NO_LIMIT = 2**62  # max_episode_steps for the trainer's copies: the trial is the spec's horizon


@dataclass(frozen=True)
class ObsVar:
    """One state variable read off the flattened observation ``(B, m) -> (B,)``."""

    var: StateVar
    read: Callable[[np.ndarray], Any]
    text: str
    """The mapping as the spec wrote it (``obs[0]``), for listings."""
    expr: Any
    """The mapping's syntax tree (:mod:`mitlc.spec.predicates`), whose variables are ``obs[i]``: the
    fused kernel's read of one copy is generated from it (:meth:`GymSimulator.kernel_step`)."""


@dataclass(frozen=True)
class EnvInfo:
    """What a plant needs to know of an environment, read once from a fresh instance."""

    obs_low: np.ndarray
    obs_high: np.ndarray
    """Bounds of the flattened observation (``inf`` where unbounded)."""
    action: str
    """The action space, as Gymnasium prints it."""
    u_max: float | None
    """The input bound when the action is one symmetric continuous entry, else None."""
    action_problem: str | None
    """Why the action space is no input for mitlc's learners (None when it is)."""
    dt: float | None
    dt_where: str
    inputs: tuple[InputVar, ...] | None = None
    """The inputs when the action is any other finite ``Box`` (several entries, or one not
    symmetric): ``a0, a1, ...``, one per entry of the flattened action, each with its bounds."""


def _gymnasium() -> Any:
    try:
        import gymnasium
    except ImportError:
        raise InputError(
            "a Gymnasium plant needs Gymnasium, an optional dependency: pip install 'mitlc[gym]'"
        ) from None
    return gymnasium


def _short(text: str, n: int = 60) -> str:
    return text if len(text) <= n else text[: n - 3] + "..."


def check_env_id(env_id: object) -> str:
    """``env_id`` if it names an environment without importing anything, else an :class:`InputError`.

    Gymnasium's ``make``, ``make_vec`` and ``spec`` read ``module:Env`` as an order to import
    ``module`` first: an id from a spec (or a run folder) must never do that, so any ``:`` is
    refused here, before Gymnasium sees the id. What is left (``[namespace/]name[-vN]``) is only
    looked up in Gymnasium's registry.
    """
    if not isinstance(env_id, str) or not env_id:
        raise InputError(f"a Gymnasium id is a non-empty string, got {_short(repr(env_id))}")
    if len(env_id) > MAX_ID:
        raise InputError(f"'{_short(env_id)}' is not a Gymnasium id: longer than {MAX_ID} characters")
    if ":" in env_id:
        module, _, name = env_id.rpartition(":")
        if _MODULE_NAME.fullmatch(module) and name and ":" not in module:
            raise InputError(
                f"'{GYM_PREFIX}{_short(env_id)}' would import the module '{_short(module)}': a spec names registered "
                f"Gymnasium ids only, and never causes an import; write 'plant {GYM_PREFIX}{_short(name)}' and pass "
                f"--gym-module {_short(module)} to register the module's environments"
            )
        raise InputError(
            f"'{GYM_PREFIX}{_short(env_id)}' is not a registered Gymnasium id: ':' would name a module to import, "
            "and a spec never causes an import (pass --gym-module MODULE to register a module's environments)"
        )
    return env_id


def import_gym_module(name: str, option: str = "--gym-module") -> None:
    """Import the module ``name`` (``--gym-module``), so that it registers its Gymnasium environments.

    The user's explicit choice on the command line; recorded in :data:`GYM_MODULES`. Any failure is
    one :class:`InputError` naming the option."""
    where = f"{option} {_short(name)}"
    if not _MODULE_NAME.fullmatch(name):
        hint = "a file of plants is --plant-file FILE.py" if name.endswith(".py") or "/" in name else None
        raise InputError("not a module name (a dotted Python name such as mypkg.envs)", file=where, hint=hint)
    try:
        importlib.import_module(name)
    except ModuleNotFoundError as exc:
        missing = exc.name or name
        hint = (
            "put its folder on the Python path (PYTHONPATH=DIR) or install its package"
            if name == missing or name.startswith(missing + ".")
            else None
        )
        raise InputError(
            f"cannot import module '{_short(name)}': no module named '{_short(missing)}'", file=where, hint=hint
        ) from None
    except (Exception, SystemExit) as exc:  # the user's code: any failure becomes one line
        raise InputError(
            f"importing module '{_short(name)}' failed: {type(exc).__name__}: {_first_line(exc)}", file=where
        ) from None
    if name not in GYM_MODULES:
        GYM_MODULES.append(name)


def open_env(env_id: str, kwargs: Mapping[str, float] | None = None, **make: Any) -> Any:
    """``gymnasium.make(env_id, **kwargs)``, with one clear error for an unknown id or argument."""
    env_id = check_env_id(env_id)
    gym = _gymnasium()
    args = {k: _make_arg(v) for k, v in (kwargs or {}).items()}
    try:
        return gym.make(env_id, disable_env_checker=True, **make, **args)
    except gym.error.Error as exc:
        raise InputError(
            f"Gymnasium has no environment '{env_id}' ({_first_line(exc)})",
            hint="an environment of your own module is registered by importing it: --gym-module MODULE",
        ) from None
    except (TypeError, ValueError) as exc:
        given = ", ".join(args) or "none"
        raise InputError(
            f"Gymnasium's '{env_id}' does not take the parameters given (given: {given}): {_first_line(exc)}"
        ) from None


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


def _make_arg(v: float) -> float | int:
    return int(v) if float(v).is_integer() and abs(v) < 2**53 else float(v)


def env_dt(env: Any) -> tuple[Any, str]:
    """The environment's step in seconds, where Gymnasium's environments keep it: ``dt``
    (MuJoCo, Pendulum-v1), ``tau`` (CartPole), or ``metadata["dt"]``; ``(None, where)`` if none."""
    base = env.unwrapped
    for name in ("dt", "tau"):
        value = getattr(base, name, None)
        if value is not None:
            return value, f"the environment's {name}"
    value = (getattr(base, "metadata", None) or {}).get("dt")
    return value, "the environment's metadata['dt']"


def action_bound(space: Any) -> tuple[float | None, str | None]:
    """``(u_max, None)`` for a one-entry symmetric finite ``Box``; ``(None, None)`` for any other
    finite ``Box`` (its entries are inputs: :func:`action_inputs`); else ``(None, why not)``."""
    spaces = _gymnasium().spaces
    if not isinstance(space, spaces.Box):
        return None, (
            f"its actions are {space}, not continuous: mitlc's learners drive continuous inputs "
            "(a Box action space); a discrete-action environment can still pay the "
            "compiled reward to another learner through mitlc.gym.MitlRewardWrapper"
        )
    low, high = np.asarray(space.low, dtype=float).reshape(-1), np.asarray(space.high, dtype=float).reshape(-1)
    if low.size == 0:
        return None, f"its action space {space} has no entries: a plant needs at least one input"
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(low < high)):
        shown = ", ".join(f"[{a:g}, {b:g}]" for a, b in zip(low[:4], high[:4], strict=False))
        more = ", ..." if low.size > 4 else ""
        return None, f"its action bounds {shown}{more} are not finite boxes with low < high"
    lo, hi = float(low[0]), float(high[0])
    if low.size == 1 and hi > 0 and abs(lo + hi) <= 1e-9 * hi:
        return hi, None
    return None, None


def action_inputs(space: Any) -> tuple[InputVar, ...] | None:
    """The inputs of a finite ``Box`` action space that is not one symmetric entry: ``a0, a1, ...``,
    one per entry of the flattened action with its bounds; None for any other space."""
    u_max, problem = action_bound(space)
    if u_max is not None or problem is not None:
        return None
    low, high = np.asarray(space.low, dtype=float).reshape(-1), np.asarray(space.high, dtype=float).reshape(-1)
    return tuple(InputVar(f"a{i}", float(a), float(b)) for i, (a, b) in enumerate(zip(low, high, strict=True)))


def env_info(env_id: str, kwargs: Mapping[str, float] | None = None) -> EnvInfo:
    """Read an environment's spaces and step once from a fresh instance (closed after)."""
    spaces = _gymnasium().spaces
    env = open_env(env_id, kwargs)
    try:
        obs_space = env.observation_space
        try:
            flat = spaces.flatten_space(obs_space)
        except NotImplementedError:
            raise InputError(f"the observation space of '{env_id}' ({obs_space}) does not flatten to numbers") from None
        if not isinstance(flat, spaces.Box):
            raise InputError(f"the observation space of '{env_id}' ({obs_space}) does not flatten to a Box")
        u_max, problem = action_bound(env.action_space)
        dt, where = env_dt(env)
        return EnvInfo(
            obs_low=_shortest(flat.low),
            obs_high=_shortest(flat.high),
            action=str(env.action_space),
            u_max=u_max,
            action_problem=problem,
            dt=None if dt is None else float(dt),
            dt_where=where,
            inputs=action_inputs(env.action_space),
        )
    finally:
        env.close()


def _shortest(a: Any) -> np.ndarray:
    """Bounds as the shortest decimals of their own precision (float32's 0.6, not 0.6000000238)."""
    arr = np.asarray(a).reshape(-1)
    if arr.dtype.kind != "f":
        return arr.astype(float)
    return np.array([float(np.format_float_positional(v, unique=True, trim="-")) for v in arr])


def gym_plant(env_id: str, kwargs: Mapping[str, float], observe: Sequence[ObsVar], dt: float, info: EnvInfo) -> Plant:
    """The plant of a Gymnasium environment: the mapped state variables, ``dt``, and ``u_max`` (one
    symmetric action entry) or the inputs (any other finite ``Box``: one per entry)."""
    defaults = {"dt": float(dt)}
    if info.u_max is not None:
        defaults["u_max"] = float(info.u_max)
    make_kwargs = dict(kwargs)
    obs = tuple(observe)
    name = GYM_PREFIX + env_id

    def no_dynamics(x: np.ndarray, u: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        raise TrainingError(
            f"plant '{name}' is a Gymnasium environment: it is stepped, not integrated, and cannot be set to a "
            "state; train it with SACPN (mitlc train) or any learner through mitlc.gym.MitlRewardWrapper"
        )

    def simulator(plant: Plant, params: Mapping[str, float], init: Mapping[str, tuple[float, float]]) -> GymSimulator:
        if info.action_problem is not None:
            raise TrainingError(f"cannot train on '{name}': {info.action_problem}")
        box = plant.input_box(params) if info.inputs is not None else None
        return GymSimulator(env_id, make_kwargs, obs, init, info.u_max or 0.0, box)

    mapping = ", ".join(f"{o.var.name} = {o.text}" for o in obs)
    return Plant(
        name=name,
        state=tuple(o.var for o in obs),
        defaults=defaults,
        dynamics=no_dynamics,
        description=f"Gymnasium environment {env_id} ({mapping}; actions {info.action})",
        make_simulator=simulator,
        observation=obs,
        inputs=info.inputs,
    )


def outside_init(x: np.ndarray, ranges: Sequence[tuple[int, float, float]]) -> np.ndarray:
    """Per row of ``x (B, n)``: a column ``i`` of ``ranges`` ``(i, lo, hi)`` lies outside
    ``[lo, hi]`` (give or take 1e-9 relative, so that a point ``v = 0`` matches 0.0); NaN is outside."""
    bad = np.zeros(x.shape[0], dtype=bool)
    for i, lo, hi in ranges:
        tol = 1e-9 * max(1.0, abs(lo), abs(hi))
        bad |= ~((x[:, i] >= lo - tol) & (x[:, i] <= hi + tol))
    return bad


class GymSimulator:
    """``B`` copies of a Gymnasium environment behind the trainer's reset/step interface.

    One synchronous vector environment per batch size (``gymnasium.make_vec``);
    ``reset(rngs)`` seeds copy ``b`` from ``rngs[b]`` (so a run's numbers do not
    depend on how many runs there are), rejects starts outside ``init``, and
    returns the states; ``step(x, u)`` applies ``u`` and writes the new states into
    ``x``, keeping a copy whose episode ended in its last state. ``u`` is ``(B,)``,
    clipped to ``[-u_max, u_max]``, or with ``box = (lo, hi)`` (an action of several
    entries) ``(B, m)``, each entry clipped to its bounds. An environment with a numpy twin
    (:mod:`mitlc.plants.gym_twins`: Pendulum-v1, MountainCarContinuous-v0) is reset by Gymnasium and
    stepped by its twin, all copies at once, with the same numbers to the bit.
    """

    settable = False
    """A state cannot be set: roll out from what :meth:`reset` returned."""

    def __init__(
        self,
        env_id: str,
        kwargs: Mapping[str, float],
        observe: Sequence[ObsVar],
        init: Mapping[str, tuple[float, float]],
        u_max: float,
        box: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        self.env_id, self.kwargs, self.observe = check_env_id(env_id), dict(kwargs), tuple(observe)
        self.u_max = float(u_max)
        self.box = box
        names = [o.var.name for o in self.observe]
        cols = [(names.index(v), lo, hi) for v, (lo, hi) in init.items() if v in names]
        self._init = cols
        self._periodic = [i for i, o in enumerate(self.observe) if o.var.periodic]
        self._envs: dict[int, Any] = {}
        self._twins: dict[int, Any] = {}
        self._done: dict[int, np.ndarray] = {}
        self._actions: dict[int, np.ndarray] = {}
        self.last: dict[int, np.ndarray] = {}
        """The states the last :meth:`reset` of each batch size returned."""

    def _vec(self, B: int) -> Any:
        env = self._envs.get(B)
        if env is None:
            gym = _gymnasium()
            args = {k: _make_arg(v) for k, v in self.kwargs.items()}
            env = gym.make_vec(
                check_env_id(self.env_id),
                num_envs=B,
                vectorization_mode="sync",
                vector_kwargs={"copy": False},
                max_episode_steps=_NO_LIMIT,
                disable_env_checker=True,
                **args,
            )
            self._envs[B] = env
            from mitlc.plants.gym_twins import twin_for

            self._twins[B] = twin_for(self.env_id, args, env)
            self._flat_space = env.single_observation_space
            self._box = isinstance(self._flat_space, gym.spaces.Box)
            self._actions[B] = np.zeros((B, *env.single_action_space.shape), dtype=env.single_action_space.dtype)
        return env

    def _states(self, obs: Any, B: int) -> np.ndarray:
        if self._box:
            flat = np.asarray(obs, dtype=float).reshape(B, -1)
        else:
            spaces = _gymnasium().spaces
            vec = self._envs[B]
            flat = np.stack(
                [
                    np.asarray(spaces.flatten(self._flat_space, o), dtype=float)
                    for o in spaces.iterate(vec.observation_space, obs)
                ]
            )
        x = np.empty((B, len(self.observe)))
        with np.errstate(all="ignore"):
            for i, o in enumerate(self.observe):
                x[:, i] = o.read(flat)
        for i in self._periodic:
            x[:, i] = wrap_angle(x[:, i])
        return x

    def _outside(self, x: np.ndarray) -> np.ndarray:
        return ~np.isfinite(x).all(axis=1) | outside_init(x, self._init)

    def reset(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        B = len(rngs)
        env = self._vec(B)
        seeds: list[int | None] = [int(g.integers(2**31)) for g in rngs]
        obs, _ = env.reset(seed=seeds)
        x = self._states(obs, B)
        bad = self._outside(x)
        tries = 0
        while bad.any():
            tries += 1
            if tries > MAX_RESETS:
                ranges = ", ".join(f"{self.observe[i].var.name} in [{lo:g}, {hi:g}]" for i, lo, hi in self._init)
                raise TrainingError(
                    f"'{self.env_id}' did not start inside the spec's init ({ranges}) in {MAX_RESETS} resets",
                    hint="a Gymnasium plant's init selects among the environment's own starts: widen it or drop it",
                )
            seeds = [int(g.integers(2**31)) if b else None for g, b in zip(rngs, bad, strict=True)]
            obs, _ = env.reset(seed=seeds, options={"reset_mask": bad.copy()})
            x[bad] = self._states(obs, B)[bad]
            bad = self._outside(x)
        twin = self._twins.get(B)
        if twin is not None:  # the twin steps the copies from the states the environment reset them to
            twin.load(env.envs)
        self._done[B] = np.zeros(B, dtype=bool)
        self.last[B] = x.copy()
        return x

    def step(self, x: np.ndarray, u: np.ndarray) -> None:
        B = x.shape[0]
        env = self._envs.get(B)
        if env is None or B not in self._done:
            raise TrainingError(f"'{self.env_id}': step before reset (batch of {B})")
        a = self._actions[B]
        if self.box is None:
            a.reshape(B, -1)[:, 0] = np.clip(u, -self.u_max, self.u_max)
        else:
            a.reshape(B, -1)[:] = np.clip(np.asarray(u).reshape(B, -1), self.box[0], self.box[1])
        twin = self._twins.get(B)
        if twin is not None:
            obs, terminated = twin.step(a)
            truncated = terminated
        else:
            obs, _, terminated, truncated, _ = env.step(a)
        done = self._done[B]
        new = self._states(obs, B)
        live = ~done
        x[live] = new[live]
        done |= np.asarray(terminated, dtype=bool) | np.asarray(truncated, dtype=bool)

    def kernel_step(self, B: int, jit: Callable = lambda f: f) -> tuple[Callable, np.ndarray, int, int] | str:
        """The parts of one copy's step for SACPN's fused kernel when ``B`` copies are trained, or why
        there are none: the twin's :meth:`~mitlc.plants.gym_twins.Twin.kernel_physics` ``(physics,
        consts, h, k)`` (the functions it calls compiled by ``jit``), whose constants start with the
        input bound (the clip of :meth:`step`). The kernel's state of a copy is its ``n`` state
        variables, then the ``h`` numbers of the twin's (:meth:`kernel_states`); the state variables
        are read off the observation as :meth:`step` reads them."""
        self._vec(B)
        twin = self._twins.get(B)
        if twin is None:
            return f"'{self.env_id}' has no numpy twin (mitlc.plants.gym_twins) to step it in the kernel"
        if self.box is not None:
            return f"'{self.env_id}' has an action of several entries"
        parts = twin.kernel_physics(jit)
        if parts is None:
            return f"the twin of '{self.env_id}' has no kernel step"
        physics, consts, h, k = parts
        return physics, np.concatenate([[self.u_max], consts]), h, k

    def kernel_states(self, x: np.ndarray) -> np.ndarray:
        """The kernel's states of the copies the last :meth:`reset` of ``len(x)`` copies returned as ``x``:
        each row ``x``'s, then the twin's hidden state (:meth:`kernel_step`)."""
        twin = self._twins.get(x.shape[0])
        assert twin is not None, "kernel_states without a twin"
        return np.ascontiguousarray(np.concatenate([x, twin.hidden()], axis=1))

    def start(self, x0: np.ndarray) -> None:
        """Check that a rollout starts where the copies are (the last reset's states)."""
        last = self.last.get(x0.shape[0])
        if last is None or not np.array_equal(last, x0):
            raise TrainingError(
                f"'{self.env_id}' cannot be set to a given state: roll out from the states its reset returned "
                "(Sacpn.evaluation_states() or Sacpn.sample_init())"
            )

    def close(self) -> None:
        for env in self._envs.values():
            env.close()
        self._envs.clear()
        self._twins.clear()
