"""Plants: the dynamical systems a spec talks about.

A plant declares its state variables with their bounds (used by the compiler's
interval analysis and by the learner's features), which of them are angles
(periodic), its parameters with defaults, and a vectorised ``step``.

To add a plant, build a :class:`Plant` and :func:`register` it (the shipped ones
are registered by :mod:`mitlc.plants`, one module each):

>>> import numpy as np
>>> import mitlc.plants
>>> p = PLANTS["pendulum"]
>>> p.state_names
('q', 'qdot')
>>> x = np.array([[-np.pi, 0.0]])         # hanging down, at rest
>>> np.allclose(p.step(x, np.zeros(1), p.params()), x)
True
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

__all__ = ["StateVar", "Plant", "PLANTS", "register", "wrap_angle", "make_integrator", "Simulator", "OdeSimulator"]


def wrap_angle(q: np.ndarray) -> np.ndarray:
    """Wrap angles to ``[-pi, pi)``.

    >>> float(wrap_angle(np.array(3 * np.pi / 2)))
    -1.5707963267948966
    """
    return (q + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True)
class StateVar:
    """One state variable: its name, bounds, and whether it is an angle."""

    name: str
    lo: float
    hi: float
    periodic: bool = False


@dataclass(frozen=True)
class Plant:
    """A plant: state variables, parameters and a batched one-step map.

    ``dynamics(x, u, params) -> xdot`` works on arrays of shape ``(R, n)``;
    :meth:`step` integrates it with RK4 over ``params['dt']``, wraps the
    angles and clips bounded velocities.
    """

    name: str
    state: tuple[StateVar, ...]
    defaults: Mapping[str, float]
    dynamics: Callable[[np.ndarray, np.ndarray, Mapping[str, float]], np.ndarray]
    description: str = ""
    default_spec: str | None = None
    clip: tuple[str, ...] = field(default=())
    fast_step: Callable[[Plant, Mapping[str, float]], Callable[[np.ndarray, np.ndarray], None]] | None = None
    """Optional: builds an in-place one-step map ``step(x, u)`` that agrees with
    :meth:`step` to rounding and is faster (the pendulum's fused RK4);
    :func:`make_integrator` uses it."""
    make_simulator: Callable[[Plant, Mapping[str, float], Mapping[str, tuple[float, float]]], Simulator] | None = None
    """Optional: builds the :class:`Simulator` trainers reset and step, for a plant that
    is stepped rather than integrated (a Gymnasium environment,
    :mod:`mitlc.plants.gym_env`); None: an :class:`OdeSimulator` of :meth:`step`."""

    observation: tuple = ()
    """An environment plant's state lines (:class:`mitlc.plants.gym_env.ObsVar`: each state
    variable read off the flattened observation); empty for an ODE plant."""

    @property
    def stepped(self) -> bool:
        """True for a plant that cannot be set to a state (an environment), only reset and stepped."""
        return self.make_simulator is not None

    def simulator(
        self, params: Mapping[str, float], init: Mapping[str, tuple[float, float]] | None = None
    ) -> Simulator:
        """``B`` copies of the plant to reset (starts drawn from ``init``) and step."""
        init = dict(init or {})
        if self.make_simulator is not None:
            return self.make_simulator(self, params, init)
        return OdeSimulator(self, params, init)

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.state)

    def var(self, name: str) -> StateVar:
        for v in self.state:
            if v.name == name:
                return v
        raise KeyError(name)

    def params(self, overrides: Mapping[str, float] | None = None) -> dict[str, float]:
        out = dict(self.defaults)
        out.update(overrides or {})
        return out

    def step(self, x: np.ndarray, u: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        """One sample period of RK4; ``x`` is ``(R, n)``, ``u`` is ``(R,)``."""
        dt = params["dt"]
        u = np.clip(u, -params["u_max"], params["u_max"])
        f = self.dynamics
        k1 = f(x, u, params)
        k2 = f(x + 0.5 * dt * k1, u, params)
        k3 = f(x + 0.5 * dt * k2, u, params)
        k4 = f(x + dt * k3, u, params)
        x = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        for i, v in enumerate(self.state):
            if v.periodic:
                x[:, i] = wrap_angle(x[:, i])
            elif v.name in self.clip:
                x[:, i] = np.clip(x[:, i], v.lo, v.hi)
        return x


PLANTS: dict[str, Plant] = {}


def register(plant: Plant) -> Plant:
    """Make ``plant`` available to specs (``plant NAME``) and the CLI."""
    PLANTS[plant.name] = plant
    return plant


def make_integrator(plant: Plant, params: Mapping[str, float]) -> Callable[[np.ndarray, np.ndarray], None]:
    """An in-place one-step map ``step(x, u)`` equal to ``plant.step``.

    A plant with a :attr:`Plant.fast_step` (the pendulum: a fused RK4 on the two
    state rows with the constants of (A-2) folded, about twice as fast, agreeing
    with :meth:`Plant.step` to rounding) gets that; any other plant uses
    :meth:`Plant.step`.
    """
    p = dict(params)
    if plant.fast_step is not None:
        return plant.fast_step(plant, p)

    def generic(x: np.ndarray, u: np.ndarray) -> None:
        x[...] = plant.step(x.copy(), u, p)

    return generic


class Simulator(Protocol):
    """What a trainer resets and steps: ``B`` copies of a plant in lock-step.

    ``reset(rngs)`` returns one start per generator, ``(B, n)``, drawn from copy
    ``b``'s own ``rngs[b]``; ``step(x, u)`` applies ``u (B,)`` and writes the next
    states into ``x`` in place. ``settable`` says whether a rollout may start
    anywhere (an ODE plant) or only where the last reset left the copies
    (:meth:`start` checks it).
    """

    settable: bool

    def reset(self, rngs: Sequence[np.random.Generator]) -> np.ndarray: ...

    def step(self, x: np.ndarray, u: np.ndarray) -> None: ...

    def start(self, x0: np.ndarray) -> None: ...


class OdeSimulator:
    """An ODE plant's copies: starts uniform in the ``init`` ranges (0 where none is
    given; angles wrapped), steps by :func:`make_integrator`."""

    settable = True

    def __init__(self, plant: Plant, params: Mapping[str, float], init: Mapping[str, tuple[float, float]]) -> None:
        self.plant = plant
        self.ranges = [init.get(v, (0.0, 0.0)) for v in plant.state_names]
        self.step = make_integrator(plant, params)

    def reset(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        x = np.empty((len(rngs), len(self.ranges)))
        for r, g in enumerate(rngs):
            for i, (lo, hi) in enumerate(self.ranges):
                x[r, i] = g.uniform(lo, hi)
        for i, v in enumerate(self.plant.state):
            if v.periodic:
                x[:, i] = (x[:, i] + np.pi) % (2 * np.pi) - np.pi
        return x

    def start(self, x0: np.ndarray) -> None:
        """Any state will do."""
