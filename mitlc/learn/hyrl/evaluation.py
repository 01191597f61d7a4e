"""Judging and composing HyRL policies (thesis section 3-3-3).

:func:`evaluate` runs a learner's greedy policy from a grid of initial states and judges
every rollout with the criteria checker (:class:`Evaluation`); :func:`compose` runs
policies learned separately on a spec's combined automaton, one per mode
(:class:`ComposedController`); :func:`brake_bound` is what any composition of them can
reach; :func:`train_handover` retrains a learner on the states the earlier modes hand over.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mitlc.errors import TrainingError
from mitlc.hybrid import HybridAutomaton, RewardConstants, compile_requirements
from mitlc.hybrid.criteria import Verdict, check
from mitlc.learn.hyrl.hyrl import HybridLearner, HybridRollout, _rollout
from mitlc.plants.base import Plant
from mitlc.spec.model import Spec

__all__ = [
    "Evaluation",
    "evaluate",
    "stabilised",
    "STABLE_FRACTION",
    "ComposedController",
    "compose",
    "brake_bound",
    "train_handover",
    "HANDOVER_SIGMA",
]


# ---------------------------------------------------------------- evaluation


STABLE_FRACTION = 0.1
"""A greedy response *stabilises* when it ends within this fraction of the step from the
set-point: the width of the thesis's S band (Inv(delta_3) of (B-1): 0.1 q0 <= q <= 0).
Criteria such as "no overshoot" alone are met by a controller that never moves."""


@dataclass
class Evaluation:
    """Greedy rollouts of every run from a grid of initial positions: ``passed (R, n)``
    (every requirement, by :mod:`mitlc.hybrid.criteria`), ``stabilised (R, n)`` (ends within
    :data:`STABLE_FRACTION` of the step from the set-point), ``measured[name] (R, n)``,
    ``q0 (n,)``; ``visited_p (R, n)``: the automaton reached P."""

    q0: np.ndarray
    passed: np.ndarray
    stabilised: np.ndarray
    measured: dict[str, np.ndarray]
    passed_each: dict[str, np.ndarray]
    visited_p: np.ndarray
    rollout: HybridRollout

    def ok(self, stable: bool = True) -> np.ndarray:
        """``(R, n)``: meets the criteria (and, with ``stable``, stabilises)."""
        return self.passed & self.stabilised if stable else self.passed

    def _sel(self, where: np.ndarray | None) -> np.ndarray:
        return np.ones(len(self.q0), dtype=bool) if where is None else np.asarray(where)

    def run_success(self, where: np.ndarray | None = None, stable: bool = True) -> np.ndarray:
        """Runs whose greedy policy succeeds from every initial state (of those selected by
        ``where``), ``(R,)``."""
        return np.asarray(self.ok(stable)[:, self._sel(where)].all(axis=1))

    def success_rate(self, where: np.ndarray | None = None, stable: bool = True) -> float:
        """Fraction of runs succeeding from all (selected) initial states."""
        return float(self.run_success(where, stable).mean())

    def state_rate(self, where: np.ndarray | None = None, stable: bool = True) -> float:
        """Fraction of (run, initial state) pairs that succeed."""
        return float(self.ok(stable)[:, self._sel(where)].mean())


def stabilised(automaton: HybridAutomaton, ro: HybridRollout) -> np.ndarray:
    """``(B,)``: each rollout ends within :data:`STABLE_FRACTION` of its step from the set-point."""
    s = automaton.setpoint
    return np.abs(ro.states[:, -1, 0] - s) <= STABLE_FRACTION * np.abs(ro.states[:, 0, 0] - s)


def _judge(spec_or_automaton: Spec | HybridAutomaton, ro: HybridRollout) -> Verdict:
    if isinstance(spec_or_automaton, HybridAutomaton):
        return check(spec_or_automaton.requirements, ro.states[:, :, 0], ro.dt, spec_or_automaton.setpoint)
    return check(spec_or_automaton, ro.states[:, :, 0], ro.dt)


def _grid_evaluation(
    automaton: HybridAutomaton, runs: int, n_init: int, roll: Callable[[np.ndarray, np.ndarray], HybridRollout]
) -> Evaluation:
    lo, hi = automaton.q0_range
    q0 = np.linspace(lo, hi, n_init)
    R = runs
    x0 = np.zeros((R * n_init, 2))
    x0[:, 0] = np.tile(q0, R)
    x0[:, 1] = 0.5 * sum(automaton.qdot0_range)
    run = np.repeat(np.arange(R), n_init)
    ro = roll(x0, run)
    v = _judge(automaton, ro)
    shape = (R, n_init)
    return Evaluation(
        q0=q0,
        passed=v.all.reshape(shape),
        stabilised=stabilised(automaton, ro).reshape(shape),
        measured={k: m.reshape(shape) for k, m in v.measured.items()},
        passed_each={k: p.reshape(shape) for k, p in v.passed.items()},
        visited_p=ro.visited("P").reshape(shape),
        rollout=ro,
    )


def evaluate(learner: HybridLearner, n_init: int = 50) -> Evaluation:
    """Greedy rollouts of every run from ``n_init`` initial positions evenly spaced over
    the spec's initial range (velocity at the middle of its range), judged by the checker."""
    return _grid_evaluation(learner.automaton, learner.runs, n_init, learner.rollout)


