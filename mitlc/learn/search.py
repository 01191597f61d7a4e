"""Direct policy search judged by the monitor: CMA-ES over a time-varying linear feedback.

SACPN learns from the net's reward one step at a time; some specs defeat it at every setting
the task suite tried (docs/suite.md): a cart-pole's pole tips while the Gaussian exploration
looks for a goal, a unicycle's two inputs never find a corridor's exit. Many of these have a
simple controller: a state feedback whose gains change over the horizon. This module searches
for one directly, judging whole rollouts with the spec's own verdict instead of a per-step reward.

The policy of a run, for a plant with state ``x`` (``n`` variables) and ``m`` inputs, is::

    z   = (x - centre) / scale          (an angle's difference wrapped to [-pi, pi) first)
    tau = t / horizon                    (in [0, 1])
    phi = [z, 1, tau z, tau]             (2n + 2 features)
    u   = lo + (tanh(phi W) + 1) / 2 (hi - lo)    (W: (2n + 2, m), each input in its own box)

``centre`` and ``scale`` come from the spec's ``init`` box (its centre and half-widths, at least
``scale_floor`` = a tenth of the state's half-range, so a variable pinned by ``init`` is still seen on
its own scale): a gain of 1 moves an input through most of its box for a state anywhere in the init
box. ``scale_floor = 1`` scales each variable to its half-range instead (features near 1 wherever the
state goes); ``spec_scale`` (on by default) stretches a variable's scale to the farthest of the spec's
thresholds on it (:func:`mitlc.learn.features.spec_thresholds`); ``products`` makes the state's features quadratic
(:func:`state_features`).

``harmonics = H`` adds ``sin(2 pi k t / P)`` and ``cos(2 pi k t / P)``, ``k = 1 .. H``, to ``phi``: a
periodic schedule in time, which a patrol or an oscillation needs and a linear one cannot give. The
period ``P`` is the spec's when it has one: the smallest deadline a ``G`` repeats
(:func:`recurrence_period`: 1.5 s for ``G[0,3.5] F[0,1.5] left``, which asks for a visit every 1.5 s),
else the horizon (``P = T``: ``sin(2 pi k tau)``); ``period`` sets it in seconds.

Each run is an independent CMA-ES (Hansen's ``cma`` package: step-size and covariance adaptation
that a hand-written evolution strategy would only approximate) over the ``(2n + 2 + 2H) m`` entries of
``W``, from ``W = 0`` (every input at the centre of its box). A generation rolls each of a run's
``popsize`` candidates out from the same ``starts`` initial states, drawn afresh from the ``init``
box by the run's own stream (cma samples from numpy's global generator: each run keeps its own
copy of it, so run ``r`` draws only from streams of ``(seed, r)`` and its gains do not depend on the
runs beside it; the caller's generator is left as it was), and judges every rollout with ``judge``
(the monitor, supplied by the caller: this stage does not import it). A rollout's score orders,
in turn, satisfaction, how late a violation came and how near it was to satisfaction:

* satisfied: ``2 + tanh(robustness)`` (in ``[2, 3)``: a larger margin is better);
* violated:  ``t_v / horizon + tanh(robustness)`` (in ``[-1, 1)``: a violation that comes later,
  or by less, is better; the time alone would leave a balance task whose pole falls at once
  and one whose pole falls at the end equal in robustness, the robustness alone every missed
  deadline equal in time). With ``score = mean`` the robustness is replaced by the **averaged
  robustness** (each ``G``'s minimum over its window replaced by the window's mean,
  :func:`mitlc.monitor.offline.mean_robustness`; the score is then in ``[-1, 2)``): a swing-up that
  reaches the top and falls back scores above one that never leaves the bottom, which the
  robustness (the worst sample, about ``-pi`` for both) ranks alike.

A candidate's fitness is the mean score over its starts; CMA-ES uses only the order. All runs and
candidates of a generation roll out together along the plant's run axis (one ``act``, one plant
step per sample for the whole batch) and are judged in one call. A run's policy is the mean of its
search distribution after the last generation (``xfavorite``), which is what it rolls out greedily.

On a Gymnasium environment, which cannot be put in a chosen state, a start is a seed: the copies of
every candidate of a run are reset with the same seed (drawn from the run's stream), so they start
from the same state (the environment's own start, inside the spec's ``init``), and are stepped through
the environment (:class:`mitlc.plants.gym_env.GymSimulator`; Pendulum-v1 and MountainCarContinuous-v0 by
their numpy twins, :mod:`mitlc.plants.gym_twins`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from mitlc.errors import InputError, TrainingError
from mitlc.learn.policy import Policy
from mitlc.petri.compile import RewardSystem
from mitlc.plants.base import make_integrator, wrap_angle

__all__ = [
    "usable_cores",
    "SearchSettings",
    "SearchRuns",
    "SearchPolicy",
    "features",
    "scores",
    "responses",
    "implication_triggers",
    "default_generations",
    "load_search",
    "FILE",
]

FILE = "search.npz"
"""A search's file in its training folder: the gains per run, the fitness per generation and a ``meta``
record (JSON text: the spec, the settings, runs, seed, generations, the plant's record)."""
MAX_META_CHARS = 1 << 22
SCORES = ("mean", "min", "credit")
"""The scores of a violated rollout (:attr:`SearchSettings.score`)."""


CHECK_STARTS = 8
"""Starts from which a run's final gains are checked after its training (:meth:`SearchRuns.restart_failed`),
drawn from the run's own stream ``(seed, r, 3, k)``, apart from its training and evaluation starts."""
RESTART_SHARE = 0.1
"""The share of runs that must pass their check for the others to be restarted: a design that passes
one run in ten can pass, and a round of restarts costs at most one more training of the failed runs; 0.5 held
back the unicycle patrol's response design, whose 5 to 12 runs of 30 passing became 16 to 24 with
their restarts (seeds 0-2, bench/suite/tuning/35-response-design-restart-share.json)."""


def default_generations(n_steps: int) -> int:
    """Generations per run when ``--trials`` is not given: 100, whatever the horizon (a generation is
    ``popsize * starts`` rollouts: 6,400 per run at the defaults; 40 and 100 compared on the task
    suite's tuning half: bench/suite/tuning/8-policy-search-40.json and 9-policy-search.json)."""
    return 100


@dataclass(frozen=True)
class SearchSettings:
    """The search's settings (``--set NAME=VALUE``)."""

    popsize: int = 16
    """Candidates per generation and run."""
    starts: int = 4
    """Initial states each candidate is rolled out from per generation (the same for all of a run's)."""
    sigma0: float = 0.5
    """The search's initial step size, in gains of the normalised features."""
    time_gains: bool = True
    """Whether the gains may change linearly over the horizon (the features ``tau z`` and ``tau``)."""
    harmonics: int = 0
    """Periodic terms in time: ``sin(2 pi k tau)``, ``cos(2 pi k tau)`` for ``k = 1 .. harmonics``."""
    scale_floor: float = 0.1
    """A state variable's scale is at least this share of its half-range (:class:`_Episode`): 0.1 lets
    a variable ``init`` pins be seen on its own scale; 1 scales every variable to its half-range, so a
    feature stays near 1 however far the state travels from the ``init`` box."""
    spec_scale: bool = True
    """Whether a state variable's scale also reaches the spec's thresholds on it (the boundaries of its
    propositions, :func:`mitlc.learn.features.spec_thresholds`): the farthest from the ``init`` box's centre.
    On by default since the race with it learnt 10 of the tuning half's 13 plant tasks to 0.9 against 8
    (bench/suite/tuning/14-search-spec-scale.json, 15-race-spec-scale.json); a ``search.npz`` written
    before the setting existed reloads with it off, as it was trained."""
    period: float | None = None
    """The harmonics' base period in seconds, ``sin(2 pi k t / period)``: None takes the spec's
    (:func:`recurrence_period`, the smallest deadline a ``G`` repeats) or else the horizon; 0 the horizon."""
    score: str = "min"
    """How a violated rollout is scored beside its violation time: ``min``, by its robustness, or
    ``mean``, by its averaged robustness (every ``G``'s window minimum replaced by its mean,
    :func:`mitlc.monitor.offline.mean_robustness`; the judge is then called with ``mean=True``).
    ``mean`` tells a swing-up that reaches the top and falls back from one that never leaves the
    bottom, which the robustness (the worst sample) scores alike: the race's last search design.
    ``credit`` scores a violated rollout by its credit and its non-vacuous robustness instead, with no
    violation time (:func:`mitlc.monitor.offline.credit_score`): a bounded response ``G (a -> F[0,d] b)``
    whose search, paid by the time and the robustness, postpones ``a`` and never goes on to ``b``."""
    trigger_starts: float = 0.0
    """The share of each generation's starts drawn where the antecedent of one of the formula's implications
    holds (a propositional ``a`` in ``a -> ...``: uniform over the plant's box, kept where ``a`` holds) instead of
    from the ``init`` box, so that the response is tried from where it is asked for; the evaluation starts stay
    the ``init`` box's. 0: none (mitlc's own plants only; a formula without such an antecedent draws none)."""
    products: bool = False
    """Whether the state features are quadratic (:func:`state_features`): an angle as its sine and
    cosine, and the products of every pair, so that a bearing to a point, an energy or a switching
    surface is one weighted sum."""
    miss_weight: float = 1.0
    """The weight ``w`` of a violated rollout's robustness (``score=min``; its averaged robustness, ``score=mean``)
    beside its violation time: ``t_v / T + w tanh(rho)`` (:func:`scores`). Where violation times tie, CMA-ES
    ranks the same whatever ``w``; a small one lets a later violation outrank a nearer one. 0.1 for every search
    design cost the unicycle's corridor, which a robot standing still in it violates last (0.96 -> 0.43 over
    seeds 0-2 on the tuning half: bench/suite/tuning/37-miss-weight-0.1.json), so it stays 1."""
    restarts: int = 3
    """Rounds of restarts after the training (:meth:`SearchRuns.restart_failed`): a run whose final gains
    fail the spec from any of :data:`CHECK_STARTS` starts of its own is searched again from zero, with
    streams of its own, for as many generations, and keeps the better of the two, where at least
    :data:`RESTART_SHARE` of the runs pass (a design that passes almost none is not one restarts rescue);
    each round searches again the runs the rounds before left failing. 0: none. Three rounds, not one:
    the unicycle's patrol 0.66 -> 0.90 and the cart-pole's catch 0.87 -> 0.93 over seeds 0-2, every task of
    both halves at 0.9 or more, the suite's trainings 3550 -> 3479 s (a round costs only its failed runs:
    bench/suite/tuning/38-search-restarts-3.json)."""

    def check(self) -> None:
        if self.popsize < 4:
            raise InputError(f"popsize must be at least 4, got {self.popsize}", file="--set")
        if self.harmonics < 0:
            raise InputError(f"harmonics must be at least 0, got {self.harmonics}", file="--set")
        if self.starts < 1:
            raise InputError(f"starts must be at least 1, got {self.starts}", file="--set")
        if not (np.isfinite(self.sigma0) and self.sigma0 > 0):
            raise InputError(f"sigma0 must be a positive number, got {self.sigma0}", file="--set")
        if self.period is not None and not (np.isfinite(self.period) and self.period >= 0):
            raise InputError(f"period must be a number of seconds >= 0, got {self.period}", file="--set")
        if self.score not in SCORES:
            raise InputError(f"score must be one of {', '.join(SCORES)}, got {self.score!r}", file="--set")
        if not (np.isfinite(self.trigger_starts) and 0.0 <= self.trigger_starts <= 1.0):
            raise InputError(f"trigger_starts must be a share in [0, 1], got {self.trigger_starts}", file="--set")
        if not (np.isfinite(self.miss_weight) and self.miss_weight > 0):
            raise InputError(f"miss_weight must be a positive number, got {self.miss_weight}", file="--set")
        if self.restarts < 0:
            raise InputError(f"restarts must be at least 0, got {self.restarts}", file="--set")
        if not (np.isfinite(self.scale_floor) and self.scale_floor > 0):
            raise InputError(f"scale_floor must be a positive number, got {self.scale_floor}", file="--set")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SearchSettings:
        names = {f.name for f in fields(cls)}
        # a file from before a setting existed was trained without it
        d = {"spec_scale": False, "period": 0.0, "score": "min", "restarts": 0, "miss_weight": 1.0, **d}
        return cls(**{k: v for k, v in d.items() if k in names})


def state_features(d: np.ndarray, scale: np.ndarray, angles: np.ndarray, products: bool) -> np.ndarray:
    """The state's features from the differences ``d`` ``(B, n)`` of the states from the init box's centre
    (an angle's wrapped to ``[-pi, pi)``): ``z = d / scale``; with ``products``, ``b`` = ``z`` with each angle
    (``angles``: a mask) as ``sin(d)``, ``cos(d)`` instead, followed by ``b_i b_j`` for every ``i <= j``.

    A unicycle's go-to-point steering, a turn rate in proportion to ``dy cos(theta) - dx sin(theta)``,
    is a weighted sum of such products; so is a pendulum's energy, ``omega^2 / 2 - g / l cos(theta)``.

    >>> one = np.ones(2)
    >>> state_features(np.array([[0.5, -1.0]]), one, np.array([False, False]), False).tolist()
    [[0.5, -1.0]]
    >>> state_features(np.array([[0.5, -1.0]]), one, np.array([False, False]), True).tolist()
    [[0.5, -1.0, 0.25, -0.5, 1.0]]
    >>> f = state_features(np.array([[4.0, 0.0]]), np.array([2.0, 1.0]), np.array([False, True]), True)
    >>> np.round(f, 12).tolist()
    [[2.0, 0.0, 1.0, 4.0, 0.0, 2.0, 0.0, 0.0, 1.0]]
    """
    z = d / scale
    if not products:
        return z
    parts = []
    for i in range(z.shape[1]):
        parts += [np.sin(d[:, i : i + 1]), np.cos(d[:, i : i + 1])] if angles[i] else [z[:, i : i + 1]]
    b = np.concatenate(parts, axis=1)
    left, right = np.triu_indices(b.shape[1])
    return np.concatenate([b, b[:, left] * b[:, right]], axis=1)


def features(
    z: np.ndarray, tau: float | np.ndarray, time_gains: bool, harmonics: int = 0, cycles: float = 1.0
) -> np.ndarray:
    """``[z, 1, tau z, tau]`` (``[z, 1]`` without ``time_gains``) for the normalised states ``z`` ``(B, n)``
    at the horizon's share ``tau`` (one number, or ``(B, 1)``: one per row), then ``sin(2 pi k c tau)``,
    ``cos(2 pi k c tau)`` for ``k = 1 .. harmonics``, ``c = cycles`` the periods in a horizon.

    >>> features(np.array([[0.5, -1.0]]), 0.25, True).tolist()
    [[0.5, -1.0, 1.0, 0.125, -0.25, 0.25]]
    >>> features(np.array([[0.5, -1.0]]), 0.25, False).tolist()
    [[0.5, -1.0, 1.0]]
    >>> np.round(features(np.array([[0.5, -1.0]]), 0.25, False, 2), 12).tolist()
    [[0.5, -1.0, 1.0, 1.0, 0.0, 0.0, -1.0]]
    """
    one = np.ones((z.shape[0], 1))
    parts = [z, one] if not time_gains else [z, one, tau * z, tau * one]
    for k in range(1, harmonics + 1):
        angle = 2.0 * np.pi * k * cycles * (tau * one)
        parts += [np.sin(angle), np.cos(angle)]
    return np.concatenate(parts, axis=1)


def gains_times(phi: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Each row's features times its gains: ``(B, f)`` by ``(B, f, m)`` -> ``(B, m)``, the numbers of
    ``np.einsum("bf,bfm->bm", phi, weights)`` (one sum over the features in their order per entry). With
    several inputs, one einsum per input on its strided column of gains: the same sums, 3.5x faster than
    einsum over the input axis (1024 rows, 30 features, 2 inputs: 39 us against 137 us).

    >>> phi, w = np.array([[1.0, 2.0]]), np.array([[[1.0, 0.5], [3.0, -1.0]]])
    >>> gains_times(phi, w).tolist()
    [[7.0, -1.5]]
    """
    m = weights.shape[2]
    if m == 1:
        return np.einsum("bf,bfm->bm", phi, weights)
    out = np.empty((phi.shape[0], m))
    for j in range(m):
        out[:, j] = np.einsum("bf,bf->b", phi, weights[:, :, j])
    return out


def recurrence_period(formula: Any) -> float | None:
    """The smallest finite deadline of an ``F`` (or an ``U``) that a ``G`` repeats: the period a patrol
    (``G[0,6] F[0,3] west``) or a bounded response (``G (p -> F[0,2] q)``) asks for; None when the formula
    repeats no deadline. The harmonics' base period when :attr:`SearchSettings.period` is left to the spec.

    >>> from mitlc.spec.parse import parse_formula
    >>> recurrence_period(parse_formula("G[0,6] F[0,3] a & G (b -> F[0,2.5] c) & F[0,1] d"))
    2.5
    >>> recurrence_period(parse_formula("F[0,4] G a")) is None
    True
    """
    from mitlc.spec.ast import Eventually, Globally, Until

    best: float | None = None
    stack: list[tuple[Any, bool]] = [(formula, False)]
    while stack:
        node, repeated = stack.pop()
        if repeated and isinstance(node, Eventually | Until) and 0 < node.interval.hi < np.inf:
            best = node.interval.hi if best is None else min(best, node.interval.hi)
        inner = repeated or isinstance(node, Globally)
        stack.extend((c, inner) for c in node.children)
    return best


def _temporal(f: Any) -> bool:
    """Whether the formula ``f`` holds a temporal operator."""
    from mitlc.spec import ast as A

    temporal = A.Eventually | A.Globally | A.Until | A.Release | A.WeakUntil
    return any(isinstance(m, temporal) for m in A.walk(f))


def _implications(formula: Any) -> list[Any]:
    """The formula's implications whose antecedent holds no temporal operator, in the order met (none for None)."""
    from mitlc.spec import ast as A

    nodes = A.walk(formula) if formula is not None else ()
    return [node for node in nodes if isinstance(node, A.Implies) and not _temporal(node.left)]


def implication_triggers(formula: Any) -> list[Any]:
    """The propositional antecedents ``a`` of the formula's implications ``a -> ...`` (no temporal operator in
    ``a``), each once, in the order met: where the formula asks for something (:attr:`SearchSettings.trigger_starts`).
    Empty for None.

    >>> from mitlc.spec.parse import parse_formula
    >>> [str(a) for a in implication_triggers(parse_formula("G (f -> F[0,1] s) & G ((a & b) -> c) & G (F d -> e)"))]
    ['f', 'a & b']
    """
    found: list[Any] = []
    for node in _implications(formula):
        if node.left not in found:
            found.append(node.left)
    return found


def responses(formula: Any) -> list[Any]:
    """The formula's responses: its implications ``a -> phi`` with a propositional trigger ``a`` and a
    temporal ``phi`` (a bounded response ``G (a -> F[0,d] b)``), in the order met. Empty for None.

    >>> from mitlc.spec.parse import parse_formula
    >>> [str(r) for r in responses(parse_formula("G (fast -> F[0,1] slow) & G ((a & b) -> c) & G (F d -> F e)"))]
    ['fast -> F[0,1] slow']
    """
    return [node for node in _implications(formula) if _temporal(node.right)]


def scores(
    satisfied: np.ndarray,
    robustness: np.ndarray,
    violation_time: np.ndarray,
    horizon: float,
    near: np.ndarray | None = None,
    credit: tuple[np.ndarray, np.ndarray] | None = None,
    miss_weight: float = 1.0,
) -> np.ndarray:
    """Each rollout's score (the module's text): satisfied ``2 + tanh(rho)``, violated ``t_v / T + w tanh(rho)``
    (``w``: ``miss_weight``), or with ``near`` (the averaged robustness, ``score=mean``) violated
    ``t_v / T + w tanh(near)`` (below 2 still),
    or with ``credit`` (the credit ``c`` and the non-vacuous robustness ``n``, ``score=credit``) violated
    ``c + n / (1 + |n|)`` (in ``[-1, 1]``: no violation time).

    >>> s = scores(np.array([True, False, False, False]), np.array([0.5, -0.1, -0.1, -np.inf]),
    ...            np.array([np.nan, 1.0, 3.0, 3.0]), 4.0)
    >>> [round(float(v), 4) for v in s]
    [2.4621, 0.1503, 0.6503, -0.25]
    """
    rho = np.nan_to_num(np.asarray(robustness, dtype=float), nan=-np.inf)
    tv = np.nan_to_num(np.asarray(violation_time, dtype=float), nan=0.0, posinf=horizon, neginf=0.0)
    late = np.clip(tv / horizon, 0.0, 1.0)
    if near is None:
        miss = np.tanh(np.minimum(rho, 0.0))
    else:
        miss = np.tanh(np.nan_to_num(np.asarray(near, dtype=float), nan=-np.inf))
    if credit is not None:
        c = np.nan_to_num(np.asarray(credit[0], dtype=float), nan=0.0)
        n = np.nan_to_num(np.asarray(credit[1], dtype=float), nan=-np.inf, posinf=1e300, neginf=-1e300)
        return np.where(satisfied, 2.0 + np.tanh(np.maximum(rho, 0.0)), c + n / (1.0 + np.abs(n)))
    return np.where(satisfied, 2.0 + np.tanh(np.maximum(rho, 0.0)), late + miss_weight * miss)


class _Episode:
    """The plant, its parameters and the normalisation of a spec's episodes."""

    def __init__(self, rs: RewardSystem, scale_floor: float = 0.1, spec_scale: bool = False) -> None:
        s = rs.spec
        plant = s.plant
        if plant is None:
            raise InputError("the spec names no plant: the policy search rolls candidates out on one", file=s.path)
        if s.horizon is None:
            raise InputError("the spec has no 'horizon': the policy search judges whole rollouts", file=s.path)
        self.plant = plant
        self.params = plant.params(dict(s.plant_params))
        self.dt = float(self.params["dt"])
        self.n_steps = max(1, int(round(s.horizon / self.dt)))
        self.horizon = self.n_steps * self.dt
        init = {r.var: (r.lo, r.hi) for r in s.init}
        self.init_ranges = [init.get(v.name, (0.0, 0.0)) for v in plant.state]
        lo = np.array([a for a, _ in self.init_ranges])
        hi = np.array([b for _, b in self.init_ranges])
        span = np.array([v.hi - v.lo for v in plant.state], dtype=float)
        self.centre = (lo + hi) / 2
        self.scale = np.maximum((hi - lo) / 2, scale_floor * span / 2)
        self.periodic = np.array([v.periodic for v in plant.state])
        if spec_scale:
            from mitlc.learn.features import spec_thresholds

            marks = spec_thresholds(s)
            for i, v in enumerate(plant.state):
                if v.name in marks:
                    d = marks[v.name] - self.centre[i]
                    self.scale[i] = max(self.scale[i], float(np.abs(wrap_angle(d) if v.periodic else d).max()))
        box = plant.input_box(self.params)
        self.u_lo = np.asarray(box[0], dtype=float)
        self.u_hi = np.asarray(box[1], dtype=float)
        self.n_inputs = int(self.u_lo.shape[0])

    def normalise(self, x: np.ndarray, products: bool = False) -> np.ndarray:
        """The state features of ``x`` ``(B, n)`` (:func:`state_features`)."""
        d = x - self.centre
        if self.periodic.any():
            d[:, self.periodic] = wrap_angle(d[:, self.periodic])
        return state_features(d, self.scale, self.periodic, products)

    def n_state_features(self, products: bool) -> int:
        """How many state features :meth:`normalise` gives."""
        n = len(self.centre)
        if not products:
            return n
        b = n + int(self.periodic.sum())
        return b + b * (b + 1) // 2

    def inputs(self, a: np.ndarray) -> np.ndarray:
        """``(B, m)`` pre-activations to inputs in their boxes (``(B,)`` for one input)."""
        u = self.u_lo + (np.tanh(a) + 1.0) / 2.0 * (self.u_hi - self.u_lo)
        return u[:, 0] if self.n_inputs == 1 else u


class SearchRuns:
    """``runs`` independent searches on the plant of ``rs``'s spec (see the module's text).

    ``judge(states, dt)`` returns the monitor's verdict on rollouts ``(B, N + 1, n)``: an object with
    ``satisfied``, ``robustness`` and ``violation_time`` ``(B,)`` (:func:`mitlc.monitor.monitor`'s
    result); with ``score=mean`` it is called as ``judge(states, dt, True)`` and gives ``mean_robustness``
    too (``monitor(..., mean=True)``). ``returns`` ``(runs, generations)``: each generation's best fitness per run.
    :meth:`rollout` rolls row ``b`` out with run ``b % runs``. The runs are numbered from ``first``:
    run ``r`` draws only from streams of ``(seed, r)``, so its result does not depend on the runs beside it.
    """

    def __init__(
        self,
        rs: RewardSystem,
        runs: int,
        seed: int,
        settings: SearchSettings | None = None,
        judge: Callable[..., Any] | None = None,
        first: int = 0,
        workers: int = 1,
    ) -> None:
        self.settings = settings or SearchSettings()
        self.settings.check()
        if runs < 1:
            raise InputError(f"runs must be at least 1, got {runs}", file="--runs")
        if first < 0:
            raise InputError(f"first must be at least 0, got {first}", file="--runs")
        self.rs, self.spec, self.runs, self.seed, self.first = rs, rs.spec, int(runs), int(seed), int(first)
        self.episode = ep = _Episode(rs, self.settings.scale_floor, self.settings.spec_scale)
        self.plant, self.dt, self.n_steps, self.init_ranges = ep.plant, ep.dt, ep.n_steps, ep.init_ranges
        self.params = ep.params
        self.n_inputs = ep.n_inputs
        self.judge = judge
        period, judged = self.settings.period, rs.spec.monitor_formula
        if period is None and judged is not None:  # the formula the search is judged by sets the period
            period = recurrence_period(judged)
        self.cycles = ep.horizon / period if period else 1.0
        n = ep.n_state_features(self.settings.products)
        self.n_features = ((2 * n + 2) if self.settings.time_gains else (n + 1)) + 2 * self.settings.harmonics
        self.weights: np.ndarray = np.zeros((self.runs, self.n_features, self.n_inputs))
        self.returns = np.zeros((self.runs, 0))
        self.trial = 0
        self._sim: Any = None
        if ep.plant.stepped:  # an environment: its copies are reset (candidates given the same seeds) and stepped
            self._sim = ep.plant.simulator(ep.params, {r.var: (r.lo, r.hi) for r in rs.spec.init})
            self._advance = self._sim.step
        else:
            self._advance = make_integrator(ep.plant, ep.params)
        self._runtime: Any = None
        self._ids: tuple[int, ...] | None = None  # the runs' numbers where they are not first .. first + runs - 1
        self._round = 0  # 0: the training; k: restart round k (streams of its own)
        self.restarted: list[list[int]] = []
        """The runs restarted by :meth:`restart_failed`, their numbers per round."""
        self.kept_restarts: list[list[int]] = []
        """Per round, those whose restart did better on their check and replaced them."""
        self.workers = int(workers)
        """Processes the runs are trained in (:meth:`train`): the results do not depend on it."""
        if self.workers < 1:
            raise InputError(f"workers must be at least 1, got {workers}", file="--workers")

    # ------------------------------------------------------------------ rolling out
    def _roll(self, weights: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States ``(B, N + 1, n)`` and inputs of rows ``x0`` ``(B, n)`` under gains ``weights`` ``(B, f, m)``."""
        ep, st = self.episode, self.settings
        x = np.array(x0, dtype=float)
        if self._sim is not None:  # the copies must be where the last reset left them
            self._sim.start(x)
        B, N = x.shape[0], self.n_steps
        states = np.empty((B, N + 1, x.shape[1]))
        actions = np.empty((B, N) if self.n_inputs == 1 else (B, N, self.n_inputs))
        states[:, 0] = x
        with np.errstate(all="ignore"):
            for k in range(N):
                phi = features(
                    ep.normalise(x, st.products), k * self.dt / ep.horizon, st.time_gains, st.harmonics, self.cycles
                )
                u = ep.inputs(gains_times(phi, weights))
                self._advance(x, u)
                states[:, k + 1], actions[:, k] = x, u
        return states, actions

    def _draw(self, rng: np.random.Generator, count: int) -> np.ndarray:
        return np.array([[rng.uniform(lo, hi) for lo, hi in self.init_ranges] for _ in range(count)])

    @property
    def _triggers(self) -> list[Any]:
        """The propositional antecedents of the judged formula's implications (for
        :attr:`SearchSettings.trigger_starts`: :func:`implication_triggers`)."""
        if not hasattr(self, "_trigger_list"):
            self._trigger_list = implication_triggers(self.spec.monitor_formula)
        return self._trigger_list

    def _holds(self, node: Any, x: np.ndarray) -> np.ndarray:
        """Where the propositional formula ``node`` (an antecedent of :attr:`_triggers`) holds on the states
        ``x`` ``(B, n)``: its propositions' predicates evaluated on them, an angle wrapped as the monitor
        wraps it."""
        from mitlc.spec import ast as A
        from mitlc.spec import predicates as P

        if isinstance(node, A.Const):
            return np.full(len(x), bool(node.value))
        if isinstance(node, A.Atom):
            pred = node.pred if node.pred is not None else self.spec.prop(node.name).pred
            env = {v.name: (wrap_angle(x[:, i]) if v.periodic else x[:, i]) for i, v in enumerate(self.plant.state)}
            truth: np.ndarray = P.evaluate(pred, env).astype(bool)  # type: ignore[arg-type]
            return np.broadcast_to(truth, (len(x),))
        if isinstance(node, A.Not):
            return ~self._holds(node.child, x)
        if isinstance(node, A.Weighted):
            return self._holds(node.child, x)
        if isinstance(node, A.And | A.Or | A.Implies | A.Iff):
            a, b = self._holds(node.left, x), self._holds(node.right, x)
            if isinstance(node, A.And):
                return a & b
            if isinstance(node, A.Or):
                return a | b
            return (~a | b) if isinstance(node, A.Implies) else (a == b)
        raise TypeError(f"not a propositional formula: {node}")  # _triggers holds no temporal operator

    def _draw_triggered(self, rng: np.random.Generator, count: int, batch: int = 4096, tries: int = 20) -> np.ndarray:
        """``count`` states where an antecedent of :attr:`_triggers` holds (each a uniform draw over the plant's box,
        kept where it holds, the antecedent drawn in turn); the ``init`` box's where none is found."""
        lo = np.array([v.lo for v in self.plant.state], dtype=float)
        hi = np.array([v.hi for v in self.plant.state], dtype=float)
        unbounded = ~(np.isfinite(lo) & np.isfinite(hi))  # such a variable is drawn from its init range
        lo[unbounded] = np.array([r[0] for r in self.init_ranges])[unbounded]
        hi[unbounded] = np.array([r[1] for r in self.init_ranges])[unbounded]
        out = self._draw(rng, count)
        for i in range(count):
            which = self._triggers[int(rng.integers(len(self._triggers)))]
            for _ in range(tries):
                x = lo + (hi - lo) * rng.random((batch, len(lo)))
                ok = self._holds(which, x)
                if ok.any():
                    out[i] = x[int(np.flatnonzero(ok)[0])]
                    break
        return out

    @property
    def settable(self) -> bool:
        """Whether a rollout may start anywhere (mitlc's own plants) or only where a reset put the copies
        (a Gymnasium environment: :meth:`sample_init`)."""
        return self._sim is None

    def sample_init(self, rngs: list[np.random.Generator]) -> np.ndarray:
        """One start per generator: drawn from the ``init`` box, or an environment's copies reset from it."""
        if self._sim is not None:
            return np.asarray(self._sim.reset(rngs))
        return np.stack([self._draw(g, 1)[0] for g in rngs])

    def _starts(self, rngs: list[np.random.Generator], P: int, S: int) -> np.ndarray:
        """Rows ``(R * P * S, n)``: run ``r``'s ``S`` starts of this generation, the same for each of
        its ``P`` candidates (row ``(r P + p) S + s``). An environment's copies are reset with the same
        seed for every candidate of a start, each seed drawn from the run's stream."""
        R = len(rngs)
        if self._sim is None:
            x0 = np.stack([self._draw(rngs[r], S) for r in range(R)])  # (R, S, n)
            k = int(round(self.settings.trigger_starts * S))
            if k and self._triggers:
                for r in range(R):
                    x0[r, S - k :] = self._draw_triggered(rngs[r], k)
            return np.repeat(x0, P, axis=0).reshape(R * P * S, -1)
        seeds = [[int(rngs[r].integers(2**63)) for _ in range(S)] for r in range(R)]
        gens = [np.random.default_rng(seeds[r][s]) for r in range(R) for _ in range(P) for s in range(S)]
        return self._sim.reset(gens)

    # ------------------------------------------------------------------ training
    def _fitness(self, states: np.ndarray) -> np.ndarray:
        """Each rollout's score (:func:`scores`) by the judge's verdict on rollouts ``states``."""
        near, judge = None, self.judge
        assert judge is not None  # train() refuses a search without one
        if self.settings.score == "mean":  # the judge computes the averaged robustness only when asked
            verdict = judge(states, self.dt, True)
            near = getattr(verdict, "mean_robustness", None)
            if near is None:
                raise TrainingError("the search's judge gave no averaged robustness (score=mean)")
        else:
            verdict = judge(states, self.dt)
        credit = None
        if self.settings.score == "credit":  # the judge computes the credit only when asked
            credit = getattr(judge, "credit", lambda states, dt: None)(states, self.dt)
            if credit is None:
                raise TrainingError("the search's judge gives no credit (score=credit)")
        return scores(
            verdict.satisfied,
            verdict.robustness,
            verdict.violation_time,
            self.episode.horizon,
            near,
            credit,
            self.settings.miss_weight,
        )

    def train(self, trials: int, progress: Callable[[int, int], None] | None = None) -> None:
        """``trials`` generations of every run's search; ``progress(done, total)`` after each.

        With :attr:`workers` above 1 (and ``fork`` available: not on Windows), the runs are split into
        that many contiguous parts (at most one per :data:`MIN_PART_RUNS` runs) trained at once in forked
        processes, each part's runs exactly as alone (run ``r`` draws only from its own streams): the same
        gains and fitness to the bit as one process, in less time on as many cores (``bench/bench_search.py
        --workers``)."""
        parts = min(int(self.workers), self.runs // MIN_PART_RUNS)
        if parts > 1 and _fork_context() is not None:
            self._train_forked(trials, progress, parts)
        else:
            self._train_runs(trials, progress)

    def _part(self, a: int, b: int) -> SearchRuns:
        """Runs ``a .. b - 1`` of these (numbered from :attr:`first`) as a search of their own."""
        part = SearchRuns(self.rs, b - a, self.seed, self.settings, self.judge, self.first + a)
        if self._ids is not None:
            part._ids = self._ids[a:b]
        part._round = self._round
        part.weights = self.weights[a:b].copy()
        part.returns = self.returns[a:b].copy()
        part.trial = self.trial
        return part

    def _train_forked(self, trials: int, progress: Callable[[int, int], None] | None, parts: int) -> None:
        """:meth:`train` over ``parts`` forked processes (see there)."""
        from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool

        ctx = _fork_context()
        assert ctx is not None
        cuts = np.linspace(0, self.runs, parts + 1).round().astype(int)
        done = ctx.Array("i", parts, lock=False)  # generations each part has finished, for the progress
        global _FORKED
        _FORKED = (self, cuts, done)
        pool = ProcessPoolExecutor(parts, mp_context=ctx, initializer=forked_child)
        try:
            futures = [pool.submit(_train_part, i, trials) for i in range(parts)]
            shown = -1
            while True:
                finished, pending = wait(futures, timeout=0.2, return_when=FIRST_EXCEPTION)
                now = min(done)
                if progress is not None and now > shown:
                    for g in range(shown + 1, now + 1):
                        if g > 0:
                            progress(g, trials)
                    shown = now
                if not pending or any(f.exception() is not None for f in finished):
                    break
            results = [f.result() for f in futures]  # raises a part's error, as one process would
        except BrokenProcessPool:
            _stop(pool)
            raise TrainingError(
                "a process training the search's runs died (killed, or out of memory)",
                hint="--workers 1 trains every run in this process",
            ) from None
        except BaseException:  # a part's error or an interrupt: stop them all
            _stop(pool)
            raise
        finally:
            _FORKED = None
        pool.shutdown(wait=True)
        if progress is not None:
            for g in range(max(shown, 0) + 1, trials + 1):
                progress(g, trials)
        for _, warned in results:
            raise_again(warned)
        self.weights = np.concatenate([w for (w, _), _ in results])
        self.returns = np.concatenate([r for (_, r), _ in results])
        self.trial += trials

    def _train_runs(self, trials: int, progress: Callable[[int, int], None] | None = None) -> None:
        """:meth:`train` in this process."""
        from mitlc.cmaes import load

        try:
            cma = load()
        except ImportError:
            raise InputError(
                "the policy search runs CMA-ES from the cma package, a dependency of mitlc: pip install cma",
                file="--learner",
            ) from None
        if self.judge is None:
            raise TrainingError("the policy search needs a judge (the monitor) to train")
        st = self.settings
        P, S, R = st.popsize, st.starts, self.runs
        ids = self.run_ids  # run r's streams are (seed, r, ...) whatever the runs beside it
        k = self._round  # a restart round draws its starts and its search's samples from streams of its own
        rngs = [np.random.default_rng([self.seed, r, 0] if k == 0 else [self.seed, r, 2 + 2 * k]) for r in ids]
        saved = np.random.get_state()  # cma samples from numpy's global generator: put it back afterwards
        try:
            searches, streams = [], []
            for i, r in enumerate(ids):
                stream = [self.seed, r, 2] if k == 0 else [self.seed, r, 3 + 2 * k]
                seed = int(np.random.SeedSequence(stream).generate_state(1)[0]) + 1
                opts = {"seed": seed, "popsize": P, "verbose": -9}
                searches.append(cma.CMAEvolutionStrategy(self.weights[i].ravel(), st.sigma0, opts))
                streams.append(np.random.get_state())  # the global generator as this run's search left it

            def ask(r: int) -> np.ndarray:  # each run draws from its own copy of the global generator
                np.random.set_state(streams[r])
                try:
                    return np.asarray(searches[r].ask())
                finally:
                    streams[r] = np.random.get_state()

            best = np.zeros((R, trials))
            for g in range(trials):
                cand = np.array([ask(r) for r in range(R)])  # (R, P, dim)
                W = np.repeat(cand.reshape(R * P, self.n_features, self.n_inputs), S, axis=0)
                states, _ = self._roll(W, self._starts(rngs, P, S))
                fit = self._fitness(states).reshape(R, P, S).mean(axis=2)
                if not np.all(np.isfinite(fit)):
                    raise TrainingError(f"the policy search's fitness is not finite in generation {g + 1}")
                for r in range(R):
                    np.random.set_state(streams[r])
                    searches[r].tell(list(cand[r]), list(-fit[r]))  # cma minimises
                    streams[r] = np.random.get_state()
                best[:, g] = fit.max(axis=1)
                self.trial += 1
                if progress is not None:
                    progress(g + 1, trials)
            self.weights = np.asarray([s.result.xfavorite for s in searches], dtype=float).reshape(self.weights.shape)
            self.returns = np.concatenate([self.returns, best], axis=1)
        finally:
            np.random.set_state(saved)

    @property
    def run_ids(self) -> tuple[int, ...]:
        """The runs' numbers: ``first .. first + runs - 1`` (a restart's: the runs it searches again)."""
        return self._ids if self._ids is not None else tuple(range(self.first, self.first + self.runs))

    # ------------------------------------------------------------------ restarts
    def check_scores(self) -> np.ndarray:
        """``(runs, CHECK_STARTS)``: each run's final gains scored (:func:`scores`) from its own check
        starts (stream ``(seed, r, 3, k)``; an environment's copies reset from them): a run passes where
        every score is at least 2 (every rollout satisfies the spec)."""
        ids, V = self.run_ids, CHECK_STARTS
        x0 = self.sample_init([np.random.default_rng([self.seed, r, 3, k]) for r in ids for k in range(V)])
        states, _ = self._roll(np.repeat(self.weights, V, axis=0), x0)
        return self._fitness(states).reshape(len(ids), V)

    def restart_failed(self, generations: int, progress: Callable[[int, int], None] | None = None) -> None:
        """After the training: :attr:`SearchSettings.restarts` rounds of restarts. In each, every run's final
        gains are checked from :data:`CHECK_STARTS` starts of its own (:meth:`check_scores`); where at least
        :data:`RESTART_SHARE` of the runs pass and some fail, the failed runs are searched again from zero gains
        for ``generations``, each with streams of its own for the round (starts ``(seed, r, 2 + 2k)``, samples
        ``(seed, r, 3 + 2k)``), in the processes :meth:`train` uses, and a run takes the restart's gains (and its
        fitness over those generations) where they score higher on the same check starts. CMA-ES from one start
        sometimes settles where no gain helps (a cart-pole that lets the pole fall at once: -0.85 against the
        others' 2.09, 6 of 30 runs on the suite's catch); a new start usually does not (IPOP-CMA-ES restarts for
        the same reason). A run's restart depends on the others only through the share that passed. ``progress``
        as :meth:`train`'s, counting the restarts' generations."""
        if generations < 1 or self.judge is None or self.settings.restarts < 1:
            return
        before = self.check_scores()  # a round changes only the rows that kept a restart: their scores follow
        for k in range(1, self.settings.restarts + 1):
            passed = before.min(axis=1) >= 2.0
            if passed.all() or passed.mean() < RESTART_SHARE:
                return
            rows = np.flatnonzero(~passed)
            again = SearchRuns(self.rs, len(rows), self.seed, self.settings, self.judge, workers=self.workers)
            again._ids = tuple(self.run_ids[i] for i in rows)
            again._round = k
            again.train(generations, progress)
            after = again.check_scores()
            g = min(generations, self.returns.shape[1])
            self.restarted.append(list(again._ids))
            self.kept_restarts.append([])
            for j, i in enumerate(rows):
                if after[j].mean() > before[i].mean():
                    before[i] = after[j]
                    self.weights[i] = again.weights[j]
                    self.returns[i, self.returns.shape[1] - g :] = again.returns[j, again.returns.shape[1] - g :]
                    self.kept_restarts[-1].append(again._ids[j])

    # ------------------------------------------------------------------ judging
    def evaluation_states(self) -> np.ndarray:
        """One initial state per run, drawn from the ``init`` box by run ``r``'s evaluation stream ``(seed, r, 1)``
        (an environment's copies reset from it)."""
        return self.sample_init([np.random.default_rng([self.seed, r, 1]) for r in self.run_ids])

    @property
    def runtime(self) -> Any:
        if self._runtime is None:
            from mitlc.runtime import NetRuntime

            self._runtime = NetRuntime(self.rs, self.plant.state_names, dt=self.dt, steps=self.n_steps)
        return self._runtime

    def rollout(self, x0: np.ndarray) -> Any:
        """Greedy rollouts from ``x0`` ``(B, n)``, row ``b`` by run ``b % runs``, as a
        :class:`mitlc.learn.sacpn.Rollout` (with the net's markings and compiled rewards along them)."""
        from mitlc.learn.sacpn import Rollout

        x0 = np.atleast_2d(np.asarray(x0, dtype=float))
        B = x0.shape[0]
        states, actions = self._roll(self.weights[np.arange(B) % self.runs], x0)
        rt = self.runtime
        codes = np.empty((B, self.n_steps + 1), dtype=np.int64)
        rewards = np.empty((B, self.n_steps))
        code = rt.reset_code(states[:, 0].copy())
        codes[:, 0] = code
        for k in range(self.n_steps):
            code1 = rt.step_code(code, states[:, k + 1].copy(), (k + 1) * self.dt)
            rewards[:, k] = rt.reward_code(code, code1, states[:, k + 1].copy())
            codes[:, k + 1] = code = code1
        return Rollout(states, actions, codes, rewards, self.dt)

    def trained_state(self) -> tuple[np.ndarray, np.ndarray, int]:
        """What training changed: the gains, each run's last fitness and the generations (what a process
        that trained these runs sends back: :meth:`restore_trained_state`)."""
        return self.weights, self.returns, self.trial

    def restore_trained_state(self, state: tuple[np.ndarray, np.ndarray, int]) -> None:
        """These runs as trained elsewhere (:meth:`trained_state` of the same runs, seed and settings)."""
        weights, returns, trial = state
        if weights.shape != self.weights.shape or returns.shape[:1] != self.returns.shape[:1]:
            raise ValueError("restore_trained_state: the state of other runs")
        self.weights, self.returns, self.trial = weights, returns, int(trial)

    def joined(self, rest: SearchRuns) -> SearchRuns:
        """These runs followed by ``rest`` (runs ``first + runs``, ... of the same seed, settings and
        generations) as one search: what a search of all of them at once gives, to the bit (each run
        draws from streams of its own; ``mitlc train``'s race keeps its search runs this way)."""
        if (rest.seed, rest.settings, rest.trial, rest.first) != (
            self.seed,
            self.settings,
            self.trial,
            self.first + self.runs,
        ):
            raise ValueError("joined: the runs that follow must share the seed, settings and generations")
        workers = max(self.workers, rest.workers)  # what restart_failed trains in (the numbers do not depend on it)
        both = SearchRuns(self.rs, self.runs + rest.runs, self.seed, self.settings, self.judge, self.first, workers)
        both.weights = np.concatenate([self.weights, rest.weights])
        both.returns = np.concatenate([self.returns, rest.returns])
        both.trial = self.trial
        return both

    def policy(self) -> SearchPolicy:
        """The trained runs as a :class:`mitlc.learn.policy.Policy`."""
        return SearchPolicy(self)

    # ------------------------------------------------------------------ files
    def file_bytes(self) -> bytes:
        """The search as :data:`FILE`'s bytes (plain arrays and a JSON record: no code)."""
        import io
        import json

        from mitlc.plants.user import plant_record

        meta = {
            "kind": "search",
            "runs": self.runs,
            "seed": self.seed,
            "first": self.first,
            "trial": self.trial,
            "settings": self.settings.to_dict(),
            "spec_source": self.spec.source or "",
            "spec_path": self.spec.path or "",
            "plant": plant_record(self.spec.plant_name or ""),
            "conjunction": self.rs.options.conjunction,
            "violations": self.rs.options.violations,
            "clock": self.rs.options.clock,
            "reward": self.rs.options.reward,
        }
        buf = io.BytesIO()
        np.savez(buf, weights=self.weights, returns=self.returns, meta=np.array(json.dumps(meta)))
        return buf.getvalue()


MIN_PART_RUNS = 4
"""The fewest runs a forked part trains: a generation's numpy calls cost about a third of its time whatever
the rows (cart-pole, 8 runs), so a part of fewer runs spends more on overhead than it saves."""
MAX_WORKERS = 8
"""The most processes :func:`usable_cores` suggests (each holds its own copy of the plant's batch)."""


def usable_cores() -> int:
    """The cores this process may run on, at most :data:`MAX_WORKERS`: ``mitlc train``'s default ``--workers``."""
    import os

    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    return max(1, min(MAX_WORKERS, cores))


_FORKED: Any = None
"""The search a forked part trains a share of (:meth:`SearchRuns._train_forked`), inherited by fork."""


def _fork_context() -> Any:
    """multiprocessing's ``fork`` context, or None where there is none (Windows)."""
    import multiprocessing

    try:
        return multiprocessing.get_context("fork")
    except ValueError:  # pragma: no cover - not POSIX
        return None


def forked_child() -> None:
    """What a process mitlc forks to train in does first (the initializer of its pools): leave Ctrl-C to the
    parent, which stops it, and hold one core, its BLAS and LAPACK thread pools set to one thread
    (threadpoolctl), so that ``workers`` such processes share the cores instead of each spinning a pool."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency; a trimmed install trains, only slower
        return
    threadpool_limits(1)


def _stop(pool: Any) -> None:
    """Terminate a process pool's workers and shut it down without waiting for their tasks."""
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        proc.terminate()
    pool.shutdown(wait=False, cancel_futures=True)


def _train_part(i: int, trials: int) -> tuple[tuple[np.ndarray, np.ndarray], list]:
    """In a forked process: part ``i`` of :data:`_FORKED`'s runs, trained; its gains and fitness, and the
    warnings it raised (:func:`caught`)."""
    search, cuts, done = _FORKED
    part = search._part(int(cuts[i]), int(cuts[i + 1]))

    def tick(g: int, total: int) -> None:
        done[i] = g

    def train() -> tuple[np.ndarray, np.ndarray]:
        part._train_runs(trials, tick)
        return part.weights, part.returns

    return caught(train)


def caught(fn: Callable[[], Any]) -> tuple[Any, list]:
    """In a forked process: ``fn()`` and the warnings it raised, each place once (text, category, file,
    line), for the parent to raise again (:func:`raise_again`): a warning raised in the process would
    otherwise be lost with it (``mitlc train`` says numpy's overflows once, at its end)."""
    import warnings

    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        out = fn()
    seen = {(str(w.message), w.category, w.filename, w.lineno): None for w in got}
    return out, list(seen)


def raise_again(warned: list) -> None:
    """The warnings a forked process raised (:func:`caught`), raised here, where they were raised there."""
    import warnings

    for text, category, filename, lineno in warned:
        warnings.warn_explicit(text, category, filename, lineno)


def _damaged(where: str, why: str) -> InputError:
    return InputError(f"damaged search file: {why}", file=where)


def load_search(folder: Any) -> SearchRuns:
    """The :class:`SearchRuns` a ``mitlc train --learner search`` folder holds (its :data:`FILE`),
    on the spec it was trained on; every field checked before use, a damaged file is one line."""
    import json
    from pathlib import Path

    from mitlc.npzfile import NpzArchive
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.plants.user import restore_plant
    from mitlc.spec.parse import parse_spec

    path = Path(folder) / FILE
    where = str(path)
    if not path.is_file():
        raise InputError(f"no {FILE} in {folder}: not a --learner search training", file=str(folder))
    with NpzArchive(path, "search file") as z:
        for name in ("meta", "weights", "returns"):
            if name not in z:
                raise _damaged(where, f"no '{name}' record")
        head = z.header("meta")
        if head.dtype.kind != "U" or head.shape != () or head.dtype.itemsize // 4 > MAX_META_CHARS:
            raise _damaged(where, "its 'meta' record is not a JSON text")
        try:
            meta = json.loads(str(z.read("meta", head.nbytes)[()]))
        except (ValueError, RecursionError):
            raise _damaged(where, "its 'meta' record is not JSON") from None
        if not isinstance(meta, dict) or meta.get("kind") != "search":
            raise _damaged(where, "its 'meta' record is not a search's")
        try:
            runs, seed, trial = (int(meta[k]) for k in ("runs", "seed", "trial"))
            first = int(meta.get("first", 0))
            settings = SearchSettings.from_dict(dict(meta["settings"]))
            settings.check()
            source, spec_path = str(meta["spec_source"]), str(meta["spec_path"])
        except (KeyError, TypeError, ValueError, InputError) as exc:
            raise _damaged(where, f"its 'meta' record is incomplete ({type(exc).__name__}: {exc})") from None
        wh, rh = z.header("weights"), z.header("returns")
        limit = 1 << 30
        if wh.dtype.kind != "f" or rh.dtype.kind != "f" or len(wh.shape) != 3 or rh.shape != (runs, trial):
            raise _damaged(where, f"arrays of shapes {wh.shape} and {rh.shape} do not fit {runs} runs x {trial}")
        weights, returns = z.read("weights", limit), z.read("returns", limit)
    restore_plant(meta.get("plant"), path.parent, where=where)
    spec = parse_spec(source, spec_path or None)
    options = CompileOptions.from_spec(
        spec, **{k: meta.get(k) for k in ("conjunction", "violations", "clock", "reward")}
    )
    try:
        search = SearchRuns(compile_spec(spec, options), runs, seed, settings, first=first)
    except InputError as exc:
        raise _damaged(where, str(exc)) from None
    if weights.shape != search.weights.shape or not np.isfinite(weights).all():
        raise _damaged(where, f"its gains have shape {weights.shape}, not {search.weights.shape}, or are not finite")
    search.weights, search.returns, search.trial = np.asarray(weights, float), np.asarray(returns, float), trial
    return search


class SearchPolicy(Policy):
    """A search's runs as a :class:`mitlc.learn.policy.Policy`: its state is the sample count ``(B,)``."""

    def __init__(self, runs: SearchRuns) -> None:
        self.search = runs
        self.spec = runs.spec
        self.runs = runs.runs
        self.dt = runs.dt

    def reset(self, x0: np.ndarray) -> np.ndarray:
        return np.zeros(np.atleast_2d(x0).shape[0], dtype=np.int64)

    def act(self, x: np.ndarray, state: np.ndarray) -> np.ndarray:
        s = self.search
        x = np.atleast_2d(np.asarray(x, dtype=float))
        W = s.weights[np.arange(x.shape[0]) % s.runs]
        tau = np.asarray(state, dtype=float)[:, None] * s.dt / s.episode.horizon
        st = s.settings
        phi = features(s.episode.normalise(x, st.products), tau, st.time_gains, st.harmonics, s.cycles)
        return s.episode.inputs(gains_times(phi, W))

    def step(self, state: np.ndarray, x_next: np.ndarray) -> np.ndarray:
        return np.asarray(state) + 1
