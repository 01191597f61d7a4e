"""The DCSC pendulum of appendix A-2, with its fused RK4 step.

>>> import numpy as np
>>> from mitlc.plants import PLANTS, make_integrator
>>> p = PLANTS["pendulum"]
>>> x = np.array([[2.5, 0.0], [-1.0, 3.0]])
>>> step = make_integrator(p, p.params())
>>> y = x.copy(); step(y, np.array([1.0, -2.0]))
>>> bool(np.allclose(y, p.step(x.copy(), np.array([1.0, -2.0]), p.params())))
True
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import numpy as np

from mitlc.plants.base import Plant, StateVar, register

__all__ = ["PENDULUM"]


def _pendulum(x: np.ndarray, u: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    # J qdd = M g l sin(q) - (b + K^2/R) qd + (K/R) u, q from upright.
    q, qd = x[:, 0], x[:, 1]
    qdd = (p["M"] * p["g"] * p["l"] * np.sin(q) - (p["b"] + p["K"] ** 2 / p["R"]) * qd + p["K"] / p["R"] * u) / p["J"]
    return np.stack([qd, qdd], axis=1)


def _rk4_pendulum_coefficients(b: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """RK4 of ``q' = v, v' = sigma - b v + U`` as linear maps.

    Every RK4 quantity of the pendulum is linear in the basis
    ``[q, v, U, 1, sigma_1, sigma_2, sigma_3, sigma_4]`` with ``U = c u`` and
    ``sigma_i = a sin q_i`` at the stage angles ``q_i``: only the sines are
    not linear.  Returns the rows giving the stage angles ``q_2, q_3, q_4``
    (3 x 8) and the step's ``[q', v']`` (2 x 8).
    """
    n = 8
    e = np.eye(n)
    q0, v0, cu = e[0], e[1], e[2]
    sig = [e[4 + i] for i in range(4)]

    def k(yq: np.ndarray, yv: np.ndarray, i: int) -> tuple[np.ndarray, np.ndarray]:
        return yv, sig[i] + cu - b * yv

    k1 = k(q0, v0, 0)
    y2 = (q0 + h / 2 * k1[0], v0 + h / 2 * k1[1])
    k2 = k(*y2, 1)
    y3 = (q0 + h / 2 * k2[0], v0 + h / 2 * k2[1])
    k3 = k(*y3, 2)
    y4 = (q0 + h * k3[0], v0 + h * k3[1])
    k4 = k(*y4, 3)
    q1 = q0 + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
    v1 = v0 + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return np.stack([y2[0], y3[0], y4[0]]), np.stack([q1, v1])


def _pendulum_rk4(plant: Plant, p: Mapping[str, float]) -> Callable[[np.ndarray, np.ndarray], None]:
    """The pendulum's RK4 step (A-2) with its linear part folded into small matrices.

    Per step: four ``sin`` and four tiny matrix products instead of ~50
    elementwise operations; the same equations as :meth:`Plant.step` (agrees
    to rounding, tested).  The wrap's ``+ pi`` rides in the final product.
    """
    J = p["J"]
    a = p["M"] * p["g"] * p["l"] / J
    b = (p["b"] + p["K"] ** 2 / p["R"]) / J
    c = p["K"] / p["R"] / J
    dt, u_max = p["dt"], p["u_max"]
    stages, final = _rk4_pendulum_coefficients(b, dt)
    for m in (stages, final):
        m[:, 4:] *= a  # the basis holds sin q_i
        m[:, 2] *= c  # ... and the saturated u
    final[0, 3] += math.pi  # q' + pi, ready for the wrap
    stage_rows = [np.ascontiguousarray(stages[i, : 5 + i][None, :]) for i in range(3)]
    v_lo, v_hi = plant.var("qdot").lo, plant.var("qdot").hi
    clip_v = "qdot" in plant.clip
    two_pi, pi = 2 * math.pi, math.pi
    bufs: dict[int, np.ndarray] = {}
    sin, minimum, maximum, matmul = np.sin, np.minimum, np.maximum, np.matmul

    def step(x: np.ndarray, u: np.ndarray) -> None:
        R = x.shape[0]
        S = bufs.get(R)
        if S is None:
            S = bufs[R] = np.empty((8, R))
            S[3] = 1.0
        xt = x.T
        S[0:2] = xt
        minimum(u, u_max, out=S[2])
        maximum(S[2], -u_max, out=S[2])
        sin(S[0], out=S[4])
        for i in range(3):
            matmul(stage_rows[i], S[: 5 + i], out=S[5 + i : 6 + i])
            sin(S[5 + i], out=S[5 + i])
        matmul(final, S, out=xt)
        q = xt[0]
        np.remainder(q, two_pi, out=q)
        q -= pi
        if clip_v:
            v = xt[1]
            minimum(v, v_hi, out=v)
            maximum(v, v_lo, out=v)

    return step


PENDULUM = register(
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
        fast_step=_pendulum_rk4,
    )
)