# ---------------------------------------------------------------- composition


class ComposedController:
    """Policies learned separately, run on a combined automaton (section 3-3-3).

    ``assignment[mode] = (learner, learner_mode)``: in ``mode`` the composed
    controller applies ``learner``'s greedy policy of ``learner_mode``, on that
    learner's own features (the combined automaton's ``q0``, clock and trial
    time feed them).  Run ``r`` of the composition uses run ``r`` of every learner.
    """

    def __init__(
        self,
        automaton: HybridAutomaton,
        assignment: Mapping[str, tuple[HybridLearner, str]],
        plant: Plant,
        params: Mapping[str, float],
        n_steps: int,
    ) -> None:
        self.automaton = automaton
        self.assignment = dict(assignment)
        self.plant, self.params, self.n_steps = plant, dict(params), int(n_steps)
        self.learners: list[HybridLearner] = []
        for lrn, _ in self.assignment.values():
            if all(lrn is not other for other in self.learners):
                self.learners.append(lrn)
        self.runs = min(lrn.runs for lrn in self.learners)
        # per combined mode: (learner index, learner's mode index)
        self._table = []
        for m in automaton.names:
            lrn, src = self.assignment[m]
            self._table.append((next(i for i, o in enumerate(self.learners) if o is lrn), lrn.automaton.index(src)))

    def describe(self) -> dict[str, str]:
        """``mode -> "spec:mode"`` of the policy used in each mode."""
        out = {}
        for m, (lrn, src) in self.assignment.items():
            out[m] = f"{Path(lrn.spec.path or 'spec').stem}:{src}"
        return out

    def control(self, run: np.ndarray) -> Callable[..., np.ndarray]:
        def u_of(x, q0, t, mode, tau):
            phis = [lrn.phi(x, q0, t, tau) for lrn in self.learners]
            u = np.zeros(x.shape[0])
            for m, (li, src) in enumerate(self._table):
                sel = mode == m
                if sel.any():
                    xi = self.learners[li].xi[run[sel], src]
                    u[sel] = np.einsum("bf,bf->b", xi, phis[li][sel])
            return u

        return u_of

    def rollout(self, x0: np.ndarray, run: np.ndarray | None = None) -> HybridRollout:
        x0 = np.asarray(x0, dtype=float)
        run = np.arange(x0.shape[0]) % self.runs if run is None else np.asarray(run)
        return _rollout(self.automaton, self.plant, self.params, self.n_steps, x0, self.control(run))

    def evaluate(self, n_init: int = 50) -> Evaluation:
        return _grid_evaluation(self.automaton, self.runs, n_init, self.rollout)


