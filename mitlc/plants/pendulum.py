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

from mitlc.plants.base import Plant, StateVar, ode_dynamics, pairwise_sum_for, register

__all__ = ["PENDULUM"]


PARAMS = ("J", "M", "g", "l", "b", "K", "R")


def _pendulum_ode(x: np.ndarray, u: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """(A-2): J qdd = M g l sin(q) - (b + K^2/R) qd + (K/R) u, q from upright; over the
    state's first axis, p in ``PARAMS`` order (:func:`~mitlc.plants.base.ode_dynamics`)."""
    out[0] = x[1]
    out[1] = (p[1] * p[2] * p[3] * np.sin(x[0]) - (p[4] + p[5] ** 2 / p[6]) * x[1] + p[5] / p[6] * u) / p[0]


_pendulum = ode_dynamics(_pendulum_ode, PARAMS)


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


def _fused_constants(plant: Plant, p: Mapping[str, float]) -> tuple[list[np.ndarray], np.ndarray]:
    """The fused step's stage rows (``q_2, q_3, q_4`` from the first 5, 6, 7 basis entries)
    and its final 2 x 8 map, with (A-2)'s constants folded and the wrap's ``+ pi``."""
    J = p["J"]
    a = p["M"] * p["g"] * p["l"] / J
    b = (p["b"] + p["K"] ** 2 / p["R"]) / J
    c = p["K"] / p["R"] / J
    stages, final = _rk4_pendulum_coefficients(b, p["dt"])
    for m in (stages, final):
        m[:, 4:] *= a  # the basis holds sin q_i
        m[:, 2] *= c  # ... and the saturated u
    final[0, 3] += math.pi  # q' + pi, ready for the wrap
    return [np.ascontiguousarray(stages[i, : 5 + i]) for i in range(3)], np.ascontiguousarray(final)


def _pendulum_rk4(plant: Plant, p: Mapping[str, float]) -> Callable[[np.ndarray, np.ndarray], None]:
    """The pendulum's RK4 step (A-2) with its linear part folded into small matrices.

    Per step: four ``sin`` and four small products-and-sums instead of ~50
    elementwise operations; the same equations as :meth:`Plant.step` (agrees
    to rounding, tested).  The wrap's ``+ pi`` rides in the final product.
    The sums are numpy's pairwise ``add.reduce`` along each run's basis row, not
    a BLAS product, whose order depends on the CPU: so :func:`_pendulum_kernel`
    (the same step for one run, compiled) gives the same numbers to the bit.
    """
    u_max = p["u_max"]
    stage_rows, final = _fused_constants(plant, p)
    v_lo, v_hi = plant.var("qdot").lo, plant.var("qdot").hi
    clip_v = "qdot" in plant.clip
    two_pi, pi = 2 * math.pi, math.pi
    bufs: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    sin, minimum, maximum, multiply, reduce = np.sin, np.minimum, np.maximum, np.multiply, np.add.reduce

    def step(x: np.ndarray, u: np.ndarray) -> None:
        R = x.shape[0]
        b = bufs.get(R)
        if b is None:
            b = bufs[R] = (np.empty((R, 8)), np.empty((R, 8)))
            b[0][:, 3] = 1.0
        S, T = b
        S[:, 0:2] = x
        minimum(u, u_max, out=S[:, 2])
        maximum(S[:, 2], -u_max, out=S[:, 2])
        sin(S[:, 0], out=S[:, 4])
        for i in range(3):
            n = 5 + i
            multiply(S[:, :n], stage_rows[i], out=T[:, :n])
            reduce(T[:, :n], axis=1, out=S[:, n])
            sin(S[:, n], out=S[:, n])
        for j in range(2):
            multiply(S, final[j], out=T)
            reduce(T, axis=1, out=x[:, j])
        q = x[:, 0]
        np.remainder(q, two_pi, out=q)
        q -= pi
        if clip_v:
            v = x[:, 1]
            minimum(v, v_hi, out=v)
            maximum(v, v_lo, out=v)

    return step


def _pendulum_kernel(plant: Plant, p: Mapping[str, float], jit: Callable) -> tuple[Callable, np.ndarray, int]:
    """:func:`_pendulum_rk4` for one run as plain Python (:attr:`Plant.kernel_step`): the
    same constants, products and pairwise sums in the same order, so the same numbers."""
    stage_rows, final = _fused_constants(plant, p)
    v = plant.var("qdot")
    consts = np.concatenate(
        [[p["u_max"], 1.0 if "qdot" in plant.clip else 0.0, v.lo, v.hi], *stage_rows, final[0], final[1]]
    )
    psum = pairwise_sum_for(jit)
    two_pi, pi = 2 * math.pi, math.pi

    def step(x: np.ndarray, u: float, c: np.ndarray, w: np.ndarray) -> None:
        S, T = w[0:8], w[8:16]
        u_max = c[0]
        S[0] = x[0]
        S[1] = x[1]
        S[2] = np.maximum(np.minimum(u, u_max), -u_max)
        S[3] = 1.0
        S[4] = np.sin(S[0])
        at = 4
        for i in range(3):
            n = 5 + i
            for j in range(n):
                T[j] = S[j] * c[at + j]
            S[n] = np.sin(psum(T, 0, n))
            at += n
        for k in range(2):
            for j in range(8):
                T[j] = S[j] * c[at + j]
            x[k] = psum(T, 0, 8)
            at += 8
        x[0] = x[0] % two_pi - pi
        if c[1] != 0.0:
            x[1] = np.maximum(np.minimum(x[1], c[3]), c[2])

    return jit(step), consts, 16


PENDULUM = register(
    Plant(
        name="pendulum",
        state=(
            StateVar("q", -math.pi, math.pi, periodic=True),
            StateVar("qdot", -15 * math.pi, 15 * math.pi, grid=(-20.0, 20.0)),
        ),
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
        kernel_step=_pendulum_kernel,
    )
)
