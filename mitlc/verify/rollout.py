"""Roll a policy out on scenarios of a :class:`~mitlc.verify.space.SearchSpace` and judge each rollout.

All scenarios of a batch step together along the plant's run axis: one ``act``, one plant
step and one net step per sample for the whole batch, whatever its size. Varied parameters
are arrays ``(B,)`` in the plant's parameter mapping (a plant's ``dynamics`` written with
:func:`mitlc.plants.base.ode_dynamics` broadcasts them; :func:`check_batched_params` tests
that a plant does).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.errors import InputError
from mitlc.monitor.offline import MonitorResult, monitor
from mitlc.plants.base import Plant, make_integrator, wrap_angle
from mitlc.spec.model import Spec
from mitlc.verify.space import SearchSpace

__all__ = [
    "Judged",
    "roll_out",
    "rows_for",
    "judge",
    "evaluate",
    "base_params",
    "check_batched_params",
    "check_plant",
]


@dataclass(frozen=True)
class Judged:
    """Rollouts of ``B`` scenarios and the monitor's verdict on each."""

    z: np.ndarray
    """The scenarios' points of the unit cube, ``(B, dim)``."""
    states: np.ndarray
    """``(B, N + 1, n)``: the states from the start on, one row per sample."""
    actions: np.ndarray
    """``(B, N)`` (one input) or ``(B, N, m)``: the inputs the plant got (policy plus disturbance, clipped)."""
    dt: float
    result: MonitorResult

    @property
    def robustness(self) -> np.ndarray:
        return self.result.robustness

    @property
    def satisfied(self) -> np.ndarray:
        return self.result.satisfied


def base_params(spec: Spec, dt: float) -> dict[str, float]:
    """The plant's parameters as the spec sets them, with the policy's sample time ``dt``."""
    plant = spec.plant
    if plant is None:
        raise InputError("the spec names no plant", file=spec.path)
    p = plant.params(dict(spec.plant_params))
    p["dt"] = float(dt)
    return p


def check_plant(plant: Plant) -> None:
    """A plant that cannot be put in a chosen state (a Gymnasium environment) cannot be verified
    from chosen starts: one line."""
    if plant.stepped:
        raise InputError(
            f"plant '{plant.name}' is an environment that resets itself: verify needs a plant it can start "
            "in a chosen state",
            file="--policy",
        )


def check_batched_params(plant: Plant, params: Mapping[str, float], vary: tuple[tuple[str, float, float], ...]) -> None:
    """One step of two copies with the varied parameters at their ends, together and one by one,
    from a state and input off the middle of their bounds: a plant whose ``dynamics`` does not take
    a parameter per copy fails here, as one line naming ``--vary``, not deep in a rollout."""
    if not vary:
        return
    # off the middle of every bound (at rest, a damping parameter would change nothing)
    at = np.array([0.3 if i % 2 == 0 else 0.7 for i in range(len(plant.state))])
    mid = np.repeat(np.array([[v.lo + f * (v.hi - v.lo) for v, f in zip(plant.state, at, strict=True)]]), 2, axis=0)
    lo, hi = plant.input_box(params)
    u1 = lo + 0.7 * (hi - lo)
    u = np.repeat(u1[None, :], 2, axis=0) if plant.n_inputs > 1 else np.full(2, u1[0])
    both: dict[str, Any] = dict(params)
    both.update({n: np.array([lo, hi]) for n, lo, hi in vary})
    try:
        with np.errstate(all="ignore"):
            together = plant.step(mid.copy(), u, both)
            apart = [
                plant.step(mid[r : r + 1].copy(), u[r : r + 1], {**params, **{n: (lo, hi)[r] for n, lo, hi in vary}})
                for r in range(2)
            ]
    except Exception as exc:  # the user's dynamics: whatever it raised, one line
        raise InputError(
            f"plant '{plant.name}' cannot step copies with a parameter each ({type(exc).__name__}: {exc}); "
            "write its dynamics with mitlc.plants.base.ode_dynamics, or vary nothing",
            file="--vary",
        ) from None
    if not np.allclose(together, np.concatenate(apart), equal_nan=True):
        raise InputError(
            f"plant '{plant.name}' steps copies with a parameter each differently from one by one: its dynamics "
            "reads a parameter as one number (write it with mitlc.plants.base.ode_dynamics, or vary nothing)",
            file="--vary",
        )


def _stepper(plant: Plant, params: Mapping[str, Any], varied: bool) -> Callable[[np.ndarray, np.ndarray], None]:
    """The in-place one-step map: the plant's fastest (:func:`make_integrator`) with fixed
    parameters, :meth:`Plant.step` with a row of parameters per copy."""
    if not varied:
        return make_integrator(plant, params)

    def advance(x: np.ndarray, u: np.ndarray) -> None:
        x[...] = plant.step(x.copy(), u, params)

    return advance


def _wrap_and_clip(plant: Plant, x: np.ndarray) -> None:
    """What :meth:`Plant.step` does after integrating: wrap the angles, clip the bounded variables."""
    for i, v in enumerate(plant.state):
        if v.periodic:
            x[:, i] = wrap_angle(x[:, i])
        elif v.name in plant.clip:
            x[:, i] = np.clip(x[:, i], v.lo, v.hi)