def brake_bound(
    ev: Evaluation,
    automaton: HybridAutomaton,
    plant: Plant,
    params: Mapping[str, float],
    mode: str = "E_Mp",
    horizon_s: float = 5.0,
) -> np.ndarray:
    """Whether *any* policy of ``mode`` could still avoid an overshoot, ``(R, n)``.

    From the first state of each rollout of ``ev`` in ``mode`` (the state handed
    over by the modes before it), the input is held at the bound against the
    motion (``-u_max`` while moving towards and past the set-point) until the mass
    turns; ``True`` where its peak stays on the start's side of the set-point.
    Rollouts that never reach ``mode`` count as avoidable when they do not
    overshoot.  An upper bound on what any policy of ``mode`` and the modes after
    it can achieve with the handovers of the modes before it.
    """
    ro = ev.rollout
    s = automaton.setpoint
    B = ro.states.shape[0]
    q0 = ro.states[:, 0, 0]
    d = np.where(q0 < s, 1.0, -1.0)  # direction of the step
    i = ro.names.index(mode)
    inmode = ro.modes == i
    reached = inmode.any(axis=1)
    first = np.argmax(inmode, axis=1)
    x = ro.states[np.arange(B), first].copy()
    peak = d * (x[:, 0] - s)
    u_max, dt = float(params["u_max"]), float(params["dt"])
    for _ in range(int(round(horizon_s / dt))):
        moving = d * x[:, 1] > 0
        if not moving.any():
            break
        x = plant.step(x, np.where(moving, -d * u_max, 0.0), params)
        peak = np.maximum(peak, d * (x[:, 0] - s))
    own = (d[:, None] * (ro.states[:, :, 0] - s)).max(axis=1) <= 0
    ok = np.where(reached, peak <= 0, own)
    return ok.reshape(ev.passed.shape)


def compose(
    spec: Spec,
    learners: Sequence[HybridLearner],
    assignment: Mapping[str, tuple[HybridLearner, str]] | None = None,
    constants: RewardConstants | None = None,
) -> ComposedController:
    """Run ``spec``'s combined automaton with policies learned separately (section 3-3-3).

    By default each evaluating mode takes the policy of the same mode from the
    first learner that has it; ``I`` takes the policy of the learner of the
    first evaluating mode, ``S`` and ``P`` those of the learner of the last
    (the mode reached just before them).  ``assignment`` overrides any mode.
    """
    if not learners:
        raise TrainingError("compose needs at least one trained learner")
    automaton = compile_requirements(spec, constants)
    chosen: dict[str, tuple[HybridLearner, str]] = {}
    owner: dict[str, HybridLearner] = {}
    for e in automaton.evaluating:
        lrn = next((lrn for lrn in learners if e in lrn.automaton.names), None)
        if lrn is not None:
            owner[e] = lrn
            chosen[e] = (lrn, e)
    given = dict(assignment or {})
    evaluating = automaton.evaluating
    if evaluating and evaluating[0] in owner:
        chosen["I"] = (owner[evaluating[0]], "I")
    if evaluating and evaluating[-1] in owner:
        for m in ("S", "P"):
            chosen[m] = (owner[evaluating[-1]], m)
    chosen.update(given)
    missing = [m for m in automaton.names if m not in chosen]
    if missing:
        raise TrainingError(
            f"no learned policy for mode(s) {', '.join(missing)} of the combined automaton",
            hint="train a spec with that criterion, or pass an assignment",
            file=spec.path,
        )
    for m, (lrn, src) in chosen.items():
        if src not in lrn.automaton.names:
            raise TrainingError(f"mode {m}: the learner of {lrn.spec.path or 'its spec'} has no mode '{src}'")
    first = next(iter(learners))
    plant = spec.plant or first.plant
    params = plant.params(dict(spec.plant_params))
    if first.settings.dt is not None:
        params["dt"] = float(first.settings.dt)
    n_steps = max(1, int(round(automaton.horizon / float(params["dt"]))))
    return ComposedController(automaton, chosen, plant, params, n_steps)


HANDOVER_SIGMA = 2.0
"""Exploration (N) of :func:`train_handover` by default: twice the learners' 1 N.  The
handed-over mass arrives at up to 3 m/s and stopping it takes inputs near the bound,
which 1 N of exploration around a policy trained on slow arrivals finds slowly.
Measured (20 runs; runs succeeding from all 50 states / states, against the brake
bound, the most any overshoot policy could do): seed 0, 1 N: 0.35 / 0.80 after 800
trials, 0.40 / 0.82 after 3200; 2 N: 0.45 / 0.87 after 400, at the bound (0.45 / 0.87);
seed 1, 800 trials: 1 N 0.25 / 0.81, 2 N 0.35 / 0.825, bound 0.35 / 0.83.  See
docs/hyrl.md."""


