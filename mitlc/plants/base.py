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

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["StateVar", "Plant", "PLANTS", "register", "wrap_angle", "make_integrator"]


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