def rows_for(run: np.ndarray, runs: int) -> tuple[np.ndarray, int]:
    """Where each scenario goes in the batch so that it acts with its run: a policy acts on row ``b``
    with run ``b % runs``, so scenario ``i`` goes to row ``run[i] + runs * k`` (its ``k``-th of that
    run); and the batch's size (rows no scenario takes are filled, and their rollouts dropped).

    >>> rows_for(np.array([1, 0, 1, 1]), 2)
    (array([1, 0, 3, 5]), 6)
    """
    seen = np.zeros(runs, dtype=np.int64)
    k = np.empty(run.shape[0], dtype=np.int64)
    for i, r in enumerate(run):
        k[i] = seen[r]
        seen[r] += 1
    return run + runs * k, int(runs * seen.max()) if run.shape[0] else 0


def roll_out(policy: Any, spec: Spec, space: SearchSpace, z: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """The states ``(B, steps + 1, n)`` and applied inputs of ``policy`` from the scenarios ``z``.

    ``policy`` is a :class:`mitlc.learn.policy.Policy` (``reset``, ``act``, ``step``, ``runs`` and
    ``dt``); each scenario acts with its run (:attr:`Scenarios.run`, placed by :func:`rows_for`)."""
    plant = spec.plant
    assert plant is not None  # SearchSpace.of refused a spec without one
    sc = space.decode(z)
    rows, B = rows_for(sc.run, int(getattr(policy, "runs", 1)))
    fill = np.zeros(B, dtype=np.int64)  # a row no scenario takes repeats scenario 0
    fill[rows] = np.arange(rows.shape[0])
    m = plant.n_inputs
    params: dict[str, Any] = base_params(spec, policy.dt)
    params.update({n: v[fill] for n, v in sc.params.items()})
    advance = _stepper(plant, params, varied=bool(sc.params))
    if plant.inputs is None:
        u_max = np.asarray(params["u_max"], dtype=float)
        lo, hi = -u_max, u_max
    else:
        box = plant.input_box(params)
        lo, hi = box[0], box[1]
    disturbance, drift = sc.disturbance[fill], sc.state_disturbance[fill]
    disturbed, drifting = bool(np.any(disturbance)), bool(np.any(drift))
    dt = float(params["dt"])
    x = np.array(sc.x0[fill], dtype=float)
    states = np.empty((B, steps + 1, x.shape[1]))
    actions = np.empty((B, steps) if m == 1 else (B, steps, m))
    states[:, 0] = x
    state = policy.reset(x.copy())
    pieces = disturbance.shape[1]
    for k in range(steps):
        u = np.asarray(policy.act(x, state), dtype=float).reshape((B,) if m == 1 else (B, m))
        if disturbed:
            d = disturbance[:, min(pieces - 1, k * pieces // steps)]
            u = u + (d[:, 0] if m == 1 else d)
        u = np.clip(u, lo, hi)
        advance(x, u)
        if drifting:  # a state disturbance: the rates plus d over the step, then the plant's own wraps and clips
            x += drift[:, min(pieces - 1, k * pieces // steps)] * dt
            _wrap_and_clip(plant, x)
        state = policy.step(state, x.copy())
        states[:, k + 1], actions[:, k] = x, u
    return states[rows], actions[rows]


DIVERGED = "the plant diverged (a state left float64's range)"
"""The failing part named for a rollout whose states stopped being finite numbers."""


def judge(spec: Spec, states: np.ndarray, dt: float) -> MonitorResult:
    """The monitor's verdict on each rollout, by the spec's ``check`` line, else its ``formula``.

    A rollout whose states stopped being finite (a plant that blew up under a varied parameter or
    a disturbance) violates the spec with robustness ``-inf`` from its first such sample: a
    counterexample, not an error that would stop the verification."""
    finite = np.isfinite(states).all(axis=2)
    whole = finite.all(axis=1)
    try:
        if whole.all():
            return monitor(spec, states, dt, spec.monitor_formula)
        part = monitor(spec, states[whole], dt, spec.monitor_formula) if whole.any() else None
    except InputError as exc:  # what the monitor refuses in the states the rollouts reached
        raise exc.located("the rollouts") from None
    B = states.shape[0]
    satisfied = np.zeros(B, dtype=bool)
    robustness = np.full(B, -np.inf)
    violation = np.argmin(finite, axis=1) * float(dt)
    failing: list[str | None] = [DIVERGED] * B
    if part is not None:
        rows = np.flatnonzero(whole)
        satisfied[rows], robustness[rows], violation[rows] = part.satisfied, part.robustness, part.violation_time
        for r, f in zip(rows, part.failing, strict=True):
            failing[r] = f
    return MonitorResult(satisfied, robustness, violation, tuple(failing))


def evaluate(policy: Any, spec: Spec, space: SearchSpace, z: np.ndarray, steps: int) -> Judged:
    """:func:`roll_out` and :func:`judge` the scenarios ``z``."""
    z = np.atleast_2d(np.asarray(z, dtype=float))
    states, actions = roll_out(policy, spec, space, z, steps)
    return Judged(z, states, actions, float(policy.dt), judge(spec, states, policy.dt))
