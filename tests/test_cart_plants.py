"""The shipped rail cart and cart-pole: their steps against values worked out by hand (and the cart-pole's
equations against Gymnasium's CartPole), their compiled one-copy step bit for bit against the batched one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mitlc.learn.sacpn import kernel as fk
from mitlc.plants import PLANTS, make_integrator
from mitlc.spec.parse import load_spec

CART = PLANTS["rail-cart"]
POLE = PLANTS["cartpole"]


def test_the_cart_steps_as_rk4_of_its_linear_ode() -> None:
    """``m qdd = -c qd + u`` is linear, ``x' = A x + b``: RK4 over ``h`` is ``sum_k<=4 (hA)^k / k! x +
    sum_1<=k<=4 h^k A^(k-1) / k! b``; with ``A = [[0, 1], [0, a]]``, ``b = [0, u/m]``, worked out for
    ``m = 2, c = 0.5, h = 0.1``."""
    p = CART.params({"m": 2.0, "c": 0.5, "dt": 0.1})
    x = np.array([[0.3, -1.2], [0.0, 0.0], [-1.0, 2.0]])
    u = np.array([4.0, -1.0, 9.0])  # 9 N is clipped to u_max = 5 N
    got = CART.step(x.copy(), u, p)
    a, h = -0.25, 0.1  # qdd = a qd + u / m
    ha = h * a
    e = 1 + ha + ha**2 / 2 + ha**3 / 6 + ha**4 / 24  # ~ exp(h a): the velocity's factor
    g = h * (1 + ha / 2 + ha**2 / 6 + ha**3 / 24)  # ~ (exp(h a) - 1) / a
    f = h**2 * (1 / 2 + ha / 6 + ha**2 / 24)  # the position's, ~ (exp(h a) - 1 - h a) / a^2
    for (q, v), force, (q1, v1) in zip(x, np.clip(u, -5, 5), got, strict=True):
        assert v1 == pytest.approx(e * v + g * force / 2, rel=1e-13, abs=1e-15)
        assert q1 == pytest.approx(q + g * v + f * force / 2, rel=1e-13, abs=1e-15)
    exact_v = 4 / 0.5 + (-1.2 - 4 / 0.5) * math.exp(-0.25 * 0.1)  # u/c + (v0 - u/c) exp(-c h / m)
    assert got[0, 1] == pytest.approx(exact_v, abs=1e-9)  # and RK4 is that close to the exact solution


def _cartpole_by_hand(theta: float, thetadot: float, u: float) -> tuple[float, float]:
    """Barto et al. (1983): ``(xdd, thetadd)`` with the default parameters, g = 9.8, mc = 1, mp = 0.1, l = 0.5."""
    total, mpl = 1.1, 0.1 * 0.5
    s, c = math.sin(theta), math.cos(theta)
    tmp = (u + mpl * thetadot**2 * s) / total
    thetadd = (9.8 * s - c * tmp) / (0.5 * (4 / 3 - 0.1 * c * c / total))
    return tmp - mpl * thetadd * c / total, thetadd


def test_the_cartpole_dynamics_by_hand() -> None:
    p = POLE.params()
    # theta = pi/6: sin = 1/2, cos = sqrt(3)/2; thetadot = 2, u = 3 N
    # tmp = (3 + 0.05 * 4 * 0.5) / 1.1 = 3.1 / 1.1; thetadd = (4.9 - sqrt(3)/2 tmp) / (0.5 (4/3 - 0.1 * 0.75 / 1.1))
    tmp = 3.1 / 1.1
    thetadd = (4.9 - math.sqrt(3) / 2 * tmp) / (0.5 * (4 / 3 - 0.075 / 1.1))
    xdd = tmp - 0.05 * thetadd * math.sqrt(3) / 2 / 1.1
    x = np.array([[0.5, -0.25, math.pi / 6, 2.0]])
    d = POLE.dynamics(x, np.array([3.0]), p)[0]
    assert d[0] == -0.25 and d[2] == 2.0
    assert d[1] == pytest.approx(xdd, rel=1e-14) and d[3] == pytest.approx(thetadd, rel=1e-14)
    assert (xdd, thetadd) == pytest.approx(_cartpole_by_hand(math.pi / 6, 2.0, 3.0), rel=1e-14)
    # at rest upright and hanging: an equilibrium without force; a push to +x tips the pole to -theta
    rest = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, -math.pi, 0.0]])
    assert np.allclose(POLE.step(rest.copy(), np.zeros(2), p), rest, rtol=0, atol=1e-15)  # sin(-pi) is 1e-16
    push = POLE.dynamics(np.zeros((1, 4)), np.array([10.0]), p)[0]
    assert push[1] > 0 and push[3] < 0


def test_the_cartpole_step_is_rk4_of_the_equations_and_wraps_the_angle() -> None:
    p = POLE.params()
    h = p["dt"]

    def f(s: np.ndarray, u: float) -> np.ndarray:
        xdd, thetadd = _cartpole_by_hand(s[2], s[3], u)
        return np.array([s[1], xdd, s[3], thetadd])

    for s0, u in [((0.2, 0.1, 0.3, -0.5), 4.0), ((-1.0, 1.5, 3.1, 6.0), -25.0), ((0.0, 0.0, -3.1, -6.0), 2.0)]:
        s = np.array(s0, dtype=float)
        uc = float(np.clip(u, -10, 10))
        k1 = f(s, uc)
        k2 = f(s + h / 2 * k1, uc)
        k3 = f(s + h / 2 * k2, uc)
        k4 = f(s + h * k3, uc)
        want = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        want[2] = (want[2] + math.pi) % (2 * math.pi) - math.pi
        got = POLE.step(s[None, :].copy(), np.array([u]), p)[0]
        assert got == pytest.approx(want, rel=1e-12, abs=1e-12)
        assert -math.pi <= got[2] < math.pi


def test_the_cartpole_equations_are_gymnasiums() -> None:
    """Gymnasium's CartPole-v1 steps the same equations with Euler over tau = 0.02 s and a force of +-10 N:
    one of its steps gives the accelerations, which must be ours."""
    gym = pytest.importorskip("gymnasium")
    env = gym.make("CartPole-v1").unwrapped
    env.reset(seed=0)
    p = POLE.params()
    for state, action in [((0.1, -0.3, 0.05, 0.4), 1), ((-0.5, 0.2, -0.15, -1.0), 0), ((0.0, 0.0, 0.2, 0.0), 1)]:
        env.state = np.array(state)
        env.step(action)
        xdd = (env.state[1] - state[1]) / env.tau
        thetadd = (env.state[3] - state[3]) / env.tau
        ours = POLE.dynamics(np.array([state]), np.array([10.0 if action else -10.0]), p)[0]
        assert ours[1] == pytest.approx(xdd, rel=1e-9) and ours[3] == pytest.approx(thetadd, rel=1e-9)
    env.close()


@pytest.mark.parametrize("plant", ["rail-cart", "cartpole"])
def test_the_kernel_step_is_the_batched_step_bit_for_bit(plant: str) -> None:
    pl = PLANTS[plant]
    p = pl.params()
    rng = np.random.default_rng(0)
    x = rng.uniform([v.lo for v in pl.state], [v.hi for v in pl.state], (200, len(pl.state)))
    u = rng.uniform(-2 * p["u_max"], 2 * p["u_max"], 200)
    batched = x.copy()
    make_integrator(pl, p)(batched, u)
    assert pl.kernel_step is not None
    step, consts, work = pl.kernel_step(pl, p, fk.identity)
    one = x.copy()
    scratch = np.empty(work)
    for r in range(len(u)):
        step(one[r], u[r], consts, scratch)
    assert np.array_equal(one, batched)
    assert np.array_equal(batched, pl.step(x.copy(), u, p))


@pytest.mark.parametrize("plant", ["rail-cart", "cartpole"])
def test_the_default_specs_load_and_compile(plant: str) -> None:
    from mitlc.petri.compile import compile_spec

    pl = PLANTS[plant]
    assert pl.default_spec is not None
    spec = load_spec(pl.default_spec.removesuffix(".mitl"))
    assert spec.plant is pl
    assert compile_spec(spec).net.places
