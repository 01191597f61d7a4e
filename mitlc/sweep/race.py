"""A short race between exploration designs before a training: ``mitlc train``'s default.

No one exploration serves every spec (docs/suite.md): a small input noise (``sigma_frac``
0.3 of the input's half-range, Table 4-4's) learns the pendulum's swing-ups and fails to find
a far goal on a heavy cart; a large one (1.0) finds the cart's bay and shakes the pendulum
past its obstacle. So unless the user chose the exploration, ``mitlc train`` first trains each
design of :data:`DESIGNS` on :data:`RACE_RUNS` runs for :data:`RACE_SHARE` of the trials,
judges each design's final greedy policies with the monitor (the fraction that satisfy the
spec from their evaluation starts, ties broken by those rollouts' mean return), and trains
the full runs with the winner's settings: the training that follows is exactly
``mitlc train --set sigma_frac=WINNER`` (same seed, same numbers), and metrics.json records
the race.

The race costs ``len(DESIGNS) * RACE_RUNS * RACE_SHARE`` run-trials per trial: a third more
than the training itself for 30 runs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

__all__ = ["DESIGNS", "RACE_RUNS", "RACE_SHARE", "Entry", "Race", "race", "race_seed"]

DESIGNS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("sigma_frac=0.3", {"sigma_frac": 0.3}),
    ("sigma_frac=1", {"sigma_frac": 1.0}),
)
"""The designs raced: name and the settings each changes (chosen on the task suite's tuning half)."""

RACE_RUNS = 10
"""Runs per design in the race (fewer when the training itself has fewer)."""

RACE_SHARE = 0.5
"""The race's trials as a share of the training's."""

RACED = frozenset(k for _, d in DESIGNS for k in d) | {"sigma"}
"""Settings that, given by the user, make the race moot (the exploration is chosen)."""


@dataclass(frozen=True)
class Entry:
    """One design's result in the race."""

    name: str
    success: float
    """Fraction of its race runs whose final greedy policy the monitor accepts."""
    mean_return: float
    """Mean return of its final greedy rollouts (the tie-break: the exploration's noise left out,
    so designs that explore differently compare on the same footing)."""


@dataclass(frozen=True)
class Race:
    winner: str
    settings: Any
    """The base settings with the winner's changes: what the training runs with."""
    entries: tuple[Entry, ...]
    runs: int
    trials: int

    def record(self) -> dict[str, Any]:
        """The race as metrics.json keeps it."""
        return {
            "winner": self.winner,
            "runs": self.runs,
            "trials": self.trials,
            "designs": [
                {"name": e.name, "success": e.success, "mean_return": round(e.mean_return, 6)} for e in self.entries
            ],
        }

    def line(self) -> str:
        table = ", ".join(f"{e.name} {e.success:.2f}" for e in self.entries)
        return (
            f"race ({self.runs} runs x {self.trials} trials each, success by the monitor): {table}; {self.winner} won"
        )


def race_seed(seed: int, i: int) -> int:
    """The race's seed for design ``i``: apart from the training's own streams."""
    return int(np.random.SeedSequence([seed, 7919, i]).generate_state(1)[0] % (2**31))


def race(
    build: Callable[[Any, int, int], Any],
    judge: Callable[[Any], tuple[np.ndarray, np.ndarray]],
    settings: Any,
    runs: int,
    trials: int,
    seed: int,
    progress: Callable[[str], None] | None = None,
) -> Race:
    """Race :data:`DESIGNS` on ``settings``: ``build(settings, runs, seed)`` makes a learner,
    ``judge(learner)`` says which of its runs' final greedy policies satisfy the spec, and their
    greedy rollouts' returns."""
    r = max(1, min(RACE_RUNS, runs))
    t = max(1, int(round(trials * RACE_SHARE)))
    entries = []
    for i, (name, changes) in enumerate(DESIGNS):
        if progress is not None:
            progress(f"race: {name} ({r} runs x {t} trials)")
        agent = build(replace(settings, **changes), r, race_seed(seed, i))
        agent.train(t)
        ok, returns = judge(agent)
        finite = np.asarray(returns, dtype=float)
        finite = finite[np.isfinite(finite)]
        mean = float(finite.mean()) if finite.size else float("-inf")
        entries.append(Entry(name, float(np.mean(np.asarray(ok, dtype=bool))), mean))
    best = max(range(len(entries)), key=lambda i: (entries[i].success, entries[i].mean_return, -i))
    return Race(DESIGNS[best][0], replace(settings, **DESIGNS[best][1]), tuple(entries), r, t)
