"""The mass-damper of appendix A-1 (the system of chapter 3)."""

from __future__ import annotations

import numpy as np

from mitlc.plants.base import Plant, StateVar, ode_dynamics, register, rk4_kernel_step

__all__ = ["MASS_DAMPER"]


PARAMS = ("M", "B")


def _mass_damper_ode(x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """(A-1): M qdd = -B qd + u, over the state's first axis (p: M, B); the physics, once."""
    out[0] = x[1]
    out[1] = (-p[1] * x[1] + u) / p[0]


_mass_damper = ode_dynamics(_mass_damper_ode, PARAMS)


MASS_DAMPER = register(
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
        kernel_step=rk4_kernel_step(_mass_damper_ode, PARAMS),
    )
)
