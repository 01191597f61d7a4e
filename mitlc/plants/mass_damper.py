"""The mass-damper of appendix A-1 (the system of chapter 3)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mitlc.plants.base import Plant, StateVar, register

__all__ = ["MASS_DAMPER"]


def _mass_damper(x: np.ndarray, u: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    # M qdd = -B qd + u
    qd = x[:, 1]
    return np.stack([qd, (-p["B"] * qd + u) / p["M"]], axis=1)


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
    )
)
