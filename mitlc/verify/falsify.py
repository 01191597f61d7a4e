"""Falsification: a budgeted search of the scenario cube for the least robust rollout.

The objective is the monitor's robustness of the rollout from a point ``z`` of
``[0, 1]^dim`` (:class:`~mitlc.verify.space.SearchSpace`); a point whose rollout violates
the spec is a counterexample. Every optimiser proposes a batch of points at a time, and the
batch is rolled out at once along the plant's run axis:

* ``cma``: CMA-ES (the ``cma`` package, Hansen's), in the cube's bounds, restarted with a
  doubled population (IPOP) when it converges before the budget is spent;
* ``de``: scipy's differential evolution, its whole population per call (``vectorized``);
* ``uniform``: uniform sampling of the cube, the baseline an optimiser must beat.

The search stops at the end of the first batch with a counterexample (``stop=True``) or when
``budget`` rollouts are spent; which optimiser found counterexamples with fewer rollouts on
a planted weakness is measured in docs/verify.md.

>>> import numpy as np
>>> def objective(z):                       # violated near z = (0.8, 0.8) only
...     rob = np.linalg.norm(z - 0.8, axis=1) - 0.05
...     return rob, rob >= 0
>>> s = falsify(objective, 2, budget=400, method="uniform", seed=1)
>>> s.found, s.rollouts <= 400
(True, True)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mitlc.errors import InputError

__all__ = ["METHODS", "Search", "falsify"]

METHODS = ("cma", "de", "uniform")

Objective = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``z (B, dim) -> (robustness (B,), satisfied (B,))``: one batch of rollouts, judged."""

SCOUTS = 3
"""CMA-ES (without a ``start``, and at each restart) first rolls out this many populations' worth of
uniform points and starts from the least robust of them."""

LARGE = 1e300
"""What an optimiser sees for a non-finite robustness (a rollout that diverged: +-inf, nan)."""


@dataclass(frozen=True)
class Search:
    """What a falsifier evaluated, in order."""

    method: str
    z: np.ndarray
    """Every point rolled out, ``(rollouts, dim)``."""
    robustness: np.ndarray
    satisfied: np.ndarray
    first: int | None
    """Rollouts spent up to the end of the batch with the first counterexample (None: none found)."""

    @property
    def rollouts(self) -> int:
        return int(self.z.shape[0])

    @property
    def found(self) -> bool:
        return self.first is not None

    def worst(self, k: int) -> np.ndarray:
        """Indices of the ``k`` least robust rollouts that violate the spec, least robust first."""
        bad = np.flatnonzero(~self.satisfied)
        return bad[np.argsort(self.robustness[bad], kind="stable")][:k]


class _Done(Exception):
    """The budget is spent, or a counterexample was found (scipy's optimiser is stopped by raising)."""


class _Ledger:
    """The points evaluated so far, the budget, and the stop rule."""

    def __init__(self, objective: Objective, dim: int, budget: int, stop: bool) -> None:
        self.objective, self.dim, self.budget, self.stop = objective, dim, budget, stop
        self.z: list[np.ndarray] = []
        self.rob: list[np.ndarray] = []
        self.sat: list[np.ndarray] = []
        self.spent = 0
        self.first: int | None = None

    @property
    def left(self) -> int:
        return self.budget - self.spent

    def __call__(self, z: np.ndarray) -> np.ndarray:
        """Robustness of the points ``z (B, dim)`` (at most the budget left of them are rolled out);
        non-finite values as +-:data:`LARGE`. Raises :class:`_Done` when nothing is left to do."""
        if self.left <= 0 or (self.stop and self.first is not None):
            raise _Done
        z = np.clip(np.asarray(z, dtype=float)[: self.left, : self.dim], 0.0, 1.0)
        rob, sat = self.objective(z)
        rob = np.asarray(rob, dtype=float)
        sat = np.asarray(sat, dtype=bool)
        self.z.append(z)
        self.rob.append(rob)
        self.sat.append(sat)
        self.spent += z.shape[0]
        if self.first is None and not sat.all():
            self.first = self.spent
        return np.nan_to_num(rob, nan=LARGE, posinf=LARGE, neginf=-LARGE)

    def search(self, method: str) -> Search:
        z = np.concatenate(self.z) if self.z else np.zeros((0, self.dim))
        rob = np.concatenate(self.rob) if self.rob else np.zeros(0)
        sat = np.concatenate(self.sat) if self.sat else np.zeros(0, dtype=bool)
        return Search(method, z, rob, sat, self.first)