def train_handover(
    ctl: ComposedController,
    learner: HybridLearner,
    trials: int,
    callback: Callable[[int, np.ndarray], None] | None = None,
    sigma: float | None = HANDOVER_SIGMA,
) -> tuple[ComposedController, HybridLearner]:
    """Go on training ``learner``'s policies of the modes it runs in ``ctl`` from the
    states the other modes hand over (beyond the thesis, see docs/hyrl.md).

    Each trial starts from the combined spec's initial range; the modes run by other
    learners act greedily (no exploration, no learning); in the modes run by
    ``learner`` it explores and learns with standard actor-critic on its own critic,
    features and settings, with the combined automaton's mode-wise rewards, but
    exploring with ``sigma`` (N; ``None``: the learner's own, see
    :data:`HANDOVER_SIGMA`).  Works on a copy: returns the new controller and the
    retrained copy of ``learner`` (whose settings then name that ``sigma``).
    """
    import copy

    if not any(lrn is learner for lrn, _ in ctl.assignment.values()):
        raise TrainingError("train_handover: the learner runs no mode of the composition")
    if sigma is not None and not (math.isfinite(sigma) and sigma >= 0):
        raise TrainingError(f"train_handover: sigma must be a non-negative number, got {sigma}")
    lrn = copy.deepcopy(learner)
    if sigma is not None:
        lrn.settings = dataclasses.replace(lrn.settings, sigma=float(sigma))
    assignment = {m: ((lrn if who is learner else who), s) for m, (who, s) in ctl.assignment.items()}
    new = ComposedController(ctl.automaton, assignment, ctl.plant, ctl.params, ctl.n_steps)
    if new.runs != lrn.runs:
        raise TrainingError("train_handover: every learner of the composition needs the same number of runs")
    A, plant, params = ctl.automaton, ctl.plant, ctl.params
    src = np.array([lrn.automaton.index(s) if who is lrn else -1 for who, s in (assignment[m] for m in A.names)])
    st = lrn.settings
    R, N = lrn.runs, ctl.n_steps
    dt, u_max = float(params["dt"]), float(params["u_max"])
    gamma, gl, a_c, a_a = st.gamma, st.gamma * st.lam, st.alpha_c, st.alpha_a
    applied = st.saturation == "applied"
    rows = np.arange(R)
    G = lrn.n_modes
    xi, theta = lrn.xi, lrn.theta
    control = new.control(rows)
    (qlo, qhi), (vlo, vhi) = A.q0_range, A.qdot0_range
    start = time.perf_counter()
    for trial in range(trials):
        x = np.array([[g.uniform(qlo, qhi), g.uniform(vlo, vhi)] for g in lrn.rngs])
        noise = lrn.exploration_noise(N, dt)
        q0 = x[:, 0].copy()
        mode, t = A.reset(x)
        phi = lrn.phi(x, q0, t, 0.0)
        e = np.zeros_like(theta)
        ret = np.zeros(R)
        for k in range(N):
            u = control(x, q0, t, mode, k * dt)
            lm = src[mode]
            act = lm >= 0
            u_sat = np.clip(u, -u_max, u_max) if applied else u
            a = np.where(act, u_sat + noise[k], u_sat)
            a = np.clip(a, -u_max, u_max) if applied else a
            du = a - u_sat
            x = plant.step(x, np.clip(a, -u_max, u_max), params)
            mode1, t1, r = A.step(mode, t, x, q0, (k + 1) * dt, dt)
            ret += r
            lm1 = src[mode1]
            phi1 = lrn.phi(x, q0, t1, (k + 1) * dt)
            v0 = np.einsum("rf,rf->r", theta[rows, np.maximum(lm, 0)] + theta[:, G], phi)
            v1 = np.einsum("rf,rf->r", theta[rows, np.maximum(lm1, 0)] + theta[:, G], phi1)
            delta = r + gamma * np.where(lm1 >= 0, v1, 0.0) - v0
            if k == N - 1 and not st.bootstrap_timeout:
                delta = r - v0
            delta = np.where(act, delta, 0.0)
            coef = a_a * delta * du
            if applied:
                coef[((u >= u_max) & (coef > 0)) | ((u <= -u_max) & (coef < 0))] = 0.0
            ra = rows[act]
            xi[ra, lm[act]] += coef[act, None] * phi[act]
            e *= gl
            e[ra, lm[act]] += phi[act]
            e[ra, G] += phi[act]
            theta += (a_c * delta)[:, None, None] * e
            mode, t, phi = mode1, t1, phi1
        if not (np.isfinite(xi).all() and np.isfinite(theta).all()):
            raise TrainingError("train_handover: a parameter diverged")
        if callback is not None:
            callback(trial, ret)
    lrn.wall_s += time.perf_counter() - start
    return new, lrn
