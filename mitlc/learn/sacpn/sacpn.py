"""SACPN: the standard actor-critic with a Petri net (thesis section 4-2, Algorithm 1).

The learner sees the augmented state ``(x, M)``: the plant state and the
reward net's marking.  Every place ``i`` owns one actor row ``xi_i`` and one
critic row ``theta_i`` over normalised Gaussian RBF features ``phi(x)``, and
the policy and value are the marking-weighted sums (4-5)..(4-8)::

    pi(x, M) = M Xi phi(x) / sum(M)          V(x, M) = M Theta phi(x) / sum(M)

``R`` independent runs are trained at once (a leading run axis everywhere);
run ``i`` draws all its random numbers from its own generator, spawned from
the seed, so its numbers do not depend on ``R`` and a seed reproduces a
training run to the bit.

Where the thesis is silent or, measured, does not learn, this module chooses
(each choice is a field of :class:`SacpnSettings`; ``docs/training.md`` gives
the reasons):

* **Update masking** (``mask``).  Algorithm 1 as printed weights the updates
  with ``M_k+1``, the marking *after* the step, which credits the TD error of
  entering a place to the new place.  The default, ``mask="current"``, is the
  true gradient of (4-7)/(4-8): the rows updated are those of ``M_k / sum(M_k)``
  (the places whose policy acted and whose value was estimated), and the
  critic's eligibility trace is kept per place (a ``places x features``
  matrix).  ``mask="next"`` is the printed form: one feature trace
  ``e <- lambda gamma e + phi(x_k)`` and updates ``e M_k+1``, ``phi M_k+1``.
* **Actor wind-up** (``saturation``).  The thesis's actor (2-18) moves the
  policy towards ``u + du`` whatever the input limit, so the raw output grows
  past ``u_max`` where a saturated input helped (the finding in issue 4).  The
  default, ``saturation="applied"``, clips the policy's output to the input
  bound and updates with the exploration *actually applied*:
  ``du_applied = clip(pi_sat + du) - pi_sat`` with ``pi_sat = clip(pi)``.
  Where the policy is saturated, exploration beyond the bound is never
  applied and never reinforced, so the output cannot run away (the
  conditional-integration anti-wind-up of control engineering).
  ``saturation="none"`` is the thesis's unprotected update.
* **Features**: 10x10 normalised Gaussian RBFs on a grid over the state
  bounds; an angle's kernel is periodic, ``exp((cos(q - c) - 1) / w^2)``,
  which equals ``exp(-(q - c)^2 / (2 w^2))`` to second order and wraps.
* **Exploration**: ``du ~ N(0, sigma^2)`` independent per step;
  ``sigma = sigma_frac * u_max`` unless given.
* **Several inputs** (a plant that declares them, :class:`~mitlc.plants.base.InputVar`):
  one actor output per input, ``Xi`` with an input axis ``(runs, places, inputs,
  features)``; each input is saturated (and protected from wind-up) at its own box and
  explored with its own ``sigma_frac`` x the box's half-width; the TD error and the
  critic are shared.
* **Violation penalties** (``violation_value``, ``penalty_ramp``; only with
  ``violations = permanent | counted``).  After the first violation the
  permanent charge is a known constant per step, so the critic is given its
  share of the value exactly (``c v sum_{j < N-k} gamma^j``) instead of
  learning it; and the penalty the learner is paid ramps in linearly over the
  first 3/4 of the planned trials.  Recorded returns are those of the full
  reward.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from mitlc.errors import InputError, MitlError, TrainingError
from mitlc.fileio import npz_bytes, save_npz
from mitlc.learn.checkpoint import load_state, read_checkpoint
from mitlc.learn.checkpoint import read_meta as _read_meta
from mitlc.learn.features import RbfFeatures, default_rbf, spec_grid
from mitlc.learn.settings import (
    Settings,
    check_fraction,
    check_grid,
    check_non_negative,
    check_range,
    from_dict,
    json_default,
)
from mitlc.limits import (
    MAX_LEARNER_BYTES,
    MAX_MAGNITUDE,
    MAX_RBF_WIDTH,
    MAX_TIME,
    MIN_DT,
    MIN_RBF_WIDTH,
    MIN_SPAN,
    check_steps,
)
from mitlc.petri.compile import RewardSystem
from mitlc.plants.base import Plant
from mitlc.runtime import NetRuntime, obligation_kernel
from mitlc.runtime.atoms import atom_source, compile_atoms, compile_observe, observe_source

__all__ = ["SacpnSettings", "Sacpn", "Rollout"]

MAX_SIGMA_FRAC = 1000.0
"""The largest ``sigma_frac``: exploration a thousand times the input bound is saturated already."""

_KERNELS: dict[tuple, Callable] = {}
"""Fused trial kernels compiled in this process, per (jit, plant step, predicates): a
learner built again on the same problem does not compile again."""


FORMER_DEFAULT_BOUNDS = (("qdot", -20.0, 20.0),)
"""``feature_bounds``'s default until the task suite chose the plants' own grids: settings that
carry it (a checkpoint's) are taken for plants without a ``qdot`` too, which it did not touch."""


def default_gamma(steps: int) -> float:
    """SACPN's default discount for a trial of ``steps`` steps: ``1 - 3 / steps``, the effective
    horizon ``1 / (1 - gamma)`` a third of the trial (0.97 at 100 steps), at least 0.5."""
    return max(0.5, 1.0 - 3.0 / steps)


LEGACY_SETTINGS = {"feature_grid": "plant"}
"""What settings written before these were named (a checkpoint's) were trained with."""


@dataclass(frozen=True)
class SacpnSettings(Settings):
    """Settings of the SACPN learner; defaults are Table 4-4 where the thesis gives them."""

    gamma: float | None = None
    """Discount factor; ``None`` (the default): ``1 - 3 / N`` for a trial of ``N`` steps, so that
    the discount's effective horizon ``1 / (1 - gamma)`` is a third of the trial whatever the
    plant's ``dt`` and the spec's horizon: Table 4-4's 0.97 for the pendulum's 100 steps
    (3 s at 0.03 s), chosen on the task suite (docs/suite.md). The learner's
    :attr:`Sacpn.settings` hold the value it took."""

    lam: float = 0.67
    """Eligibility trace decay lambda (Table 4-4)."""

    alpha_c: float = 0.3
    """Critic learning rate (Table 4-4)."""

    alpha_a: float = 0.1
    """Actor learning rate (Table 4-4)."""

    rbf: tuple[int, ...] | None = None
    """RBF centres per state variable, in the plant's state order; ``None`` (the default):
    from the plant's number of state variables (:func:`~mitlc.learn.features.default_rbf`):
    10 x 10 for two (Table 4-4), about 100 features in all for three to six, 2 per
    variable from seven on. The learner's :attr:`Sacpn.settings` hold the grid it took."""

    rbf_width: float = 0.5
    """Gaussian width as a multiple of the centre spacing (thesis silent; 0.5 chosen on the task
    suite, docs/suite.md, where 1.0 learned 3 of its tuning tasks' swing-ups and docks less)."""

    feature_bounds: tuple[tuple[str, float, float], ...] = ()
    """Feature grid range per variable, overriding the plant's: ``(name, lo, hi)``. Without
    an entry a variable's grid is the plant's (:attr:`~mitlc.plants.StateVar.grid`, else its
    box: the pendulum's velocity over [-20, 20], Table 4-4's range, not its 15 pi bound).
    Values outside are clipped for the features only."""

    feature_grid: str = "spec"
    """Where the feature grid lies: ``spec`` (the default), over the thresholds of the spec's
    one-variable propositions and its ``init`` range, widened by half their span each side
    (:func:`~mitlc.learn.features.spec_grid`), for the variables they bound; ``plant``: the
    plant's grid (its :attr:`~mitlc.plants.StateVar.grid`, else its box) for every variable.
    ``feature_bounds`` overrides either."""

    sigma: float | None = None
    """Exploration standard deviation of the input; ``None``: ``sigma_frac * u_max``. A plant
    with several inputs takes no one ``sigma`` (refused): each input's is from ``sigma_frac``."""

    sigma_frac: float = 0.3
    """Exploration as a fraction of the input bound when ``sigma`` is not given (of each input's
    half-range, ``(hi - lo) / 2``, for a plant that declares its inputs)."""

    trial_s: float | None = None
    """Trial duration in seconds; ``None``: the spec's ``horizon``, else 3 s (Table 4-4)."""

    dt: float | None = None
    """Sample time; ``None``: the plant's ``dt`` (0.03 s for the pendulum, Table 4-4)."""

    mask: str = "current"
    """``current``: true gradient, updates weighted by ``M_k / sum(M_k)`` with per-place
    traces (default). ``next``: Algorithm 1 as printed, updates weighted by ``M_k+1``."""

    saturation: str = "applied"
    """``applied``: clip the policy to the input bound and update with the applied
    exploration (anti-wind-up, default). ``none``: the thesis's update with the raw
    exploration; the plant still saturates the input."""

    violation_value: str = "known"
    """With ``violations = permanent``: ``known`` (default) gives the critic the penalty's
    part of the value exactly, ``c v sum_{j < N-k} gamma^j`` (from the first violation on
    the penalty is a known constant per step to the end of the trial), and the critic
    and actor both weigh the rows of the state and timing places only; ``learned``
    leaves the penalty to the critic, which then also weighs the violation places' rows."""

    penalty_ramp: float = 0.75
    """With ``violations = permanent | counted``: the penalty ``c`` the learner is paid
    grows linearly from 0 to its full value over this fraction of the planned trials
    (a continuation schedule; 0: full from the first trial). The returns recorded are
    always those of the full reward, the spec's."""

    bootstrap_timeout: bool = True
    """Treat the end of a trial as a time-out (bootstrap ``gamma V(x_N)``), not as a terminal state."""

    kernel: str = "auto"
    """How a trial is computed: ``numpy`` (the reference: vectorised over the runs),
    ``numba`` (the exact fused trial kernel of :mod:`mitlc.learn.sacpn.kernel`, compiled; needs
    ``mitlc[fast]``), ``auto`` (numba when installed, else numpy), ``simd`` (the fast kernel of
    :mod:`mitlc.learn.sacpn.simd`: the exact one with its sums over features reassociated and
    its own exp and cos, so that they vectorise; needs ``mitlc[fast]``). numpy and numba give
    the same returns and parameters to the bit where numpy's float64 sin/cos/exp are the C
    library's (x86-64 up to AVX2; on AVX-512 CPUs within about 1e-13, see
    :mod:`mitlc.learn.sacpn.kernel`; tested); ``simd`` is not exact: within 1e-9 of numpy after
    five trials on the shipped specs (tested), and like any rounding difference this grows as a
    training goes on. Problems outside the kernels' scope (environments without a numpy twin, user plants without
    ``kernel_step``, untabulated rewards, timed obligations with compact tables) train on numpy
    whatever this says (:attr:`Sacpn.kernel_reason`)."""

    @classmethod
    def thesis(cls) -> SacpnSettings:
        """Table 4-4's settings as the thesis trained chapter 4 (``mitlc train --preset thesis``):
        gamma 0.97 whatever the trial's length, a grid over the plant's box (the pendulum's
        velocity over [-20, 20]) with Gaussians one spacing wide, ``sigma_frac`` 0.3."""
        return cls(
            gamma=0.97, rbf_width=1.0, feature_grid="plant", feature_bounds=FORMER_DEFAULT_BOUNDS, sigma_frac=0.3
        )

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SacpnSettings:
        """From :meth:`to_dict` data; a checkpoint that names no ``feature_grid`` was trained on
        the plant's grid (:data:`LEGACY_SETTINGS`)."""
        return from_dict(cls, {**LEGACY_SETTINGS, **d})

    def resolved(self, plant: Plant) -> SacpnSettings:
        """These settings with what follows from ``plant`` filled in: the default ``rbf``
        grid (:func:`~mitlc.learn.features.default_rbf` of its number of state variables);
        a grid given must have one count per state variable.

        >>> from mitlc.plants import PLANTS
        >>> SacpnSettings().resolved(PLANTS["pendulum"]).rbf
        (10, 10)
        """
        n = len(plant.state)
        if self.rbf is not None:
            if len(self.rbf) != n:
                raise TrainingError(f"rbf has {len(self.rbf)} entries, the plant has {n} state variables")
            return self
        rbf = default_rbf(n)
        try:
            check_grid(rbf)
        except TrainingError as exc:
            raise TrainingError(
                f"{exc.message}: the default grid for {n} state variables",
                hint="set rbf with fewer centres (1 on some variables: --set rbf=2x2x1x...)",
            ) from None
        return replace(self, rbf=rbf)

    def check(self) -> None:
        if self.mask not in ("current", "next"):
            raise TrainingError(f"unknown mask '{self.mask}' (current or next)")
        if self.saturation not in ("applied", "none"):
            raise TrainingError(f"unknown saturation '{self.saturation}' (applied or none)")
        if self.kernel not in ("auto", "numpy", "numba", "simd"):
            raise TrainingError(f"unknown kernel '{self.kernel}' (auto, numpy, numba or simd)")
        if self.feature_grid not in ("spec", "plant"):
            raise TrainingError(f"unknown feature_grid '{self.feature_grid}' (spec or plant)")
        if self.violation_value not in ("known", "learned"):
            raise TrainingError(f"unknown violation_value '{self.violation_value}' (known or learned)")
        check_fraction(self, ("lam", "penalty_ramp"))
        if self.gamma is not None:
            check_fraction(self, ("gamma",))
        check_non_negative(self, ("alpha_c", "alpha_a"))
        check_range(self, ("sigma_frac",), 0.0, MAX_SIGMA_FRAC)
        check_range(self, ("rbf_width",), MIN_RBF_WIDTH, MAX_RBF_WIDTH)
        if self.rbf is not None:
            check_grid(self.rbf)
        seen = set()
        for entry in self.feature_bounds:
            if len(entry) != 3:
                raise TrainingError(f"feature_bounds entries are (name, lo, hi), got {entry!r}")
            name, lo, hi = entry
            if not (-MAX_MAGNITUDE <= lo < hi <= MAX_MAGNITUDE and hi - lo >= MIN_SPAN):
                raise TrainingError(
                    f"feature_bounds of '{name}' must lie in [{-MAX_MAGNITUDE:g}, {MAX_MAGNITUDE:g}] with lo < hi, "
                    f"at least {MIN_SPAN:g} apart, got [{lo:g}, {hi:g}]"
                )
            if name in seen:
                raise TrainingError(f"feature_bounds gives '{name}' twice")
            seen.add(name)
        check_range(self, ("sigma",), 0.0, MAX_MAGNITUDE, optional=True)
        check_range(self, ("trial_s", "dt"), MIN_DT, MAX_TIME, optional=True)


# ---------------------------------------------------------------- the learner


@dataclass
class Rollout:
    """One batch of trajectories: ``states (R, N+1, n)``, ``actions (R, N)`` (``(R, N, m)`` for a
    plant with ``m > 1`` inputs), marking ``codes (R, N+1)`` and ``rewards (R, N)``; ``dt`` the
    sample time."""

    states: np.ndarray
    actions: np.ndarray
    codes: np.ndarray
    rewards: np.ndarray
    dt: float

    @property
    def returns(self) -> np.ndarray:
        return self.rewards.sum(axis=1)


@dataclass
class _Snapshot:
    xi: np.ndarray
    theta: np.ndarray
    rng_states: list
    trial: int


class TraceRewardLike(Protocol):
    """What pays SACPN in place of the net (:class:`mitlc.monitor.rewards.TraceReward`)."""

    def reset(self, x0: np.ndarray) -> None: ...

    def step(self, x: np.ndarray, last: bool) -> np.ndarray: ...


class Sacpn:
    """SACPN for ``runs`` independent runs on one compiled spec.

    >>> from mitlc.spec.parse import parse_spec
    >>> from mitlc.petri.compile import compile_spec
    >>> rs = compile_spec(parse_spec('''
    ... plant pendulum(u_max = 3)
    ... init q = pi, qdot = 0
    ... prop kappa = abs(q) < 0.3
    ... formula F G kappa'''))
    >>> agent = Sacpn(rs, runs=2, seed=1)
    >>> agent.train(3).shape                       # returns: runs x trials
    (2, 3)
    """

    def __init__(
        self,
        rs: RewardSystem,
        settings: SacpnSettings | None = None,
        runs: int = 1,
        seed: int = 0,
        trace_reward: TraceRewardLike | None = None,
    ) -> None:
        self.trace_reward = trace_reward
        """What pays the learner when the spec's reward is the monitor's (``sparse``, ``robustness``,
        ``robustness-window``): a :class:`mitlc.monitor.rewards.TraceReward` over the plant's state
        columns (``mitlc train`` makes it); None where the net pays."""
        try:
            self._setup(rs, settings, runs, seed)
        except MitlError as exc:  # name the spec file where the error does not name another
            raise exc.located(rs.spec.path) from None

    def _paying(self) -> TraceRewardLike | None:
        """The monitor's reward, checked, where it pays; None where the net does."""
        if not self.rs.paid_by_monitor:
            return None
        if self.trace_reward is None:
            raise TrainingError(
                f"reward {self.rs.options.reward} is paid by the monitor: give Sacpn(..., trace_reward="
                "mitlc.monitor.rewards.TraceReward(spec, design, dt, plant state names)); mitlc train does",
                file=self.spec.path,
            )
        return self.trace_reward

    def _setup(self, rs: RewardSystem, settings: SacpnSettings | None, runs: int, seed: int) -> None:
        settings = settings or SacpnSettings()
        settings.check()
        if runs < 1:
            raise TrainingError(f"runs must be at least 1, got {runs}")
        spec = rs.spec
        plant = spec.plant
        if plant is None:
            raise TrainingError("the spec names no plant (add 'plant NAME' to train on it)")
        settings = settings.resolved(plant)  # the grid taken is the one recorded
        self.rs, self.spec, self.plant, self.settings = rs, spec, plant, settings
        self.runs, self.seed = int(runs), int(seed)
        self.params = plant.params({k: v for k, v in spec.plant_params})
        if plant.inputs is None and "u_max" not in self.params:
            if plant.stepped:
                try:
                    plant.simulator(self.params)  # says why an environment has no input bound
                except MitlError as exc:
                    raise exc.located(spec.path) from None
            raise TrainingError(
                f"plant '{plant.name}' has no input bound u_max: SACPN drives bounded inputs", file=spec.path
            )
        if settings.dt is not None:
            self.params["dt"] = float(settings.dt)
        self.dt = float(self.params["dt"])
        self.n_inputs = plant.n_inputs
        """``m``: one actor output per input; ``u`` is ``(R,)`` when it is 1, ``(R, m)`` otherwise."""
        self.u_lo, self.u_hi = plant.input_box(self.params)
        """The inputs' boxes, ``(m,)`` each: the policy is clipped to them (``[-u_max, u_max]`` for one input
        bounded by ``u_max``)."""
        self.u_max = float(max(-self.u_lo[0], self.u_hi[0])) if self.n_inputs == 1 else None
        """The input bound ``|u| <= u_max`` of a plant with one input (None with several: see :attr:`u_lo`)."""
        half = 0.5 * self.u_hi - 0.5 * self.u_lo  # [-u_max, u_max]: u_max exactly (and no overflow)
        if settings.sigma is not None and self.n_inputs > 1:
            raise TrainingError(
                f"sigma is the exploration of one input; plant '{plant.name}' has {self.n_inputs} "
                f"({', '.join(plant.input_names)})",
                hint="give sigma_frac, the exploration as a fraction of each input's half-range",
            )
        self.sigmas = np.full(1, float(settings.sigma)) if settings.sigma is not None else settings.sigma_frac * half
        """The exploration's standard deviation per input, ``(m,)``: ``sigma``, or ``sigma_frac`` times
        each box's half-width."""
        self.sigma: float | np.ndarray = float(self.sigmas[0]) if self.n_inputs == 1 else self.sigmas
        """:attr:`sigmas` as a number for a plant with one input."""
        if not np.all(self.sigmas <= MAX_MAGNITUDE):  # sigma_frac x a huge u_max: the noise would overflow
            big = int(np.argmax(self.sigmas))
            raise TrainingError(
                f"sigma_frac {settings.sigma_frac:g} x {plant.input_names[big]}'s half-range {half[big]:g} is an "
                f"exploration sigma of {self.sigmas[big]:g}, more than the {MAX_MAGNITUDE:g} supported"
                if plant.inputs is not None
                else f"sigma_frac {settings.sigma_frac:g} x u_max {half[0]:g} is an exploration sigma of "
                f"{self.sigmas[0]:g}, more than the {MAX_MAGNITUDE:g} supported",
                hint="give sigma itself (--sigma)",
            )
        horizon = settings.trial_s if settings.trial_s is not None else (spec.horizon or 3.0)
        self.trial_s = float(horizon)
        try:
            self.n_steps = check_steps(self.trial_s, self.dt, "a trial")
        except ValueError as exc:
            raise TrainingError(str(exc), file=spec.path, hint="a shorter trial_s or horizon, a larger dt") from None
        if settings.gamma is None:
            settings = replace(settings, gamma=default_gamma(self.n_steps))
            self.settings = settings
        self.gamma: float = float(settings.gamma)  # type: ignore[arg-type]
        """The discount taken: ``settings.gamma``, or ``1 - 3 / N`` for a trial of ``N`` steps."""
        self.runtime = NetRuntime(rs, plant.state_names, dt=self.dt, steps=self.n_steps)
        if self.runtime.tables is None:
            raise TrainingError(
                f"the net has too many markings for SACPN's transition tables ({len(rs.net.places)} places in "
                f"{len(rs.net.subnets)} sub-nets); split the formula or merge propositions"
            )
        self.n_places = self.runtime.n_places
        # The actor weighs the rows of the state and timing places only: a violation
        # sub-net is no reason to act differently in the same state. The critic weighs
        # the violation places' rows too, unless it is given the penalty's value
        # (violation_value = known with permanent), which is all they would carry.
        acting = [s for s, sub in enumerate(rs.net.subnets) if sub.kind != "violation"]
        tables = self.runtime.tables
        self._marked = np.ascontiguousarray(tables.marked[:, acting])
        # the penalty's known part of the value (violation_value = known, permanent only):
        # V_pen = -pen[code] G[k], pen[code] = c when the marking records a violation (a
        # permanent charge depends only on the marking entered: any row of the table
        # gives it), G[k] = sum_{j < N-k} gamma^j
        self._known = rs.options.violations == "permanent" and settings.violation_value == "known"
        if self._known:
            if tables.charge is not None:
                self._pen = rs.penalty * tables.charge.max(axis=0)
            else:  # compact tables without a reward table: the charge of the marking entered
                assert tables.markings is not None and rs.charge is not None
                m = tables.markings.astype(np.int64)
                self._pen = rs.penalty * np.asarray(rs.charge.evaluate(m, m), dtype=float)
            self._pen_left = np.array(
                [sum(self.gamma**j for j in range(self.n_steps - k)) for k in range(self.n_steps + 1)]
            )
        self._marked_c = self._marked if self._known else tables.marked
        self.n_tokens = len(acting)
        self.n_tokens_c = self._marked_c.shape[1]
        for entry in settings.feature_bounds:
            if entry[0] not in plant.state_names and tuple(entry) not in FORMER_DEFAULT_BOUNDS:
                raise TrainingError(
                    f"feature_bounds names '{entry[0]}', which plant '{plant.name}' does not have "
                    f"(its variables: {', '.join(plant.state_names)})"
                )
        bounds = spec_grid(spec) if settings.feature_grid == "spec" else {}
        bounds.update({n: (lo, hi) for n, lo, hi in settings.feature_bounds if n in plant.state_names})
        assert settings.rbf is not None  # resolved
        self.features = RbfFeatures.for_state(plant.state, settings.rbf, settings.rbf_width, bounds)
        self.n_features = self.features.n_features
        n_in = self.n_inputs
        need = (n_in + 3) * self.runs * self.n_places * self.n_features * 8  # actor (per input), critic, trace, scratch
        if need > MAX_LEARNER_BYTES:
            inputs = f" x {n_in} inputs" if n_in > 1 else ""
            raise TrainingError(
                f"{self.runs} runs x {self.n_places} places x {self.n_features} features{inputs} need "
                f"{need / 2**30:.1f} GiB "
                f"of learner arrays, more than the {MAX_LEARNER_BYTES / 2**30:.0f} GiB supported",
                hint="fewer runs (train them in several processes: mitlc sweep) or a coarser rbf grid",
            )
        init = {r.var: (r.lo, r.hi) for r in spec.init}
        self.init_ranges = [init.get(v, (0.0, 0.0)) for v in plant.state_names]
        # the copies the runs act on: an ODE plant integrated in place from starts in the
        # init ranges, or a Gymnasium environment's copies reset and stepped (gym_env)
        self.sim = plant.simulator(self.params, init)
        self.integrate = self.sim.step
        # clock code of every step's tau_k+1 (the same for all runs: they move in lock-step)
        self._clock = [self.runtime.clock_code((k + 1) * self.dt) for k in range(self.n_steps)]

        R, P, F = self.runs, self.n_places, self.n_features
        self.xi = np.zeros(self.actor_shape)
        """The actor's parameters: ``(runs, places, features)`` for a plant with one input, and
        ``(runs, places, inputs, features)`` with several (a row per place and input)."""
        self.theta = np.zeros((R, P, F))
        self.trial = 0
        self.ramp_trials: int | None = None  # fixed by the first train() (penalty_ramp x planned trials)
        self.returns = np.zeros((R, 0))
        self.diverged = np.full(R, -1, dtype=np.int64)
        """Per run: the trial (1-based) in which its parameters stopped being finite, -1 if
        they never did. A diverged run keeps its last finite parameters (it learns no more)
        and its returns from then on are NaN; the other runs go on."""
        children = np.random.SeedSequence(self.seed).spawn(R)
        pairs = [c.spawn(2) for c in children]
        self.rngs = [np.random.Generator(np.random.PCG64(p[0])) for p in pairs]
        self.eval_rngs = [np.random.Generator(np.random.PCG64(p[1])) for p in pairs]
        self._snapshot: _Snapshot | None = None
        self._choose_kernel()

    @property
    def actor_shape(self) -> tuple[int, ...]:
        """The shape of :attr:`xi`: ``(R, P, F)``, or ``(R, P, m, F)`` with ``m > 1`` inputs."""
        R, P, F, m = self.runs, self.n_places, self.n_features, self.n_inputs
        return (R, P, F) if m == 1 else (R, P, m, F)

    def _actor_rows(self) -> np.ndarray:
        """:attr:`xi` as ``(R * P, m, F)``, a view (updates through it are the learner's)."""
        if not self.xi.flags.c_contiguous:
            self.xi = np.ascontiguousarray(self.xi)
        return self.xi.reshape(self.runs * self.n_places, self.n_inputs, self.n_features)

    def _choose_kernel(self) -> None:
        """Pick the trial's path (``settings.kernel``): :attr:`kernel` is ``numpy``, ``numba`` or
        ``simd``, :attr:`kernel_reason` why numpy where the fused kernel was not taken (and why not
        the fast one where ``simd`` was asked for and the exact one trains)."""
        from mitlc.learn.sacpn import kernel as fk
        from mitlc.learn.sacpn import simd as sk

        want = self.settings.kernel
        self.kernel, self.kernel_reason = "numpy", "kernel = numpy" if want == "numpy" else None
        self._fused: Callable | None = None
        if want == "numpy":
            return
        if not fk.numba_available():
            if want in ("numba", "simd"):
                raise TrainingError(f"kernel = {want} needs numba", hint="pip install 'mitlc[fast]', or kernel = auto")
            self.kernel_reason = "numba is not installed"
            return
        if want == "simd":
            why = sk.unsupported(self)
            if why is None:
                self._fused = self.fused_trial(fk.jit, simd=True)
                self.kernel = "simd"
                return
            self.kernel_reason = f"kernel = simd cannot: {why}"
        why = fk.unsupported(self)
        if why is not None:
            self.kernel_reason = why if self.kernel_reason is None else f"{self.kernel_reason}; nor the exact kernel"
            return
        self._fused = self.fused_trial(fk.jit)
        self.kernel = "numba"

    def fused_trial(self, jit: Callable, simd: bool = False, exact_parts: bool = False) -> Callable[[], np.ndarray]:
        """One trial by the fused kernel (:mod:`mitlc.learn.sacpn.kernel`) compiled by ``jit`` (the
        identity runs it as plain Python: the test that it is :meth:`_trial_numpy`, bit for bit).
        ``simd``: by the fast kernel (:mod:`mitlc.learn.sacpn.simd`, ``kernel = simd``), with
        ``exact_parts`` the exact kernel's sums, exp and cos (its test). Compiled kernels are kept
        per plant step and predicates for the process."""
        from mitlc.learn.sacpn import kernel as fk
        from mitlc.learn.sacpn import simd as sk

        plant, rt = self.plant, self.runtime
        assert rt.tables is not None and rt.tables.reward is not None
        kernel_step, step_key = self._kernel_step()
        plain_step, pc, nwork = kernel_step(plant, self.params, fk.identity)  # pc, nwork: whatever jit
        one = self.n_inputs == 1
        timed = bool(rt.timed)  # the obligations' engine is compiled in only where the net has some

        def build(step: Callable, atoms: Callable, jit_fn: Callable) -> Callable:
            if simd:
                return sk.simd_trial_kernel(step, atoms, jit_fn, one, timed, exact_parts)
            return fk.trial_kernel(step, atoms, jit_fn, one, timed)

        kind = ("simd", exact_parts) if simd else ()  # the exact kernel's key as before
        key: tuple = (jit, plant.name, step_key, len(plant.state), one, atom_source(rt.preds, rt.columns))
        key += (timed, *kind)
        trial = _KERNELS.get(key)
        if trial is None:
            if jit is fk.identity or jit is fk.jit:
                atoms = compile_atoms(rt.preds, rt.columns, fk.identity)
                plain = build(plain_step, atoms, fk.identity)
                if jit is fk.identity:
                    trial = plain
                else:  # compiled once per machine, through the disk cache
                    from mitlc.learn import jitcache

                    trial = jitcache.load(plain)
            if trial is None:  # compiled in memory, for this process
                step = kernel_step(plant, self.params, jit)[0]
                trial = build(step, compile_atoms(rt.preds, rt.columns, jit), jit)
            _KERNELS[key] = trial
        self._kernel_fn = trial  # the compiled (or plain) trial itself, for inspection
        feats = self.features
        A = len(feats.centres)
        width = max(len(c) for c in feats.centres)
        centres = np.zeros((A, width))
        for i, c in enumerate(feats.centres):
            centres[i, : len(c)] = c
        fc = (
            np.array(feats.counts, dtype=np.int64),
            np.array(feats.periodic, dtype=np.bool_),
            np.array([b[0] for b in feats.bounds]),
            np.array([b[1] for b in feats.bounds]),
            np.array(feats.inv_w2),
            centres,
        )
        tables = rt.tables
        clock = np.array(self._clock, dtype=np.int64)
        st = self.settings
        marked = np.ascontiguousarray(self._marked, dtype=np.int64)
        marked_c = np.ascontiguousarray(self._marked_c, dtype=np.int64)
        reward_full = np.ascontiguousarray(tables.reward, dtype=float)
        pen_left = self._pen_left if self._known else np.zeros(self.n_steps + 1)
        u_lo, u_hi = np.ascontiguousarray(self.u_lo, dtype=float), np.ascontiguousarray(self.u_hi, dtype=float)
        obl = rt.obligation_arrays()  # kernel.unsupported: no compact tables with timed obligations
        sim: Any = self.sim  # an environment's GymSimulator where the plant is stepped
        work = obligation_kernel.scratch(obl)
        first = [True]

        def run() -> np.ndarray:
            if first[0]:  # numba compiles on the first call: say so where it is not loaded from the cache
                from mitlc.learn import jitcache

                jitcache.announce(trial)
                first[0] = False
            s_pen = self.penalty_scale(self.trial)
            reward_tab = reward_full
            if s_pen < 1.0:
                assert tables.charge is not None
                reward_tab = reward_full + ((1.0 - s_pen) * self.rs.penalty) * tables.charge
            pen = self._pen * s_pen if self._known else np.zeros(reward_full.shape[0])
            x, noise = self._trial_start()
            code0 = np.asarray(rt.reset_code(x, obligations=False), dtype=np.int64)  # the kernel places them
            if plant.stepped:  # an environment's copies: their twin's hidden states after the states
                x = sim.kernel_states(x)
            ret = np.zeros(self.runs)
            xi = self._actor_rows().reshape(self.runs, self.n_places, self.n_inputs, self.n_features)
            trial(
                x, noise, code0, xi, self.theta, ret, tables.next_code, clock, reward_tab, reward_full,
                marked, marked_c, pen, pen_left, pc, nwork, *fc,
                self.gamma, self.gamma * st.lam, st.alpha_c, st.alpha_a, u_lo, u_hi,
                1.0 / self.n_tokens, 1.0 / self.n_tokens_c,
                st.mask == "current", st.saturation == "applied", bool(st.bootstrap_timeout), bool(self._known),
                s_pen >= 1.0,
                obl.nodes, obl.truth, obl.temporal, *work, timed,
            )  # fmt: skip
            return ret

        return run

    def _kernel_step(self) -> tuple[Callable, Any]:
        """The plant's :attr:`~mitlc.plants.base.Plant.kernel_step` and what names it among the compiled
        kernels; for an environment with a numpy twin, one built from the twin's physics and the spec's
        reads of the observation (:func:`mitlc.learn.sacpn.kernel.env_step`), named by those reads."""
        from mitlc.learn.sacpn import kernel as fk

        plant = self.plant
        if not plant.stepped:
            assert plant.kernel_step is not None
            return plant.kernel_step, plant.kernel_step
        sim: Any = self.sim  # a GymSimulator (kernel.unsupported asked it)
        parts = sim.kernel_step(self.runs)
        assert not isinstance(parts, str), parts
        _, consts, _, k = parts
        obs = plant.observation
        exprs, periodic = [o.expr for o in obs], [o.var.periodic for o in obs]
        columns = {f"obs[{j}]": j for j in range(k)}
        n = len(obs)

        def build(plant: Plant, params: Mapping[str, float], jit: Callable) -> tuple[Callable, np.ndarray, int]:
            observe = compile_observe(exprs, columns, periodic, jit)
            physics = sim.kernel_step(self.runs, jit)[0]  # the functions it calls compiled by jit too
            return fk.env_step(jit(physics), observe, n, jit), consts, k

        return build, ("environment", observe_source(exprs, columns, periodic))

    def _trial_start(self) -> tuple[np.ndarray, np.ndarray]:
        """A trial's initial states ``(R, n)`` and exploration ``(N, R, m)``, drawn from the runs'
        generators in the one order both paths use (run by run, step by step, input by input:
        with one input, the numbers one ``standard_normal(N)`` per run gives)."""
        N, R, m = self.n_steps, self.runs, self.n_inputs
        x = np.ascontiguousarray(self.sample_init(self.rngs), dtype=float)
        noise = np.empty((N, R, m))
        for i, g in enumerate(self.rngs):
            noise[:, i, :] = g.standard_normal((N, m))
        noise *= self.sigmas
        return x, noise

    # ------------------------------------------------------------ helpers
    def sample_init(self, rngs: list[np.random.Generator]) -> np.ndarray:
        """One initial state per run from the spec's ``init`` ranges (others 0); for a
        Gymnasium plant, the copies are reset (the environment's starts inside ``init``)."""
        return self.sim.reset(rngs)

    def penalty_scale(self, trial: int) -> float:
        """The fraction of the violation penalty ``c`` paid in (0-based) ``trial``."""
        ramp = self.ramp_trials or 0
        return 1.0 if trial >= ramp else trial / ramp

    def _flat(self, code: np.ndarray, offset: np.ndarray, critic: bool = False) -> np.ndarray:
        return (self._marked_c if critic else self._marked)[code] + offset

    def policy(self, x: np.ndarray, code: np.ndarray, xi: np.ndarray | None = None) -> np.ndarray:
        """Greedy input ``pi(x, M)`` clipped to the inputs' boxes: ``(R,)`` for a plant with one
        input, ``(R, m)`` with several."""
        xi = self.xi if xi is None else xi
        R, m = x.shape[0], self.n_inputs
        phi = self.features(x)
        offset = (np.arange(R) * self.n_places)[:, None]
        flat = self._flat(code, offset)
        if m == 1:
            u = np.einsum("rkf,rf->r", xi.reshape(-1, self.n_features)[flat], phi) / self.n_tokens
            return np.clip(u, self.u_lo[0], self.u_hi[0])
        rows = xi.reshape(-1, m, self.n_features)[flat]  # (R, K, m, F)
        u = np.stack([np.einsum("rkf,rf->r", rows[:, :, i], phi) for i in range(m)], axis=1) / self.n_tokens
        return np.clip(u, self.u_lo, self.u_hi)

    def value(self, x: np.ndarray, code: np.ndarray) -> np.ndarray:
        """Critic ``V(x, M)``, ``(R,)``."""
        R = x.shape[0]
        phi = self.features(x)
        offset = (np.arange(R) * self.n_places)[:, None]
        rows = self.theta.reshape(-1, self.n_features)[self._flat(code, offset, critic=True)]
        return np.einsum("rkf,rf->r", rows, phi) / self.n_tokens_c

    # ------------------------------------------------------------ training
    def train(
        self, trials: int, callback: Callable[[int, np.ndarray], None] | None = None, total: int | None = None
    ) -> np.ndarray:
        """Run ``trials`` more trials on every run; returns their returns ``(R, trials)``.

        ``total``: the trials this learner is meant to run in all, counting those
        already done (default: done + ``trials``); the first call fixes the penalty
        ramp (``penalty_ramp``) from it, so a learner trained in chunks passes it.
        ``callback(trial, returns)`` is called after each trial.  On
        KeyboardInterrupt the learner is rolled back to the end of the last
        complete trial (so :meth:`save` then writes a consistent checkpoint)
        and the interrupt is re-raised.
        """
        if self.ramp_trials is None:
            planned = self.trial + trials if total is None else max(int(total), self.trial)
            self.ramp_trials = int(round(self.settings.penalty_ramp * planned)) if self.rs.charge is not None else 0
        out = np.zeros((self.runs, trials))
        done = 0
        try:
            for t in range(trials):
                self._snapshot = _Snapshot(
                    self.xi.copy(), self.theta.copy(), [g.bit_generator.state for g in self.rngs], self.trial
                )
                out[:, t] = self._trial()
                out[self._check_finite(), t] = np.nan
                self.trial += 1
                done = t + 1
                self.returns = np.concatenate([self.returns, out[:, t : t + 1]], axis=1)
                if callback is not None:
                    callback(self.trial, out[:, t])
        except KeyboardInterrupt:
            self._rollback()
            raise
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

    def _check_finite(self) -> np.ndarray:
        """The runs whose parameters are not finite after this trial, rolled back to the
        trial's start (their last finite values) and marked in :attr:`diverged`; stop only
        when every run has diverged."""
        bad = np.zeros(self.runs, dtype=bool)
        for arr in (self.xi, self.theta):
            bad |= ~np.isfinite(arr).reshape(self.runs, -1).all(axis=1)
        bad |= self.diverged >= 0
        if not bad.any():
            return bad
        snap = self._snapshot
        assert snap is not None  # train() takes one before every trial
        self.xi[bad] = snap.xi[bad]
        self.theta[bad] = snap.theta[bad]
        self.diverged[bad & (self.diverged < 0)] = self.trial + 1
        if bad.all():
            raise TrainingError(
                f"the parameters of every run diverged (NaN or inf), the last in trial {self.trial + 1}",
                file=self.spec.path,
                hint="lower the learning rates (alpha_a, alpha_c) or the exploration sigma",
            )
        return bad

    def _trial(self) -> np.ndarray:
        """One trial of Algorithm 1 on all runs at once; returns the undiscounted returns
        (the fused kernel's when :attr:`kernel` is ``numba``, else :meth:`_trial_numpy`'s)."""
        if self._fused is not None:
            return self._fused()
        return self._trial_numpy()

    def _trial_numpy(self) -> np.ndarray:
        """One trial of Algorithm 1 on all runs at once, vectorised; the reference.

        The hot loop: every array is preallocated, the net is two table
        look-ups, and each update touches only the rows of the marked places
        except the critic's trace update, which is one pass over ``Theta``.
        """
        st = self.settings
        R, P, F, K, KC = self.runs, self.n_places, self.n_features, self.n_tokens, self.n_tokens_c
        N = self.n_steps
        rt = self.runtime
        tables = rt.tables
        assert tables is not None  # checked in __init__
        next_code, marked, marked_c = tables.next_code, self._marked, self._marked_c
        # the penalty ramp: this trial pays s c instead of c (returns are counted with c)
        s_pen = self.penalty_scale(self.trial)
        dense = tables.reward is not None  # else (compact tables of a large net) the reward is evaluated
        reward_full: np.ndarray = tables.reward if tables.reward is not None else np.zeros((0, 0))
        reward_tab = reward_full
        if dense and s_pen < 1.0:
            assert tables.charge is not None
            reward_tab = reward_full + ((1.0 - s_pen) * self.rs.penalty) * tables.charge
        if not dense:
            reward_code, charge_code = rt.reward_code, rt.charge_code
            ramp = (1.0 - s_pen) * self.rs.penalty
        atom_code, features, integrate, clock = rt.atom_code, self.features, self.integrate, self._clock
        timed, advance = bool(rt.timed), rt.advance_code
        plain = dense and not timed
        gamma, gl = self.gamma, self.gamma * st.lam
        a_c, a_a = st.alpha_c, st.alpha_a
        m, u_lo, u_hi = self.n_inputs, self.u_lo, self.u_hi  # each input saturated to its own box
        current = st.mask == "current"
        applied = st.saturation == "applied"
        inv_k, inv_kc = 1.0 / K, 1.0 / KC
        minimum, maximum, add, subtract, multiply = (
            np.minimum,
            np.maximum,
            np.add,
            np.subtract,
            np.multiply,
        )

        xt = np.empty((len(self.plant.state), R))  # rows are contiguous: cheap column access
        x = xt.T
        x[...], noise = self._trial_start()

        theta = self.theta
        xi_f = self._actor_rows()  # (R * P, m, F)
        th_f = theta.reshape(R * P, F)
        offset = (np.arange(R) * P)[:, None]
        # critic trace, stored scaled: E = scale * E_hat (lazy decay by gamma * lambda)
        e_hat = np.zeros((R, P, F) if current else (R, F))
        e_hat_f = e_hat.reshape(R * P, F) if current else e_hat
        tmp = np.empty_like(e_hat)
        scale = 1.0

        code = rt.reset_code(x)
        paid = self._paying()  # the monitor's reward, where it pays instead of the net
        if paid is not None:
            paid.reset(x)
        # marked rows as flat indices into (R * P, F); with one token per run a 1-D index
        # (the actor's rows: flat; the critic's, which add the violation places: flat_c)
        one, one_c = K == 1, KC == 1
        mk = marked[:, 0] if one else marked
        mk_c = marked_c[:, 0] if one_c else marked_c
        off = offset[:, 0] if one else offset
        off_c = offset[:, 0] if one_c else offset
        flat = mk[code] + off
        same = KC == K  # no violation sub-nets: the critic's rows are the actor's
        flat_c = flat if same else mk_c[code] + off_c
        phi = features(x)
        phi_next = np.empty_like(phi)
        ret = np.zeros(R)
        u, a, du, coef, u_sat, over = (np.empty((R, m)) for _ in range(6))  # an entry per run and input
        v0, v1, delta, sv, u_i = (np.empty(R) for _ in range(5))
        keep = np.zeros((R, m), dtype=bool)
        a_in = a[:, 0] if m == 1 else a  # what the plant takes: (R,) for one input, (R, m) for several
        bootstrap = st.bootstrap_timeout
        known = self._known
        if known:
            pen, pen_left = self._pen * s_pen, self._pen_left
        reduce = np.add.reduce
        prods: dict[tuple[int, ...], np.ndarray] = {}
        sv_b = sv[:, None] if (one_c or not current) else sv[:, None, None]
        coef_b = coef[:, :, None] if one else coef[:, None, :, None]  # like the gathered rows (R, [K,] m, F)
        delta_b = delta[:, None]

        def dot(rows: np.ndarray, ph: np.ndarray, out: np.ndarray, single: bool) -> None:
            # products, then numpy's pairwise sums (not BLAS, whose order depends on the CPU):
            # the order the fused kernel repeats, so both give the same bits
            prod = prods.get(rows.shape)
            if prod is None:
                prod = prods[rows.shape] = np.empty(rows.shape)
            if single:
                multiply(rows, ph, out=prod)
                reduce(prod, axis=1, out=out)
            else:
                multiply(rows, ph[:, None, :], out=prod)
                reduce(reduce(prod, axis=2), axis=1, out=out)

        def rows_of(ph: np.ndarray, single: bool) -> np.ndarray:  # phi shaped like the gathered rows
            return ph if single else ph[:, None, :]

        def actor_rows_of(ph: np.ndarray) -> np.ndarray:  # phi shaped like the actor's rows (R, [K,] m, F)
            return ph[:, None, :] if one else ph[:, None, None, :]

        def act(rows: np.ndarray, ph: np.ndarray) -> None:  # u = pi(x) with the marked rows, input by input
            for i in range(m):
                dot(xi_f[rows, i], ph, u_i, one)  # summed into a contiguous row: numpy's pairwise order
                u[:, i] = u_i
            multiply(u, inv_k, out=u)

        act(flat, phi)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            for k in range(N):
                # act: u_k = pi(x_k) + du_k, saturated
                if applied:
                    minimum(u, u_hi, out=u_sat)
                    maximum(u_sat, u_lo, out=u_sat)
                    add(u_sat, noise[k], out=a)
                    minimum(a, u_hi, out=a)
                    maximum(a, u_lo, out=a)
                    subtract(a, u_sat, out=du)
                else:
                    add(u, noise[k], out=a)
                    du[:] = noise[k]
                # the plant and the net move
                integrate(x, a_in)
                code1 = next_code[clock[k], code, atom_code(x)]
                if paid is not None:  # sparse, robustness, robustness-window: the monitor pays
                    if timed:
                        code1 = advance(code1, x)
                    r = paid.step(x, k == N - 1)
                    ret += r
                elif plain:  # the tables say everything (the thesis's nets): two look-ups
                    r = reward_tab[code, code1]
                    ret += r if s_pen >= 1.0 else reward_full[code, code1]
                else:
                    if timed:
                        code1 = advance(code1, x)
                    if dense:
                        r = reward_tab[code, code1]
                        ret += r if s_pen >= 1.0 else reward_full[code, code1]
                    else:
                        r = reward_code(code, code1, x)
                        ret += r
                        if s_pen < 1.0:
                            r = r + ramp * charge_code(code, code1)
                features(x, out=phi_next)
                flat1 = mk[code1]
                flat1 += off
                if same:
                    flat1_c = flat1
                else:
                    flat1_c = mk_c[code1]
                    flat1_c += off_c
                # TD error with Theta_k
                dot(th_f[flat_c], phi, v0, one_c)
                multiply(v0, -inv_kc, out=delta)
                delta += r
                if bootstrap or k < N - 1:
                    dot(th_f[flat1_c], phi_next, v1, one_c)
                    v1 *= gamma * inv_kc
                    delta += v1
                if known:  # V_pen = -pen[code] G[k]: + pen_k G_k - gamma pen_k+1 G_k+1
                    delta += pen[code] * pen_left[k] - (gamma * pen_left[k + 1]) * pen[code1]
                # actor, per input j: xi_j += alpha_a delta du_j grad pi_j, grad pi_j = m phi(x_k)
                multiply(delta_b, du, out=coef)
                if applied:  # never move a saturated output further past the bound:
                    subtract(u, u_sat, out=over)  # > 0 above the bound, < 0 below, else 0
                    over *= coef
                    np.less_equal(over, 0.0, out=keep)
                    coef *= keep
                # critic: per-place trace (current) or one feature trace (next)
                scale *= gl
                if scale < 1e-100:
                    e_hat *= scale
                    scale = 1.0
                if current:
                    coef *= a_a * inv_k
                    xi_f[flat] += coef_b * actor_rows_of(phi)
                    e_hat_f[flat_c] += (inv_kc / scale) * rows_of(phi, one_c)
                    multiply(delta, a_c * scale, out=sv)
                    multiply(e_hat, sv[:, None, None], out=tmp)
                    theta += tmp
                else:
                    coef *= a_a
                    xi_f[flat1] += coef_b * actor_rows_of(phi)
                    e_hat += phi * (1.0 / scale)
                    multiply(delta, a_c * scale, out=sv)
                    multiply(e_hat, sv_b, out=tmp)
                    th_f[flat1_c] += tmp if one_c else tmp[:, None, :]
                # next policy output with Xi_k+1
                code, flat, flat_c = code1, flat1, flat1_c
                phi, phi_next = phi_next, phi
                act(flat, phi)
        return ret

    # ------------------------------------------------------------ evaluation
    def rollout(self, x0: np.ndarray, greedy: bool = True, rngs: list[np.random.Generator] | None = None) -> Rollout:
        """Roll the policy out from ``x0`` ``(B, n)``; every row uses run ``b % R``'s parameters.

        Greedy by default (no exploration, no learning); with ``greedy=False``
        the exploration noise is drawn from ``rngs`` (one per row).
        """
        x = np.array(x0, dtype=float)
        self.sim.start(x)  # a Gymnasium plant rolls out from where its last reset left it
        B, N, m = x.shape[0], self.n_steps, self.n_inputs
        run = np.arange(B) % self.runs
        xi = self.xi[run]
        states = np.empty((B, N + 1, x.shape[1]))
        actions = np.empty((B, N) if m == 1 else (B, N, m))
        codes = np.empty((B, N + 1), dtype=np.int64)
        rewards = np.empty((B, N))
        rt = self.runtime
        code = rt.reset_code(x)
        paid = self._paying()
        if paid is not None:
            paid.reset(x)
        states[:, 0], codes[:, 0] = x, code
        for k in range(N):
            u = self.policy(x, code, xi)
            if not greedy:
                assert rngs is not None
                if m == 1:
                    noise = np.array([g.standard_normal() for g in rngs]) * self.sigmas[0]
                    u = np.clip(u + noise, self.u_lo[0], self.u_hi[0])
                else:
                    noise = np.array([g.standard_normal(m) for g in rngs]) * self.sigmas
                    u = np.clip(u + noise, self.u_lo, self.u_hi)
            self.integrate(x, u)
            code1 = rt.step_code(code, x, (k + 1) * self.dt)
            rewards[:, k] = rt.reward_code(code, code1, x) if paid is None else paid.step(x, k == N - 1)
            code = code1
            states[:, k + 1], codes[:, k + 1], actions[:, k] = x, code, u
        return Rollout(states, actions, codes, rewards, self.dt)

    def evaluation_states(self) -> np.ndarray:
        """One initial state per run for the final greedy rollout (each run's own evaluation stream)."""
        return self.sample_init(self.eval_rngs)

    # ------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, np.ndarray]:
        from mitlc.plants.user import plant_record

        meta = {
            "trial": self.trial,
            "ramp_trials": self.ramp_trials,
            "runs": self.runs,
            "seed": self.seed,
            "settings": self.settings.to_dict(),
            "rng_states": [g.bit_generator.state for g in self.rngs],
            "eval_rng_states": [g.bit_generator.state for g in self.eval_rngs],
            "places": list(self.rs.net.place_names),
            "state_names": list(self.plant.state_names),
            "spec_source": self.spec.source or "",
            "spec_path": self.spec.path or "",
            "plant": plant_record(self.spec.plant_name or ""),  # a plant file: used again from the run's copy
            "conjunction": self.rs.options.conjunction,
            "violations": self.rs.options.violations,
            "clock": self.rs.options.clock,
            "reward": self.rs.options.reward,
            "diverged": self.diverged.tolist(),
        }
        if self.plant.inputs is not None:  # declared inputs (none recorded: one input u bounded by u_max)
            meta["inputs"] = list(self.plant.input_names)
        return {
            "xi": self.xi,
            "theta": self.theta,
            "returns": self.returns,
            "meta": np.array(json.dumps(meta, default=json_default)),
        }

    def load_state_dict(self, d: Mapping[str, np.ndarray]) -> None:
        meta = json.loads(str(d["meta"]))
        inputs = meta.get("inputs", ["u"])  # a checkpoint from before inputs were recorded: one input
        if len(inputs) != self.n_inputs:
            raise InputError(
                f"checkpoint was trained on a plant with the inputs ({', '.join(inputs)}); plant '{self.plant.name}' "
                f"has ({', '.join(self.plant.input_names)})"
            )
        shape = self.actor_shape
        if meta["runs"] != self.runs or tuple(d["xi"].shape) != shape:
            raise InputError(f"checkpoint holds {meta['runs']} runs of shape {tuple(d['xi'].shape)}, expected {shape}")
        if meta["places"] != list(self.rs.net.place_names):
            raise InputError("checkpoint was trained on a different reward net")
        if meta.get("reward", "net") != self.rs.options.reward:
            raise InputError(
                f"checkpoint was trained with reward {meta.get('reward', 'net')}, not {self.rs.options.reward}"
            )
        self.xi = np.array(d["xi"], dtype=float)
        self.theta = np.array(d["theta"], dtype=float)
        self.returns = np.array(d["returns"], dtype=float).reshape(self.runs, -1)
        self.trial = int(meta["trial"])
        self.ramp_trials = meta.get("ramp_trials")
        self.diverged = np.array(meta.get("diverged", [-1] * self.runs), dtype=np.int64).reshape(self.runs)
        self.seed = int(meta["seed"])
        for g, s in zip(self.rngs, meta["rng_states"], strict=True):
            g.bit_generator.state = s
        for g, s in zip(self.eval_rngs, meta["eval_rng_states"], strict=True):
            g.bit_generator.state = s

    def save(self, path: str | Path) -> None:
        """Write the learner's state to ``path`` (.npz) atomically."""
        save_npz(path, self.state_dict())

    def to_bytes(self) -> bytes:
        """The learner's state as the bytes of a ``.npz`` checkpoint (what :meth:`save` writes)."""
        return npz_bytes(self.state_dict())

    def load(self, path: str | Path) -> None:
        arrays, _ = read_checkpoint(path)
        load_state(self, arrays, path)


def read_meta(path: str | Path) -> dict:
    """The metadata stored in a checkpoint (settings, runs, seed, spec text...), checked."""
    return _read_meta(path)
