"""The cart-pole of Barto, Sutton and Anderson (1983): a pole hinged on a cart, one force.

State ``x`` (cart position, m), ``xdot`` (m/s), ``theta`` (the pole's angle from upright,
rad, positive when it leans towards +x; an angle, wrapped to ``[-pi, pi)``) and ``thetadot``
(rad/s); the input ``u`` is the force on the cart in N, clipped to ``+-u_max``. The
equations are the frictionless ones of the paper (and of Gymnasium's CartPole), with
``l`` the half-length of the pole and ``M = mc + mp``::

    tmp      = (u + mp l thetadot^2 sin theta) / M
    thetadd  = (g sin theta - cos theta tmp) / (l (4/3 - mp cos^2 theta / M))
    xdd      = tmp - mp l thetadd cos theta / M

integrated with RK4 (Gymnasium steps them with Euler). The track is the state bound
``x in [-2.4, 2.4]`` of the benchmark; like every bound here it sets the learner's
features and the compiler's interval analysis, and staying on the track is a spec's
proposition. Nothing but the input is clipped.

>>> import numpy as np
>>> from mitlc.plants import PLANTS
>>> p = PLANTS["cartpole"]
>>> p.state_names
('x', 'xdot', 'theta', 'thetadot')
>>> y = p.step(np.array([[0.0, 0.0, 0.1, 0.0]]), np.zeros(1), p.params())
>>> bool(y[0, 2] > 0.1 and y[0, 1] < 0.0)  # the pole falls further, pushing the cart back
True
"""

from __future__ import annotations

import math

import numpy as np

from mitlc.plants.base import Plant, StateVar, ode_dynamics, register, rk4_kernel_step

__all__ = ["CARTPOLE"]


PARAMS = ("g", "mc", "mp", "l")


def _cartpole_ode(x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """Barto et al. (1983), frictionless, over the state's first axis (p: g, mc, mp, l)."""
    g, mc, mp, ll = p[0], p[1], p[2], p[3]
    total = mc + mp
    s = np.sin(x[2])
    c = np.cos(x[2])
    tmp = (u + mp * ll * x[3] * x[3] * s) / total
    thetadd = (g * s - c * tmp) / (ll * (4.0 / 3.0 - mp * c * c / total))
    out[0] = x[1]
    out[1] = tmp - mp * ll * thetadd * c / total
    out[2] = x[3]
    out[3] = thetadd


_cartpole = ode_dynamics(_cartpole_ode, PARAMS)


CARTPOLE = register(
    Plant(
        name="cartpole",
        # The benchmark's numbers: g = 9.8, a 1 kg cart, a 0.1 kg pole of half-length 0.5 m,
        # at most 10 N, sampled at 50 Hz (Gymnasium's CartPole-v1 has the same).
        state=(
            StateVar("x", -2.4, 2.4),
            StateVar("xdot", -5.0, 5.0),
            StateVar("theta", -math.pi, math.pi, periodic=True),
            StateVar("thetadot", -10.0, 10.0),
        ),
        defaults={"g": 9.8, "mc": 1.0, "mp": 0.1, "l": 0.5, "u_max": 10.0, "dt": 0.02},
        dynamics=_cartpole,
        description=(
            "cart-pole of Barto, Sutton and Anderson (mc = 1 kg, mp = 0.1 kg, half-length l = 0.5 m); "
            "x in m, theta in rad from upright (positive leaning to +x)"
        ),
        default_spec="cartpole/balance.mitl",
        kernel_step=rk4_kernel_step(_cartpole_ode, PARAMS),
    )
)
