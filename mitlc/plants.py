"""Plants: the dynamical systems a spec talks about.

A plant declares its state variables with their bounds (used by the compiler's
interval analysis and by the learner's features), which of them are angles
(periodic), its parameters with defaults, and a vectorised ``step``.

To add a plant, subclass :class:`Plant` (or build one) and :func:`register` it:

>>> import numpy as np
>>> p = PLANTS["pendulum"]
>>> p.state_names
('q', 'qdot')
>>> x = np.array([[-np.pi, 0.0]])         # hanging down, at rest
>>> np.allclose(p.step(x, np.zeros(1), p.params()), x)
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

__all__ = ["StateVar", "Plant", "PLANTS", "register", "wrap_angle"]


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


def _pendulum(x: np.ndarray, u: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    # J qdd = M g l sin(q) - (b + K^2/R) qd + (K/R) u, q from upright.
    q, qd = x[:, 0], x[:, 1]
    qdd = (
        p["M"] * p["g"] * p["l"] * np.sin(q) - (p["b"] + p["K"] ** 2 / p["R"]) * qd + p["K"] / p["R"] * u
    ) / p["J"]
    return np.stack([qd, qdd], axis=1)


def _mass_damper(x: np.ndarray, u: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    # M qdd = -B qd + u
    qd = x[:, 1]
    return np.stack([qd, (-p["B"] * qd + u) / p["M"]], axis=1)


PLANTS: dict[str, Plant] = {}


def register(plant: Plant) -> Plant:
    """Make ``plant`` available to specs (``plant NAME``) and the CLI."""
    PLANTS[plant.name] = plant
    return plant


register(
    Plant(
        name="pendulum",
        state=(StateVar("q", -math.pi, math.pi, periodic=True), StateVar("qdot", -15 * math.pi, 15 * math.pi)),
        defaults={
            "J": 1.91e-4,
            "M": 5.50e-2,
            "g": 9.81,
            "l": 4.20e-2,
            "b": 3e-6,
            "K": 5.36e-2,
            "R": 9.50,
            "u_max": 3.0,
            "dt": 0.03,
        },
        dynamics=_pendulum,
        description="DCSC pendulum of appendix A-2; q in rad from upright, qdot bounded to 15 pi rad/s",
        default_spec="pendulum/p2_avoid.mitl",
        clip=("qdot",),
    )
)

register(
    Plant(
        name="mass-damper",
        # q in [-1, 1] m and qdot in [-5, 5] m/s: thesis section 3-1 (example 1, the
        # system of chapter 3); dt = 0.03 s: Table 3-2.  The thesis gives no input bound
        # for the mass-damper (its input plots are lost figures): u_max = 10 N is
        # chapter 4's bound, an assumption.  Nothing is clipped: the bounds set the
        # learner's feature grid, not the physics.
        state=(StateVar("q", -1.0, 1.0), StateVar("qdot", -5.0, 5.0)),
        defaults={"M": 0.5, "B": 0.05, "u_max": 10.0, "dt": 0.03},
        dynamics=_mass_damper,
        description="mass-damper of appendix A-1 (M = 0.5 kg, B = 0.05 N s/m); q in m, qdot in m/s",
        default_spec="mass_damper/overshoot.mitl",
    )
)