def _cma(ledger: _Ledger, rng: np.random.Generator, start: np.ndarray | None, popsize: int | None) -> None:
    from mitlc.cmaes import load

    try:
        cma = load()
    except ImportError:
        raise InputError("CMA-ES needs the cma package: pip install 'mitlc[verify]'", file="--method") from None
    # CMA-ES needs two coordinates or more: a one-dimensional cube gets a coordinate nobody reads
    n = max(2, ledger.dim)
    pop = popsize or 4 + int(3 * math.log(n))
    while True:
        if start is None:  # from the least robust of a uniform batch: CMA-ES stalls on a flat plateau
            scouts = rng.random((SCOUTS * pop, ledger.dim))
            start = scouts[int(np.argmin(ledger(scouts)))]
        x0 = np.r_[start, np.full(n - ledger.dim, 0.5)]
        opts = {
            "bounds": [0.0, 1.0],
            "popsize": pop,
            "seed": int(rng.integers(1, 2**31 - 1)),  # cma's seed 0 would be a random one
            "verbose": -9,
            "maxfevals": max(ledger.left, 1),
        }
        es = cma.CMAEvolutionStrategy(list(x0), 0.3, opts)
        while not es.stop():
            xs = es.ask()
            values = ledger(np.array(xs))  # raises _Done when the budget is spent or a counterexample found
            if values.shape[0] < len(xs):  # the budget ended inside the population
                raise _Done
            es.tell(xs, list(values))
        pop *= 2  # IPOP: a restart with twice the population, from the best of fresh scouts
        start = None


def _de(ledger: _Ledger, rng: np.random.Generator, start: np.ndarray | None, popsize: int | None) -> None:
    try:
        from scipy.optimize import differential_evolution
    except ImportError:
        raise InputError("differential evolution needs scipy: pip install 'mitlc[verify]'", file="--method") from None

    def f(zt: np.ndarray) -> np.ndarray:
        z = np.atleast_2d(zt.T)
        values = ledger(z)
        if values.shape[0] < z.shape[0]:
            raise _Done
        return values

    while True:  # scipy stops on its own tolerance: search again, from a fresh population
        differential_evolution(
            f,
            [(0.0, 1.0)] * ledger.dim,
            vectorized=True,
            updating="deferred",
            popsize=popsize or 15,
            maxiter=10**6,
            tol=0.0,
            polish=False,
            seed=int(rng.integers(2**31 - 1)),
            x0=start,
        )
        start = None


def _uniform(ledger: _Ledger, rng: np.random.Generator, start: np.ndarray | None, popsize: int | None) -> None:
    batch = popsize or 64
    if start is not None:
        ledger(start[None, :])
    while True:
        ledger(rng.random((min(batch, max(ledger.left, 1)), ledger.dim)))


def falsify(
    objective: Objective,
    dim: int,
    budget: int,
    method: str = "de",
    seed: int = 0,
    start: np.ndarray | None = None,
    stop: bool = True,
    popsize: int | None = None,
) -> Search:
    """Search ``[0, 1]^dim`` for points whose rollouts violate the spec, spending at most ``budget``
    rollouts; ``start``: a point to search from (e.g. the least robust sample); ``popsize``: the
    batch (CMA-ES's population, DE's population multiplier, uniform's batch). Deterministic
    given ``seed``."""
    if method not in METHODS:
        raise InputError(f"unknown method '{method}' (one of {', '.join(METHODS)})", file="--method")
    ledger = _Ledger(objective, dim, int(budget), stop)
    if budget > 0 and dim == 0:  # one scenario only: nothing to search, roll it out once
        ledger(np.zeros((1, 0)))
    elif budget > 0:
        rng = np.random.default_rng(seed)
        run = {"cma": _cma, "de": _de, "uniform": _uniform}[method]
        try:
            run(ledger, rng, None if start is None else np.clip(np.asarray(start, dtype=float), 0, 1), popsize)
        except _Done:
            pass
    return ledger.search(method)
