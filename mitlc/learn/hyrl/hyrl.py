"""HyRL: actor-critic learning on a hybrid automaton (thesis chapter 3).

The learner sees the augmented state ``(q, qdot, q0, t, delta)``: the plant
state, the memory of the automaton (initial position, mode clock; the clock
only when the automaton's guards read one) and the mode.  Over normalised
Gaussian RBFs ``phi`` on a grid over ``(q, qdot, q0[, t])`` (Table 3-2: 10 x
10 x 5, and 10 x 10 x 5 x 5 with the clock):

* value (3-7)/(3-8): a general part plus a mode part,
  ``V = theta_g . phi + theta_delta . phi``;
* policy (3-10): one per mode, no general part, ``pi = xi_delta . phi``;
* standard actor-critic (section 2-1-3): TD error (2-8) ``delta = r + gamma
  V(x_k+1) - V(x_k)``, critic (2-16)/(2-17) with accumulating eligibility
  traces over the stacked parameters of (3-8) (the general row's gradient is
  ``phi`` at every step, mode ``i``'s is ``eta_i(delta_k) phi``: a mode part
  is updated only while its trace, laid down while it was active, lasts),
  actor (2-11)/(2-18) ``xi_delta_k += alpha_a delta du phi(x_k)``.

``R`` independent runs are trained at once (a leading run axis everywhere);
run ``i`` draws its numbers from its own generators, spawned from the seed
with :class:`numpy.random.SeedSequence`, so a seed reproduces a training to
the bit.  Where the thesis is silent the choices are fields of
:class:`HyrlSettings` (exploration and its correlation time, RBF width, the
velocity span of the grid, the critic's initial value, anti-wind-up), as in
:mod:`mitlc.learn.sacpn`.

>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec('''
... plant mass-damper
... init q in [-1, 1], qdot = 0
... setpoint 0
... require overshoot <= 0''')
>>> learner = train_hybrid(spec, runs=2, trials=2, seed=3)
>>> learner.returns.shape, learner.xi.shape, learner.theta.shape   # I, E_Mp, S, P (+ general)
((2, 2), (2, 4, 500), (2, 5, 500))
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import InputError, MitlError, TrainingError
from mitlc.fileio import atomic_write
from mitlc.hybrid import HybridAutomaton, compile_requirements
from mitlc.learn.features import Axis, RbfFeatures
from mitlc.learn.settings import Settings, check_fraction, check_grid, check_non_negative, check_range, json_default
from mitlc.limits import MAX_MAGNITUDE, MAX_RBF_WIDTH, MAX_TIME, MIN_DT, MIN_RBF_WIDTH, MIN_SPAN, check_steps
from mitlc.plants.base import Plant
from mitlc.spec.model import Spec

__all__ = [
    "HyrlSettings",
    "HybridLearner",
    "HybridRollout",
    "train_hybrid",
    "load_learner",
    "q_warp_for",
]


@dataclass(frozen=True)
class HyrlSettings(Settings):
    """Settings of the HyRL learner; defaults are Table 3-2 where the thesis gives them."""

    gamma: float = 0.98
    """Discount factor (Table 3-2)."""

    lam: float = 0.65
    """Eligibility trace decay lambda (Table 3-2)."""

    alpha_c: float = 0.3
    """Critic learning rate (Table 3-2)."""

    alpha_a: float = 0.04
    """Actor learning rate.  Table 3-2 gives 0.08 for the thesis's exploration, which it
    does not describe; with this learner's (Ornstein-Uhlenbeck, :attr:`noise_tau`) and
    centres (:attr:`q_warp`) half of it is measured better on both of the thesis's
    problems (20 runs; runs whose greedy policy succeeds from every initial state, 0.08
    -> 0.04): overshoot after 800 trials (``|q0| >= 0.1``) 0.65 -> 0.90 (seed 0),
    0.60 -> 0.95 (seed 1), 0.45 -> 0.95 (seed 2), 0.50 -> 0.90 (seed 3); rise time
    after 2000 trials 0.95 -> 1.00 (seed 0), 0.70 -> 0.90 (seed 1).  See docs/hyrl.md."""

    rbf: tuple[int, int, int] = (10, 10, 5)
    """RBF centres for ``q``, ``qdot`` and ``q0`` (Table 3-2: 10 x 10 x 5)."""

    rbf_clock: int = 5
    """RBF centres per clock the automaton reads (``t``, ``tau``); section 3-3-2: 10 x 10 x 5 x 5."""

    rbf_width: float = 0.5
    """Gaussian width (standard deviation) as a multiple of the centre spacing (thesis
    silent).  Measured on the mass-damper (8 runs, Table 3-2 otherwise): 0.5 lets the
    critic and the policies resolve the S band and the rise-time window; wider kernels
    blur them (overshoot: 45% of the greedy rollouts succeed with 0.5, 3% with 0.7,
    none with 1.0; see docs/hyrl.md)."""

    sigma: float = 1.0
    """Exploration: ``du ~ N(0, sigma^2)`` per step, in N (thesis silent; 10% of u_max).
    A larger noise keeps the mass from staying in the narrow S band of a small step
    (the thesis's own observation for |q0| < 0.1, section 3-3-1)."""

    sigma_decay: float = 1.0
    """Exploration decay per trial: trial ``k`` (from 0) explores with
    ``max(sigma_min, sigma * sigma_decay**k)``.  The thesis gives no schedule but asks
    for less exploration "in the later phase of the learning process" (section 2-1-2)."""

    sigma_min: float = 0.0
    """Floor of the decayed exploration."""

    trial_s: float | None = None
    """Trial duration in s; ``None``: the spec's ``horizon``, else 5 s (Table 3-2)."""

    dt: float | None = None
    """Sample time; ``None``: the plant's ``dt`` (0.03 s, Table 3-2)."""

    saturation: str = "applied"
    """``applied``: clip the policy to the input bound and update with the exploration
    actually applied (anti-wind-up, as :class:`mitlc.learn.sacpn.SacpnSettings`).
    ``none``: the thesis's update (2-18) with the raw exploration."""

    bootstrap_timeout: bool = True
    """Treat the end of a trial as a time-out (bootstrap ``gamma V(x_N)``), not a terminal state."""

    critic_init: str = "stay"
    """Initial critic (thesis silent; it gives no initial parameters).  ``zero``: every
    parameter 0.  ``stay``: the mode part of a mode whose reward has a positive constant
    part ``c`` (S's stay bonus, +3) starts at ``c / (1 - gamma)`` (+150), the value of
    staying there at the set-point; the features sum to one, so a constant row is that
    value.  ``constant``: every mode's part starts at ``c / (1 - gamma)`` of its constant
    reward (also P: -9 / 0.02 = -450).  Measured (rise time, 8 runs, seed 1, 2000 trials,
    white noise, 5 m/s grid; rollouts that succeed): 1% (zero), 60% (stay), 32% (constant:
    with P that costly, 4 runs miss the rise time from every state).  See docs/hyrl.md."""

    qdot_grid: float | None = 1.5
    """Half-width of the feature grid in ``qdot`` (m/s); ``None``: the plant's bound (5 m/s,
    the state bound of section 3-1).  Values outside are clipped for the features only
    (thesis silent on where the RBF centres lie).  With +-5 m/s the 10 centres are 1.1 m/s
    apart and ``qdot = 0`` falls between two of them, too coarse for braking into the S
    band.  Measured (8 runs, Table 3-2 otherwise, states that succeed): overshoot 39%
    (+-2), 77% (+-1.5), 79% (+-1), seed 0; rise time 64% (+-5), 96% (+-2), 100% (+-1.5),
    90% (+-1), seed 1."""

    q_warp: float | None = None
    """Where the ``q`` centres lie (thesis silent; it gives their number only): evenly
    in ``w = s + sign(q - s) D |(q - s) / D| ** q_warp`` (``s`` the set-point, ``D`` the
    larger distance from it to a bound of ``q``).  Below 1 they crowd towards the
    set-point and their spacing grows with the distance from it, as the bands of
    the overshoot's automaton do (S: ``0.1 q0`` wide next to the set-point, P just
    past it); 1: evenly in ``q``.  With [-1, 1], 10 centres and 0.5: +-0.012, +-0.11,
    +-0.31, +-0.60, +-1 instead of +-0.11, +-0.33, ...  ``None`` (auto): 1 when the
    rise time is the only requirement (its bands, 10% and 90% of the step, spread
    over the whole step), else 0.5.  Measured (20 runs; successful states, overshoot
    ``|q0| >= 0.1`` after 800 trials, seeds 0 / 1): 0.73 / 0.79 (1), 0.89 / 0.82
    (0.75), 0.94 / 0.94 (0.6), 0.98 / 0.97 (0.5), 0.94 / 0.94 (0.4), 0.92 / 0.88
    (0.33); rise time after 2000 trials, seed 0: 0.99 (1), 0.97 (0.75), 0.93 (0.5);
    see docs/hyrl.md."""

    noise_tau: float = 0.1
    """Correlation time of the exploration in s (thesis silent): ``du`` is an
    Ornstein-Uhlenbeck process with stationary deviation ``sigma``,
    ``n_k+1 = a n_k + sqrt(1 - a^2) sigma eps``, ``a = exp(-T_s / noise_tau)``; 0 draws
    ``du`` independently every step (white).  White noise of 1 N changes the position of
    the 0.5 kg mass by under a millimetre per sample, too little for the TD error to tell
    a good push from a bad one.  Measured (8 runs, seed 1, critic ``stay``, 5 m/s grid):
    rollouts that succeed, overshoot 41% (white) -> 54% (0.1 s), 25% (0.3 s); rise time
    60% -> 64%, runs succeeding from every state 1 -> 5 of 8."""

    def check(self) -> None:
        if self.critic_init not in ("zero", "stay", "constant"):
            raise TrainingError(f"unknown critic_init '{self.critic_init}' (zero, stay or constant)")
        if self.saturation not in ("applied", "none"):
            raise TrainingError(f"unknown saturation '{self.saturation}' (applied or none)")
        check_fraction(self, ("gamma", "lam"))
        if not 0.0 < self.sigma_decay <= 1.0:
            raise TrainingError(f"sigma_decay must be in (0, 1], got {self.sigma_decay}")
        check_non_negative(self, ("alpha_c", "alpha_a"))
        check_range(self, ("sigma", "sigma_min"), 0.0, MAX_MAGNITUDE)
        check_range(self, ("noise_tau",), 0.0, MAX_TIME)
        check_range(self, ("rbf_width",), MIN_RBF_WIDTH, MAX_RBF_WIDTH)
        if len(self.rbf) != 3 or any(int(n) < 1 for n in self.rbf) or self.rbf_clock < 1:
            raise TrainingError(f"rbf needs three positive counts (q, qdot, q0) and rbf_clock >= 1, got {self.rbf}")
        check_grid((*self.rbf, self.rbf_clock))
        if self.q_warp is not None and not (math.isfinite(self.q_warp) and 0.0 < self.q_warp <= 1.0):
            raise TrainingError(f"q_warp must be in (0, 1], got {self.q_warp}")
        check_range(self, ("trial_s", "dt"), MIN_DT, MAX_TIME, optional=True)
        check_range(self, ("qdot_grid",), MIN_SPAN, MAX_MAGNITUDE, optional=True)


# ---------------------------------------------------------------- features


def q_warp_for(automaton: HybridAutomaton) -> float:
    """The ``q_warp`` that :attr:`HyrlSettings.q_warp` ``None`` picks: an even grid (1) when
    the rise time is the only requirement, else 0.5 (centres crowding towards the set-point,
    where the overshoot's, settling time's and steady-state error's bands lie)."""
    names = {r.name for r in automaton.requirements}
    return 1.0 if names == {"rise_time"} else 0.5


# ---------------------------------------------------------------- rollouts


@dataclass
class HybridRollout:
    """Trajectories of the plant and the automaton: ``states (B, N+1, 2)``,
    ``actions (B, N)``, ``modes (B, N+1)`` (indices into ``names``), clock
    ``t (B, N+1)``, ``rewards (B, N)``; ``dt`` the sample time."""

    states: np.ndarray
    actions: np.ndarray
    modes: np.ndarray
    t: np.ndarray
    rewards: np.ndarray
    dt: float
    names: tuple[str, ...]

    @property
    def returns(self) -> np.ndarray:
        return self.rewards.sum(axis=1)

    def visited(self, name: str) -> np.ndarray:
        """Rollouts that were ever in mode ``name``, ``(B,)``."""
        return (self.modes == self.names.index(name)).any(axis=1)

    def final_mode(self) -> list[str]:
        return [self.names[i] for i in self.modes[:, -1]]


def _rollout(
    automaton: HybridAutomaton,
    plant: Plant,
    params: Mapping[str, float],
    n_steps: int,
    x0: np.ndarray,
    control: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float], np.ndarray],
) -> HybridRollout:
    """Greedy rollout of ``control(x, q0, t, mode, tau) -> u`` on the automaton."""
    x = np.array(x0, dtype=float)
    B = x.shape[0]
    dt, u_max = float(params["dt"]), float(params["u_max"])
    states = np.empty((B, n_steps + 1, 2))
    actions = np.empty((B, n_steps))
    modes = np.empty((B, n_steps + 1), dtype=np.int64)
    clocks = np.empty((B, n_steps + 1))
    rewards = np.empty((B, n_steps))
    q0 = x[:, 0].copy()
    mode, t = automaton.reset(x)
    states[:, 0], modes[:, 0], clocks[:, 0] = x, mode, t
    for k in range(n_steps):
        u = np.clip(control(x, q0, t, mode, k * dt), -u_max, u_max)
        x = plant.step(x, u, params)
        mode, t, r = automaton.step(mode, t, x, q0, (k + 1) * dt, dt)
        states[:, k + 1], modes[:, k + 1], clocks[:, k + 1] = x, mode, t
        actions[:, k], rewards[:, k] = u, r
    return HybridRollout(states, actions, modes, clocks, rewards, dt, automaton.names)


