"""A witness per task: a fixed controller the monitor accepts from every start of the task's spread.

``witness(x, t, params) -> u``: ``x`` the states ``(R, n)`` in the spec's state order, ``t``
the time in seconds since the start, ``params`` the plant's parameters with the spec's
overrides; ``u`` the inputs ``(R,)`` (``(R, m)`` for a plant of ``m`` inputs), each clipped to
its box (``+-u_max`` for a plant bounded by ``u_max``). A witness is a feedback law (sometimes
with a schedule of targets in ``t``): it proves the task satisfiable, and is no claim to be a
good controller.

The building blocks are the textbook ones: feedback linearisation with a PD law for the
pendulum, PD and velocity-limited tracking for the mass-damper and the cart, an energy
pump for swinging up, LQR for the cart-pole (gains from the linearisation at upright,
computed once with scipy and written here), pushing along the velocity for the
mountain car, and for the unicycle go-to-point steering (the turn rate in proportion to the
wrapped heading error, the speed scaled by the distance and the alignment) towards waypoints
chosen by time or by position, and a vector field round a circle.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import numpy as np

from mitlc.plants import PLANTS

Params = Mapping[str, float]
Witness = Callable[[np.ndarray, float, Params], np.ndarray]

WITNESSES: dict[str, Witness] = {}


def witness(fn: Witness) -> Witness:
    """Register ``fn`` as the witness of the task of its name."""
    WITNESSES[fn.__name__] = fn
    return fn


def _clip(u: np.ndarray, p: Params) -> np.ndarray:
    return np.clip(u, -p["u_max"], p["u_max"])


def _wrap(q: np.ndarray) -> np.ndarray:
    return (q + np.pi) % (2 * np.pi) - np.pi


# ------------------------------------------------------------------ the DCSC pendulum
# J qdd = M g l sin q - (b + K^2/R) qd + (K/R) u, q from upright: qdd = a sin q - d qd + c u.


def _pend(p: Params) -> tuple[float, float, float]:
    a = p["M"] * p["g"] * p["l"] / p["J"]
    d = (p["b"] + p["K"] ** 2 / p["R"]) / p["J"]
    c = p["K"] / p["R"] / p["J"]
    return a, d, c


def _pend_track(x: np.ndarray, p: Params, err: np.ndarray, kp: float, kd: float, v_max: float = np.inf) -> np.ndarray:
    """Feedback linearisation: the input that makes ``qdd = kd (v* - qd)``, ``v* = clip(-kp/kd err)``
    (a PD law with its speed limited to ``v_max``), clipped to the motor's bound."""
    a, d, c = _pend(p)
    q, qd = x[:, 0], x[:, 1]
    v_star = np.clip(-kp / kd * err, -v_max, v_max)
    acc = kd * (v_star - qd)
    return _clip((acc - a * np.sin(q) + d * qd) / c, p)


def _pend_energy_pump(x: np.ndarray, p: Params, gain: float = 4.0) -> np.ndarray:
    """Swing-up by energy: ``E = qd^2/2 + a cos q`` is ``a`` at rest upright; ``dE/dt = qd (c u - d qd)``,
    so pushing along ``qd`` (in proportion to the energy missing, saturating at ``u_max`` while a
    quarter or more is missing) and making up for the damping pumps it up."""
    a, d, c = _pend(p)
    q, qd = x[:, 0], x[:, 1]
    e = 0.5 * qd**2 + a * np.cos(q)
    push = np.where(qd >= 0, 1.0, -1.0)
    return _clip(push * p["u_max"] * np.clip(gain * (a - e) / a, 0.0, 1.0) + d * qd / c, p)


