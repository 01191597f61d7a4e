"""A cart on a rail with viscous friction, pushed by one force (the cart of docs/architecture.md).

``m qdd = -c qd + u``: ``q`` the position in m, ``qdot`` the velocity in m/s, ``u`` the
force in N (clipped to ``+-u_max``). Nothing else is clipped: the state bounds set the
learner's feature grid and the compiler's interval analysis, and a wall is a spec's
proposition, not the plant's.

>>> import numpy as np
>>> from mitlc.plants import PLANTS
>>> p = PLANTS["rail-cart"]
>>> p.state_names
('q', 'qdot')
>>> x = np.array([[0.0, 1.0]])            # rolling at 1 m/s, no force: friction slows it
>>> y = p.step(x.copy(), np.zeros(1), p.params())
>>> bool(0.0 < y[0, 1] < 1.0 and y[0, 0] > 0.0)
True
"""

from __future__ import annotations

import numpy as np

from mitlc.plants.base import Plant, StateVar, ode_dynamics, register, rk4_kernel_step

__all__ = ["CART"]


PARAMS = ("m", "c")


def _cart_ode(x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """``m qdd = -c qd + u``, over the state's first axis (p: m, c)."""
    out[0] = x[1]
    out[1] = (-p[1] * x[1] + u) / p[0]


_cart = ode_dynamics(_cart_ode, PARAMS)


CART = register(
    Plant(
        name="rail-cart",
        # The cart of docs/architecture.md: 1 kg, friction 0.1 N s/m, at most 5 N, sampled
        # at 20 Hz. Named rail-cart, not cart: examples/cart/cart_plant.py is a user's plant
        # file that registers its own 'cart' (state x, v), and a shipped plant of that name
        # would stand in for the user's (docs/plants.md).
        state=(StateVar("q", -2.0, 2.0), StateVar("qdot", -4.0, 4.0)),
        defaults={"m": 1.0, "c": 0.1, "u_max": 5.0, "dt": 0.05},
        dynamics=_cart,
        description="a cart on a rail with viscous friction (m = 1 kg, c = 0.1 N s/m); q in m, qdot in m/s",
        default_spec="cart/park.mitl",
        kernel_step=rk4_kernel_step(_cart_ode, PARAMS),
    )
)
