"""A kinematic unicycle: mitlc's plant with two inputs, a forward speed and a turn rate.

The state is the position ``(x, y)`` in metres and the heading ``theta`` in radians
(an angle, wrapped to ``[-pi, pi)``); the inputs are the speed ``v`` along the heading
and the turn rate ``omega``, each in its own box::

    xdot = v cos(theta),    ydot = v sin(theta),    thetadot = omega

The model is the textbook one of wheeled robots (a differential-drive base, the
unicycle of LaValle, *Planning Algorithms*, 2006, section 13.1.2.3): no mass, no slip,
the inputs act at once. The arena is the square ``[-2, 2]^2``; ``x`` and ``y`` are
clipped to it (walls that stop the robot, not reflect it), so a learner cannot leave
its feature grid.

>>> import numpy as np
>>> from mitlc.plants import PLANTS
>>> p = PLANTS["unicycle"]
>>> p.input_names, p.n_inputs
(('v', 'omega'), 2)
>>> x = np.array([[0.0, 0.0, 0.0]])
>>> p.step(x, np.array([[1.0, 0.0]]), p.params()).round(6).tolist()   # straight ahead, 0.1 s at 1 m/s
[[0.1, 0.0, 0.0]]
"""

from __future__ import annotations

import numpy as np

from mitlc.plants.base import InputVar, Plant, StateVar, ode_dynamics, register, rk4_kernel_step

__all__ = ["UNICYCLE"]


PARAMS: tuple[str, ...] = ()
"""The ODE reads no parameters: the model has none besides ``dt``."""


def _unicycle_ode(x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """``xdot = v cos(theta), ydot = v sin(theta), thetadot = omega``, over the first axis
    (``u[0] = v``, ``u[1] = omega``; :func:`~mitlc.plants.base.ode_dynamics`); the physics, once."""
    out[0] = u[0] * np.cos(x[2])
    out[1] = u[0] * np.sin(x[2])
    out[2] = u[1]


_unicycle = ode_dynamics(_unicycle_ode, PARAMS)


UNICYCLE = register(
    Plant(
        name="unicycle",
        # The arena [-2, 2]^2 with its walls (x, y clipped) and the heading as an angle;
        # a speed of at most 1 m/s forwards or backwards and a turn rate of at most
        # 2 rad/s (a small indoor robot's; a half turn takes 1.6 s); dt = 0.1 s, the
        # rate of such a robot's velocity commands.
        state=(
            StateVar("x", -2.0, 2.0),
            StateVar("y", -2.0, 2.0),
            StateVar("theta", -np.pi, np.pi, periodic=True),
        ),
        defaults={"dt": 0.1},
        dynamics=_unicycle,
        inputs=(InputVar("v", -1.0, 1.0), InputVar("omega", -2.0, 2.0)),
        description="kinematic unicycle in the arena [-2, 2]^2; x, y in m, theta in rad; "
        "inputs v in m/s, omega in rad/s",
        default_spec="unicycle/reach_avoid.mitl",
        clip=("x", "y"),
        kernel_step=rk4_kernel_step(_unicycle_ode, PARAMS),
    )
)
