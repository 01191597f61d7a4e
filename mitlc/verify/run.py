"""One verification: sample the scenarios for the bound, then search them for counterexamples.

:func:`verify_policy` is what ``mitlc verify`` runs between loading and writing: ``samples``
uniform scenarios rolled out in batches of :data:`CHUNK`, judged, counted and bounded; then a
falsifier's ``budget`` of rollouts from the least robust sample on. Every violating rollout of
either is counted, and the ``keep`` least robust distinct ones are kept (their states and inputs)
as the counterexamples.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.monitor.offline import MonitorResult
from mitlc.spec.model import Spec
from mitlc.verify.falsify import Search, falsify
from mitlc.verify.rollout import Judged, evaluate
from mitlc.verify.space import SearchSpace
from mitlc.verify.stats import clopper_pearson_lower

__all__ = ["CHUNK", "Sampled", "Outcome", "Counterexamples", "verify_policy"]

CHUNK = 1000
"""Sampled scenarios rolled out per batch along the run axis (the memory of one batch:
``CHUNK x (steps + 1) x n`` floats)."""


@dataclass(frozen=True)
class Sampled:
    """The uniform samples: how many, how many satisfied, the bound, and the least robust one."""

    samples: int
    satisfied: int
    confidence: float
    lower_bound: float
    least_z: np.ndarray
    least_robustness: float
    seconds: float


@dataclass(frozen=True)
class Outcome:
    """What one verification found."""

    sampled: Sampled
    search: Search | None
    """The falsifier's rollouts (None with a budget of 0)."""
    search_seconds: float
    violations: int
    """Violating rollouts, sampled and searched together."""
    counterexamples: Judged | None
    """The least robust distinct violating rollouts, least robust first (None: none violated)."""


def _subset(judged: Judged, rows: np.ndarray) -> Judged:
    r = judged.result
    res = MonitorResult(
        r.satisfied[rows], r.robustness[rows], r.violation_time[rows], tuple(r.failing[i] for i in rows)
    )
    return Judged(judged.z[rows], judged.states[rows], judged.actions[rows], judged.dt, res)


def _joined(a: Judged, b: Judged) -> Judged:
    cat = np.concatenate
    ra, rb = a.result, b.result
    res = MonitorResult(
        cat([ra.satisfied, rb.satisfied]),
        cat([ra.robustness, rb.robustness]),
        cat([ra.violation_time, rb.violation_time]),
        ra.failing + rb.failing,
    )
    return Judged(cat([a.z, b.z]), cat([a.states, b.states]), cat([a.actions, b.actions]), a.dt, res)


class Counterexamples:
    """Violating rollouts as they come: how many, and the ``keep`` least robust distinct scenarios
    (a falsifier may revisit one), least robust first; memory: ``keep`` rollouts."""

    def __init__(self, keep: int) -> None:
        self.keep = keep
        self.count = 0
        self.kept: Judged | None = None

    def add(self, judged: Judged) -> None:
        bad = np.flatnonzero(~judged.satisfied)
        if not bad.size:
            return
        self.count += int(bad.size)
        both = _subset(judged, bad) if self.kept is None else _joined(self.kept, _subset(judged, bad))
        _, first_seen = np.unique(both.z, axis=0, return_index=True)
        distinct = np.sort(first_seen)
        order = distinct[np.argsort(both.robustness[distinct], kind="stable")][: self.keep]
        self.kept = _subset(both, order)


def _least(robustness: np.ndarray) -> int:
    """The index of the least robust rollout (a NaN counts as least)."""
    return int(np.argmin(np.nan_to_num(robustness, nan=-np.inf)))


def verify_policy(
    policy: Any,
    spec: Spec,
    space: SearchSpace,
    steps: int,
    samples: int,
    budget: int,
    method: str = "de",
    seed: int = 0,
    keep: int = 3,
    confidence: float = 0.95,
) -> Outcome:
    """Sample ``samples`` scenarios of ``space`` (seeded), bound the satisfied probability, then
    search with ``method`` for ``budget`` rollouts from the least robust sample, through the whole
    budget (the least robust rollout, not only the first counterexample). Deterministic given ``seed``."""
    if samples < 1:
        raise ValueError(f"samples must be 1 or more, got {samples}")
    found = Counterexamples(keep)

    def run(z: np.ndarray) -> Judged:
        judged = evaluate(policy, spec, space, z, steps)
        found.add(judged)
        return judged

    started = time.perf_counter()
    sample_seq, search_seq = np.random.SeedSequence(seed).spawn(2)
    rng = np.random.default_rng(sample_seq)
    k = 0
    least_z, least_rob = np.zeros(space.dim), np.inf
    for a in range(0, samples, CHUNK):  # batch by batch from one generator: the points of one draw of all
        j = run(space.sample(min(CHUNK, samples - a), rng))
        k += int(j.satisfied.sum())
        i = _least(j.robustness)
        if a == 0 or j.robustness[i] < least_rob:
            least_z, least_rob = j.z[i], float(j.robustness[i])
    sampled = Sampled(
        samples,
        k,
        confidence,
        clopper_pearson_lower(k, samples, confidence),
        least_z,
        least_rob,
        time.perf_counter() - started,
    )
    search = None
    started = time.perf_counter()
    if budget > 0:

        def objective(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            j = run(z)
            return j.robustness, j.satisfied

        seed_of_search = int(search_seq.generate_state(1)[0])
        search = falsify(objective, space.dim, budget, method, seed=seed_of_search, start=least_z, stop=False)
    return Outcome(sampled, search, time.perf_counter() - started, found.count, found.kept)