@witness
def pendulum_swing_up_avoid(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """Up the long way (through the bottom, q past pi to -pi, then up to 0), never through the obstacle
    on the positive side: the angle error is measured going round the negative side."""
    q = x[:, 0]
    err = np.where(q > 0.25, q - 2 * np.pi, q)
    return _pend_track(x, p, err, kp=60.0, kd=15.0, v_max=14.0)


@witness
def pendulum_horizontal_then_up(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """To the horizontal on the positive side, held there until 1.4 s, then up."""
    q = x[:, 0]
    target = np.pi / 2 if t < 1.4 else 0.0
    return _pend_track(x, p, _wrap(q - target), kp=80.0, kd=18.0, v_max=8.0)


@witness
def pendulum_weak_swing_up(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """Pump energy until near the top, then catch it with a PD law."""
    q = x[:, 0]
    near = np.abs(q) < 0.6
    return np.where(near, _pend_track(x, p, q, kp=60.0, kd=15.0), _pend_energy_pump(x, p))


@witness
def pendulum_bounded_response(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """A stiff PD law at the top."""
    return _pend_track(x, p, x[:, 0], kp=150.0, kd=25.0)


@witness
def pendulum_alternate(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """Left and right horizontal in turn, 0.6 s each, going round through the top."""
    target = -np.pi / 2 if int(t / 0.6) % 2 == 0 else np.pi / 2
    return _pend_track(x, p, _wrap(x[:, 0] - target), kp=100.0, kd=20.0)


@witness
def pendulum_slow_until_up(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """Straight up the short way, at most 8 rad/s."""
    return _pend_track(x, p, _wrap(x[:, 0]), kp=60.0, kd=15.0, v_max=8.0)


# ------------------------------------------------------------------ a mass on a line: the mass-damper, the cart
# m qdd = -c qd + u: the mass-damper (M, B) and the rail cart (m, c) alike.


def _line_track(
    x: np.ndarray, p: Params, target: float | np.ndarray, kp: float, kd: float, v_max: float = np.inf
) -> np.ndarray:
    """The force that makes ``qdd = kd (v* - qd)``, ``v* = clip(-kp/kd (q - target))``: a PD law towards
    ``target`` with its speed limited to ``v_max``."""
    m, c = (p["M"], p["B"]) if "M" in p else (p["m"], p["c"])
    q, qd = x[:, 0], x[:, 1]
    v_star = np.clip(-kp / kd * (q - target), -v_max, v_max)
    return _clip(m * kd * (v_star - qd) + c * qd, p)


@witness
def mass_damper_settle(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _line_track(x, p, 0.0, kp=100.0, kd=20.0, v_max=2.5)


@witness
def mass_damper_out_and_back(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _line_track(x, p, 0.75 if t < 0.8 else -0.5, kp=100.0, kd=20.0)


@witness
def mass_damper_speed_limit(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _line_track(x, p, 0.9, kp=100.0, kd=20.0, v_max=0.8)


@witness
def mass_damper_oscillate(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _line_track(x, p, 0.7 if int(t / 0.8) % 2 == 0 else -0.7, kp=100.0, kd=20.0)


@witness
def mass_damper_either_station(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """To the station on the side where the mass would stop."""
    side = np.where(x[:, 0] + 0.15 * x[:, 1] >= 0, 1.0, -1.0)
    return _line_track(x, p, 0.7 * side, kp=100.0, kd=20.0, v_max=2.0)


@witness
def cart_out_and_home(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _line_track(x, p, 1.25 if t < 1.6 else 0.0, kp=25.0, kd=10.0, v_max=2.0)


@witness
def cart_park_slowly(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _line_track(x, p, 1.5, kp=25.0, kd=10.0, v_max=1.2)


@witness
def cart_patrol(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _line_track(x, p, 1.3 if int(t / 1.4) % 2 == 0 else -1.3, kp=25.0, kd=10.0)


@witness
def cart_dock_until(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _line_track(x, p, 1.2, kp=25.0, kd=10.0, v_max=0.8)


@witness
def cart_bay_window(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """Hold still until 0.9 s, then into the bay on the side the cart is on."""
    if t < 0.9:
        return _line_track(x, p, x[:, 0], kp=25.0, kd=10.0)
    side = np.where(x[:, 0] >= 0, 1.0, -1.0)
    return _line_track(x, p, side, kp=25.0, kd=10.0, v_max=2.0)


# ------------------------------------------------------------------ the cart-pole
# LQR gains of the linearisation at upright (Barto's numbers, continuous-time Riccati equation),
# u = K . (x - x*, xdot, theta, thetadot): Q = diag(10, 1, 50, 1), R = 0.1 and a stiffer
# Q = diag(30, 3, 100, 1), and one that rights the pole fast, Q = diag(1, 1, 100, 1), R = 0.01.
CARTPOLE_LQR = (10.0, 11.62, 72.0, 17.93)
CARTPOLE_LQR_STIFF = (17.32, 18.37, 97.73, 24.12)
CARTPOLE_LQR_FAST = (10.0, 19.79, 153.61, 31.77)


def _cartpole_track(
    x: np.ndarray,
    p: Params,
    target: float | np.ndarray,
    v_max: float = 1.0,
    kx: float = 1.5,
    gains: tuple[float, ...] = CARTPOLE_LQR_STIFF,
) -> np.ndarray:
    """LQR about a moving reference: the cart's velocity error to ``v* = clip(-kx (x - target), +-v_max)``
    (no position term: the outer loop moves the cart), the pole's angle and rate."""
    k = gains
    v_star = np.clip(-kx * (x[:, 0] - target), -v_max, v_max)
    th = _wrap(x[:, 2])
    return _clip(k[1] * (x[:, 1] - v_star) + k[2] * th + k[3] * x[:, 3], p)


def _cartpole_follow(
    x: np.ndarray, p: Params, x_ref: float, v_ref: float, gains: tuple[float, ...] = CARTPOLE_LQR_STIFF
) -> np.ndarray:
    """LQR about a reference motion of the cart, ``x_ref(t)`` at ``v_ref(t)``."""
    k = gains
    th = _wrap(x[:, 2])
    return _clip(k[0] * (x[:, 0] - x_ref) + k[1] * (x[:, 1] - v_ref) + k[2] * th + k[3] * x[:, 3], p)


@witness
def cartpole_visit_window(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _cartpole_track(x, p, 1.0)


@witness
def cartpole_lean_response(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _cartpole_track(x, p, 0.0, kx=0.5)


@witness
def cartpole_shuttle(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _cartpole_track(x, p, 1.1 if t < 2.2 else 0.0)


@witness
def cartpole_catch_and_centre(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _cartpole_track(x, p, 0.0, v_max=0.6, kx=1.0)


@witness
def cartpole_slow_move(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _cartpole_track(x, p, 1.5, v_max=0.8)


@witness
def cartpole_sway(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """LQR about a sine, 0.5 m either side, a period of 4 s."""
    w = 2 * np.pi / 4.0
    return _cartpole_follow(x, p, 0.5 * math.sin(w * t), 0.5 * w * math.cos(w * t), CARTPOLE_LQR)


# ------------------------------------------------------------------ Gymnasium's Pendulum-v1
# thdd = 3 g / (2 l) sin th + 3 / (m l^2) u = 15 sin th + 3 u (g = 10, m = l = 1), |u| <= 2, |w| <= 8.
GYM_A, GYM_C = 15.0, 3.0


def _gym_pendulum_swing_up(x: np.ndarray, p: Params, catch: float = 0.4) -> np.ndarray:
    """Pump energy (``E = w^2/2 + 15 cos q``, ``15`` at rest upright) by pushing along ``w``; near the
    top, a PD law with gravity compensation catches the pendulum."""
    q, w = _wrap(x[:, 0]), x[:, 1]
    e = 0.5 * w**2 + GYM_A * np.cos(q)
    pump = np.where(w >= 0, 1.0, -1.0) * p["u_max"] * (e < GYM_A)
    pd = (-GYM_A * np.sin(q) - 10.0 * q - 5.0 * w) / GYM_C
    return _clip(np.where(np.abs(q) < catch, pd, pump), p)


@witness
def gym_pendulum_swing_up_rest(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _gym_pendulum_swing_up(x, p)


@witness
def gym_pendulum_spin_response(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _gym_pendulum_swing_up(x, p)


# ------------------------------------------------------------------ Gymnasium's MountainCarContinuous-v0
# v += 0.0015 u - 0.0025 cos(3 x), |u| <= 1: too weak to climb straight up, so push along the velocity.


def _mountain_car(x: np.ndarray, p: Params, turn: float) -> np.ndarray:
    """Push right when moving right; when moving left (or at rest), hold the energy
    ``E = v^2/2 + 0.0025/3 sin(3 x)`` at what carries the car to ``turn`` on the left hill (push left
    below it, brake above it): the swing back from there, pushed all the way, reaches the goal."""
    pos, v = x[:, 0], x[:, 1]
    e = 0.5 * v**2 + 0.0025 / 3 * np.sin(3 * pos)
    left = np.where(e < 0.0025 / 3 * math.sin(3 * turn), -1.0, 1.0)
    return np.where(v > 0, 1.0, left) * p["u_max"]


@witness
def gym_mountain_car_no_wall(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    return _mountain_car(x, p, turn=-0.85)


@witness
def gym_mountain_car_left_first(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """Push along the velocity, left when at rest: up the left hill first."""
    return np.where(x[:, 1] > 0, 1.0, -1.0) * p["u_max"]


# ------------------------------------------------------------------ the unicycle
# xdot = v cos theta, ydot = v sin theta, thetadot = omega; u = (v, omega), (R, 2), each in its own box.
UNICYCLE_LO, UNICYCLE_HI = PLANTS["unicycle"].input_box()


def _unicycle(v: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``(R, 2)``: the speed and the turn rate, each clipped to its box."""
    return np.clip(np.stack([v, omega], axis=1), UNICYCLE_LO, UNICYCLE_HI)


def _steer(x: np.ndarray, heading: np.ndarray, speed: float | np.ndarray, k: float = 4.0) -> np.ndarray:
    """Turn towards ``heading`` (``omega = k`` times the wrapped heading error) and drive at ``speed``
    scaled by how well the robot is aligned (``cos`` of the error, none while it faces away)."""
    err = _wrap(heading - x[:, 2])
    return _unicycle(speed * np.clip(np.cos(err), 0.0, 1.0), k * err)


def _go_to(x: np.ndarray, gx: float | np.ndarray, gy: float | np.ndarray, k_d: float = 2.0) -> np.ndarray:
    """Go to the point ``(gx, gy)``: steer along the bearing to it, the speed ``min(1, k_d d)`` falling
    off with the distance ``d`` to it, so the robot comes to rest there."""
    dx, dy = gx - x[:, 0], gy - x[:, 1]
    return _steer(x, np.arctan2(dy, dx), np.clip(k_d * np.hypot(dx, dy), 0.0, 1.0))


@witness
def unicycle_goal_around_rock(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """Round the rock by the side the robot is on (through a point 0.85 m above or below its centre),
    then to the goal once past it; the speed falls off with the distance to the goal, not to the
    point beside the rock, so the robot drives through that point and comes to rest in the goal."""
    side = np.where(x[:, 1] >= 0, 1.0, -1.0)
    past = x[:, 0] >= 0.0
    gx = np.where(past, 1.3, 0.0)
    gy = np.where(past, 0.0, 0.85 * side)
    dx, dy = gx - x[:, 0], gy - x[:, 1]
    to_goal = np.hypot(1.3 - x[:, 0], x[:, 1])
    return _steer(x, np.arctan2(dy, dx), np.clip(2.0 * to_goal, 0.0, 1.0))


@witness
def unicycle_two_waypoints(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """To waypoint A until 3 s, then to waypoint B."""
    return _go_to(x, -1.0, -0.2) if t < 3.0 else _go_to(x, 0.9, 0.8)


@witness
def unicycle_patrol_pillar(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """Round the circle of radius 0.8 m through both stations, clockwise (from the bottom, A first):
    the tangent's heading turned towards the circle by ``atan(3 (r - 0.8))``, plus the turn rate
    of the circle itself."""
    r = np.hypot(x[:, 0], x[:, 1])
    phi = np.arctan2(x[:, 1], x[:, 0])
    heading = phi - np.pi / 2 - np.arctan(3.0 * (r - 0.8))
    u = _steer(x, heading, 1.0)
    u[:, 1] = np.clip(u[:, 1] - u[:, 0] / 0.8, UNICYCLE_LO[1], UNICYCLE_HI[1])
    return u


@witness
def unicycle_corridor_exit(x: np.ndarray, t: float, p: Params) -> np.ndarray:
    """Along the corridor's centre line (a point 0.5 m ahead on it), round the corner at (1, 0), up to
    the exit bay's middle, (1, 1.6), and stop there."""
    along = x[:, 0] < 0.7
    gx = np.where(along, np.minimum(x[:, 0] + 0.5, 1.0), 1.0)
    gy = np.where(along, 0.0, np.minimum(np.maximum(x[:, 1], 0.0) + 0.5, 1.6))
    return _go_to(x, gx, gy)