# ---------------------------------------------------------------- the learner


@dataclass
class _Snapshot:
    xi: np.ndarray
    theta: np.ndarray
    rng_states: list
    trial: int


class HybridLearner:
    """HyRL for ``runs`` independent runs on one hybrid automaton.

    ``xi (R, modes, F)``: one policy per mode (3-10); ``theta (R, modes + 1, F)``:
    one value part per mode and the general part in the last row (3-8);
    ``returns (R, trials)``: the undiscounted return of every trial.
    """

    def __init__(
        self,
        spec: Spec,
        settings: HyrlSettings | None = None,
        runs: int = 1,
        seed: int = 0,
        automaton: HybridAutomaton | None = None,
    ) -> None:
        try:
            self._setup(spec, settings, runs, seed, automaton)
        except MitlError as exc:  # name the spec file where the error does not name another
            raise exc.located(spec.path) from None

    def _setup(
        self,
        spec: Spec,
        settings: HyrlSettings | None,
        runs: int,
        seed: int,
        automaton: HybridAutomaton | None,
    ) -> None:
        settings = settings or HyrlSettings()
        settings.check()
        if runs < 1:
            raise TrainingError(f"runs must be at least 1, got {runs}")
        plant = spec.plant
        if plant is None:
            raise TrainingError("the spec names no plant (add 'plant mass-damper')")
        if plant.stepped:
            raise TrainingError(
                f"HyRL integrates its plant from chosen states; '{plant.name}' can only be reset and stepped "
                "(train it with SACPN: a spec with a formula)"
            )
        if plant.inputs is not None:
            raise TrainingError(
                f"HyRL drives one input u bounded by the parameter u_max; plant '{plant.name}' declares "
                f"{plant.n_inputs} input{'s' if plant.n_inputs > 1 else ''} ({', '.join(plant.input_names)}) "
                "(train it with SACPN: a spec with a formula)"
            )
        self.spec, self.plant, self.settings = spec, plant, settings
        self.automaton = automaton if automaton is not None else compile_requirements(spec)
        self.runs, self.seed = int(runs), int(seed)
        self.params = plant.params(dict(spec.plant_params))
        if settings.dt is not None:
            self.params["dt"] = float(settings.dt)
        self.dt = float(self.params["dt"])
        self.u_max = float(self.params["u_max"])
        self.trial_s = float(settings.trial_s if settings.trial_s is not None else self.automaton.horizon)
        try:
            self.n_steps = check_steps(self.trial_s, self.dt, "a trial")
        except ValueError as exc:
            raise TrainingError(str(exc), file=spec.path, hint="a shorter trial_s, a larger dt") from None
        A = self.automaton
        self.time_vars = A.time_vars()
        names = ("q", "qdot", "q0") + self.time_vars
        vb = (plant.var("qdot").lo, plant.var("qdot").hi)
        if settings.qdot_grid is not None:
            vb = (-settings.qdot_grid, settings.qdot_grid)
        bounds = [(plant.var("q").lo, plant.var("q").hi), vb, A.q0_range]
        bounds += [A.time_range(v) for v in self.time_vars]
        counts = tuple(settings.rbf) + (settings.rbf_clock,) * len(self.time_vars)
        self.q_warp = q_warp_for(A) if settings.q_warp is None else float(settings.q_warp)
        warps = [(A.setpoint, self.q_warp)] + [None] * (len(names) - 1)
        self.features = RbfFeatures(
            [Axis(n, lo, hi, c, warp=w) for n, (lo, hi), c, w in zip(names, bounds, counts, warps, strict=True)],
            settings.rbf_width,
        )
        self.n_features = self.features.n_features
        self.n_modes = len(A.modes)
        R, M, F = self.runs, self.n_modes, self.n_features
        self.xi = np.zeros((R, M, F))
        self.theta = np.zeros((R, M + 1, F))
        self.theta[:, :M] = self.initial_values()[None, :, None]
        self.returns = np.zeros((R, 0))
        self.trial = 0
        self.wall_s = 0.0
        children = np.random.SeedSequence(self.seed).spawn(R)
        pairs = [c.spawn(2) for c in children]
        self.rngs = [np.random.Generator(np.random.PCG64(p[0])) for p in pairs]
        self.eval_rngs = [np.random.Generator(np.random.PCG64(p[1])) for p in pairs]
        self._snapshot: _Snapshot | None = None

    # ------------------------------------------------------------ helpers
    def sigma_at(self, trial: int) -> float:
        """Exploration standard deviation of trial ``trial`` (counted from 0)."""
        st = self.settings
        return max(st.sigma_min, st.sigma * st.sigma_decay**trial)

    def exploration_noise(self, n_steps: int, dt: float) -> np.ndarray:
        """This trial's input exploration ``(n_steps, R)``: each run draws ``n_steps``
        normals from its own generator; with ``noise_tau`` they are filtered into an
        Ornstein-Uhlenbeck process (stationary from the first step); scaled by
        :meth:`sigma_at` of the current trial."""
        st = self.settings
        noise = np.empty((n_steps, self.runs))
        for r, g in enumerate(self.rngs):
            noise[:, r] = g.standard_normal(n_steps)
        if st.noise_tau > 0:
            a_ou = math.exp(-dt / st.noise_tau)
            b_ou = math.sqrt(1.0 - a_ou * a_ou)
            for k in range(1, n_steps):
                noise[k] = a_ou * noise[k - 1] + b_ou * noise[k]
        return noise * self.sigma_at(self.trial)

    def initial_values(self) -> np.ndarray:
        """Per mode, the value its mode part starts at (``settings.critic_init``):
        ``c / (1 - gamma)`` for the constant part ``c`` of the mode's reward (its constants
        and stay bonus) kept forever; under ``stay`` only where ``c > 0``; zeros under ``zero``."""
        from mitlc.hybrid import Const, StayBonus

        out = np.zeros(self.n_modes)
        how = self.settings.critic_init
        if how == "zero":
            return out
        for i, m in enumerate(self.automaton.modes):
            c = sum(t.value for t in m.reward.terms if isinstance(t, (Const, StayBonus)))
            if how == "constant" or c > 0:
                out[i] = c / (1.0 - self.settings.gamma)
        return out

    def phi(self, x: np.ndarray, q0: np.ndarray, t: np.ndarray, tau: float | np.ndarray) -> np.ndarray:
        """Features of the augmented state, ``(R, F)``."""
        cols = [x[:, 0], x[:, 1], q0]
        for v in self.time_vars:
            cols.append(t if v == "t" else np.broadcast_to(tau, q0.shape))
        return self.features(np.stack(cols, axis=1))

    def sample_init(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """One initial state per generator: ``q0`` and ``qdot0`` uniform in the spec's ranges."""
        (qlo, qhi), (vlo, vhi) = self.automaton.q0_range, self.automaton.qdot0_range
        x = np.empty((len(rngs), 2))
        for r, g in enumerate(rngs):
            x[r, 0] = g.uniform(qlo, qhi)
            x[r, 1] = g.uniform(vlo, vhi)
        return x

    def policy(
        self, x: np.ndarray, q0: np.ndarray, t: np.ndarray, mode: np.ndarray, tau: float, run: np.ndarray | None = None
    ) -> np.ndarray:
        """Greedy input of each row's mode policy, clipped to the input bound; row ``b``
        uses run ``run[b]`` (default: row ``b`` is run ``b``)."""
        run = np.arange(x.shape[0]) if run is None else run
        phi = self.phi(x, q0, t, tau)
        u = np.einsum("bf,bf->b", self.xi[run, mode], phi)
        return np.clip(u, -self.u_max, self.u_max)

    def value(
        self, x: np.ndarray, q0: np.ndarray, t: np.ndarray, mode: np.ndarray, tau: float, run: np.ndarray | None = None
    ) -> np.ndarray:
        """Critic (3-7): general plus mode part of each row; row ``b`` uses run ``run[b]``
        (default: row ``b`` is run ``b``), like :meth:`policy`."""
        run = np.arange(x.shape[0]) if run is None else run
        phi = self.phi(x, q0, t, tau)
        return np.einsum("bf,bf->b", self.theta[run, mode] + self.theta[run, -1], phi)

    # ------------------------------------------------------------ training
    def train(self, trials: int, callback: Callable[[int, np.ndarray], None] | None = None) -> np.ndarray:
        """Run ``trials`` more trials on every run; returns their returns ``(R, trials)``.

        ``callback(trial, returns)`` after each trial.  On KeyboardInterrupt the
        learner is rolled back to the end of the last complete trial and the
        interrupt re-raised (so a checkpoint saved then is consistent).
        """
        out = np.zeros((self.runs, trials))
        done = 0
        start = time.perf_counter()
        try:
            for k in range(trials):
                self._snapshot = _Snapshot(
                    self.xi.copy(), self.theta.copy(), [g.bit_generator.state for g in self.rngs], self.trial
                )
                with np.errstate(over="ignore", invalid="ignore"):  # divergence is reported below
                    out[:, k] = self._trial()
                self._check_finite(out[:, k])
                self.trial += 1
                done = k + 1
                self.returns = np.concatenate([self.returns, out[:, k : k + 1]], axis=1)
                if callback is not None:
                    callback(self.trial, out[:, k])
        except KeyboardInterrupt:
            self._rollback()
            raise
        finally:
            self.wall_s += time.perf_counter() - start
        self._snapshot = None
        return out[:, :done]

    def _rollback(self) -> None:
        s = self._snapshot
        if s is None or s.trial != self.trial:
            return
        self.xi, self.theta = s.xi, s.theta
        for g, st in zip(self.rngs, s.rng_states, strict=True):
            g.bit_generator.state = st
        self._snapshot = None

    def _check_finite(self, ret: np.ndarray) -> None:
        for name, arr in (("actor", self.xi), ("critic", self.theta), ("return", ret)):
            bad = ~np.isfinite(arr).reshape(self.runs, -1).all(axis=1)
            if bad.any():
                runs = ", ".join(str(int(i)) for i in np.flatnonzero(bad)[:10])
                raise TrainingError(
                    f"the {name} diverged (NaN or inf) in trial {self.trial + 1}, run(s) {runs}",
                    file=self.spec.path,
                    hint="lower the learning rates (alpha_a, alpha_c) or the exploration sigma",
                )

    def _trial(self) -> np.ndarray:
        """One trial of standard actor-critic on the hybrid system, all runs at once;
        returns the undiscounted returns ``(R,)``."""
        st = self.settings
        A, plant, params = self.automaton, self.plant, self.params
        R, N, dt, u_max = self.runs, self.n_steps, self.dt, self.u_max
        gamma, gl = st.gamma, st.gamma * st.lam
        a_c, a_a = st.alpha_c, st.alpha_a
        applied = st.saturation == "applied"
        rows = np.arange(R)
        G = self.n_modes  # the general row of theta
        xi, theta = self.xi, self.theta

        x = self.sample_init(self.rngs)
        noise = self.exploration_noise(N, dt)
        q0 = x[:, 0].copy()
        mode, t = A.reset(x)
        phi = self.phi(x, q0, t, 0.0)
        # critic trace over the stacked parameters (3-8), stored scaled: e = scale * e_hat
        e_hat = np.zeros_like(theta)
        tmp = np.empty_like(theta)
        scale = 1.0
        ret = np.zeros(R)
        u = np.einsum("rf,rf->r", xi[rows, mode], phi)
        for k in range(N):
            if applied:
                u_sat = np.clip(u, -u_max, u_max)
                a = np.clip(u_sat + noise[k], -u_max, u_max)
                du = a - u_sat
            else:
                a = u + noise[k]
                du = noise[k]
            x = plant.step(x, a, params)
            tau1 = (k + 1) * dt
            mode1, t1, r = A.step(mode, t, x, q0, tau1, dt)
            ret += r
            phi1 = self.phi(x, q0, t1, tau1)
            v0 = np.einsum("rf,rf->r", theta[rows, mode] + theta[:, G], phi)
            v1 = np.einsum("rf,rf->r", theta[rows, mode1] + theta[:, G], phi1)
            delta = r - v0
            if k < N - 1 or st.bootstrap_timeout:
                delta += gamma * v1
            # actor (2-18) on the policy of the mode that acted (3-10)
            coef = a_a * delta * du
            if applied:  # never push a saturated output further past the bound
                coef[((u >= u_max) & (coef > 0)) | ((u <= -u_max) & (coef < 0))] = 0.0
            xi[rows, mode] += coef[:, None] * phi
            # critic (2-16)/(2-17): e <- gamma lambda e + grad V(x_k); theta += alpha delta e
            scale *= gl
            if scale < 1e-100:
                e_hat *= scale
                scale = 1.0
            grad = phi * (1.0 / scale)
            e_hat[rows, mode] += grad
            e_hat[:, G] += grad
            np.multiply(e_hat, (a_c * scale * delta)[:, None, None], out=tmp)
            theta += tmp
            mode, t, phi = mode1, t1, phi1
            u = np.einsum("rf,rf->r", xi[rows, mode], phi)
        return ret

    # ------------------------------------------------------------ evaluation
    def control(self, run: np.ndarray) -> Callable[..., np.ndarray]:
        """The greedy controller ``(x, q0, t, mode, tau) -> u`` of row ``b``'s run ``run[b]``."""
        return lambda x, q0, t, mode, tau: self.policy(x, q0, t, mode, tau, run)

    def rollout(self, x0: np.ndarray, run: np.ndarray | None = None) -> HybridRollout:
        """Greedy rollouts (no exploration, no learning) from ``x0 (B, 2)``; row ``b``
        uses run ``run[b]`` (default ``b % R``)."""
        x0 = np.asarray(x0, dtype=float)
        run = np.arange(x0.shape[0]) % self.runs if run is None else np.asarray(run)
        return _rollout(self.automaton, self.plant, self.params, self.n_steps, x0, self.control(run))

    # ------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, np.ndarray]:
        from mitlc.plants.user import plant_record

        meta = {
            "kind": "hyrl",
            "trial": self.trial,
            "runs": self.runs,
            "seed": self.seed,
            "wall_s": self.wall_s,
            "settings": self.settings.to_dict(),
            "rng_states": [g.bit_generator.state for g in self.rngs],
            "eval_rng_states": [g.bit_generator.state for g in self.eval_rngs],
            "modes": list(self.automaton.names),
            "feature_vars": list(self.features.names),
            "spec_source": self.spec.source or "",
            "spec_path": self.spec.path or "",
            "plant": plant_record(self.spec.plant_name or ""),  # a plant file: used again from the run's copy
        }
        return {
            "xi": self.xi,
            "theta": self.theta,
            "returns": self.returns,
            "meta": np.array(json.dumps(meta, default=json_default)),
        }

    def load_state_dict(self, d: Mapping[str, np.ndarray]) -> None:
        meta = json.loads(str(d["meta"]))
        if meta.get("kind") != "hyrl":
            raise InputError("not a HyRL checkpoint")
        shape = (self.runs, self.n_modes, self.n_features)
        if meta["runs"] != self.runs or tuple(d["xi"].shape) != shape:
            raise InputError(f"checkpoint holds {meta['runs']} runs of shape {tuple(d['xi'].shape)}, expected {shape}")
        if meta["modes"] != list(self.automaton.names):
            raise InputError("checkpoint was trained on a different hybrid automaton")
        self.xi = np.array(d["xi"], dtype=float)
        self.theta = np.array(d["theta"], dtype=float)
        self.returns = np.array(d["returns"], dtype=float).reshape(self.runs, -1)
        self.trial = int(meta["trial"])
        self.seed = int(meta["seed"])
        self.wall_s = float(meta.get("wall_s", 0.0))
        for g, s in zip(self.rngs, meta["rng_states"], strict=True):
            g.bit_generator.state = s
        for g, s in zip(self.eval_rngs, meta["eval_rng_states"], strict=True):
            g.bit_generator.state = s

    def to_bytes(self) -> bytes:
        """The learner's state as ``.npz`` bytes."""
        import io

        buf = io.BytesIO()
        arrays: dict[str, Any] = self.state_dict()  # numpy's stub reads **kwargs as if they could be allow_pickle
        np.savez(buf, **arrays)
        return buf.getvalue()

    def save(self, path: str | Path) -> None:
        """Write the learner's state to ``path`` (.npz) atomically."""
        atomic_write(path, self.to_bytes())


_LEGACY_SETTINGS = {"critic_init": "zero", "qdot_grid": None, "noise_tau": 0.0, "q_warp": 1.0}
"""What a checkpoint that does not name these settings was trained with."""


def load_learner(path: str | Path, spec: Spec | None = None) -> HybridLearner:
    """Rebuild a learner from a checkpoint written by :meth:`HybridLearner.save`
    (the spec's text travels inside it).

    ``spec``: the checkpoint's spec when the caller has parsed it already (``mitlc train
    --resume`` has); used only if its text is the checkpoint's, else the text is parsed."""
    from mitlc.learn.checkpoint import load_state, read_checkpoint, recorded_spec

    data, meta = read_checkpoint(path)
    if meta.get("kind") != "hyrl":
        raise InputError("not a HyRL checkpoint", file=str(path))
    if spec is None or spec.source != meta["spec_source"]:
        spec = recorded_spec(meta, path)
    # checkpoints written before these settings existed were trained without them
    saved = {**_LEGACY_SETTINGS, **meta["settings"]}
    learner = HybridLearner(spec, HyrlSettings.from_dict(saved), runs=int(meta["runs"]), seed=int(meta["seed"]))
    load_state(learner, data, path)
    return learner


def train_hybrid(
    spec: Spec,
    settings: HyrlSettings | None = None,
    runs: int = 1,
    trials: int = 800,
    seed: int = 0,
    progress: Callable[[int, np.ndarray], None] | None = None,
) -> HybridLearner:
    """Compile ``spec``'s requirements to a hybrid automaton and train HyRL on it.

    Returns the learner: ``returns (runs, trials)``, parameters ``xi``, ``theta``,
    ``wall_s``; :meth:`HybridLearner.rollout` for greedy rollouts.
    ``progress(trial, returns)`` is called after every trial.
    """
    learner = HybridLearner(spec, settings, runs=runs, seed=seed)
    learner.train(trials, progress)
    return learner
