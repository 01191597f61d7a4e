"""A cart on a rail, as a user would write a plant of their own (docs/plants.md).

    mitlc plants --plant-file examples/cart/cart_plant.py
    mitlc train --plant-file examples/cart/cart_plant.py --spec examples/cart/cart.mitl

The state is the position x (m) and the velocity v (m/s); the input u is a force (N),
with friction b and mass m:  x' = v,  v' = (u - b v) / m.  The bounds of the state
set the learner's feature grid and the compiler's interval analysis; nothing is
clipped but the input (to +-u_max).
"""

import numpy as np

from mitlc.plants import Plant, StateVar


def cart_dynamics(x, u, p):
    """``xdot`` for a batch: ``x`` is (R, 2) = [position, velocity], ``u`` is (R,)."""
    v = x[:, 1]
    return np.stack([v, (u - p["b"] * v) / p["m"]], axis=1)


CART = Plant(
    name="cart",
    state=(StateVar("x", -2.0, 2.0), StateVar("v", -3.0, 3.0)),
    defaults={"m": 1.0, "b": 0.5, "u_max": 2.0, "dt": 0.05},
    dynamics=cart_dynamics,
    description="a cart on a rail (m = 1 kg, friction b = 0.5 N s/m); x in m, v in m/s",
)
