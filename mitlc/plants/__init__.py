"""Plants: the dynamical systems a spec talks about.

In: nothing (the first stage). Out: :class:`Plant` (state variables with bounds,
inputs with their boxes (:class:`InputVar`), parameters, a batched RK4 ``step``) in the registry :data:`PLANTS`, and
:func:`make_integrator`, the fastest in-place one-step map a plant offers (the
pendulum's fused RK4, :mod:`mitlc.plants.pendulum`).

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`.

Add a plant: a module here with its dynamics and a :func:`register` call (see
:mod:`mitlc.plants.mass_damper`), imported below.
"""

from mitlc.plants.base import PLANTS, InputVar, Plant, StateVar, make_integrator, register, wrap_angle
from mitlc.plants.cart import CART
from mitlc.plants.cartpole import CARTPOLE
from mitlc.plants.mass_damper import MASS_DAMPER
from mitlc.plants.pendulum import PENDULUM
from mitlc.plants.unicycle import UNICYCLE

__all__ = [
    "CART",
    "CARTPOLE",
    "MASS_DAMPER",
    "PENDULUM",
    "UNICYCLE",
    "PLANTS",
    "InputVar",
    "Plant",
    "StateVar",
    "make_integrator",
    "register",
    "wrap_angle",
]
