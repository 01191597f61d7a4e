"""The rewards the field uses instead of a compiled one, generated from the same spec.

``option reward = sparse | robustness | robustness-window`` (``--reward`` on ``train``) pays the
learner from the monitor instead of the net's ``r(M_k, M_k+1)``; the net still runs beside the
plant (SACPN's actor and critic are indexed by its marking), only what it pays changes:

* ``sparse``: 1 on the last step of a trial whose whole trace satisfies the spec's monitor
  formula, 0 on every other step (the thesis's (2-19));
* ``robustness``: the monitor's robustness of the whole trace on the last step, 0 before (a
  terminal robustness reward, as TLTL uses);
* ``robustness-window``: on every step ``k``, the robustness at its start of the formula over
  the last ``W`` samples ``x_{k-W+1} .. x_k`` (fewer at the start), as stl-gym and RLRom pay
  per step. ``W`` covers the formula's own horizon (the furthest any operator looks ahead)
  when that is finite, else :data:`WINDOW_S` seconds.

:class:`TraceReward` keeps the trace of ``R`` runs and is stepped one sample at a time, so a
trainer (or the Gymnasium wrapper) asks it for the reward of the sample it has just entered.

>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec("plant pendulum\\nprop up = abs(q) < 0.3\\nformula F[0,0.1] up")
>>> tr = TraceReward(spec, "robustness-window", dt=0.05, columns=("q", "qdot"))
>>> tr.window
3
>>> tr.reset(np.array([[1.0, 0.0]]))
>>> [round(float(tr.step(np.array([[q, 0.0]]), last=False)[0]), 3) for q in (0.5, 0.1, 0.2)]
[-0.2, 0.2, 0.2]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from mitlc.errors import InputError
from mitlc.monitor.offline import judged_formula, sample_time, verdict
from mitlc.spec import ast as A
from mitlc.spec.model import MONITOR_REWARDS, Spec

__all__ = ["DESIGNS", "WINDOW_S", "TraceReward", "formula_horizon", "pay"]

DESIGNS = MONITOR_REWARDS
"""The reward designs paid from the monitor (the values of ``option reward`` that are not the net's)."""

WINDOW_S = 1.0
"""``robustness-window``'s window in seconds for a formula with an unbounded operator."""


def formula_horizon(f: A.Formula) -> float:
    """How far past a time point ``f``'s value there reads, in seconds (inf with an unbounded operator).

    >>> from mitlc.spec.parse import parse_formula
    >>> formula_horizon(parse_formula("G[0,1] (a -> F[0,0.5] b)")), formula_horizon(parse_formula("F G a"))
    (1.5, inf)
    """
    if isinstance(f, (A.Atom, A.Const)):
        return 0.0
    kids = [formula_horizon(c) for c in f.children]
    inner = max(kids) if kids else 0.0
    interval = getattr(f, "interval", None)
    return inner + (interval.hi if interval is not None else 0.0)


def pay(agent: Any) -> Any:
    """Give a SACPN learner (:class:`mitlc.learn.sacpn.Sacpn`) whose spec's reward is the monitor's its
    :class:`TraceReward` (over its plant's state, at its sample time); returns the agent."""
    if agent.rs.paid_by_monitor:
        agent.trace_reward = TraceReward(
            agent.spec, agent.rs.options.reward, agent.dt, agent.plant.state_names, agent.runs
        )
    return agent


class TraceReward:
    """One of :data:`DESIGNS` for ``R`` runs: :meth:`reset` with the first samples, then
    :meth:`step` with each new one; ``columns`` names the state arrays' columns."""

    def __init__(self, spec: Spec, design: str, dt: float, columns: Sequence[str], runs: int = 1) -> None:
        if design not in DESIGNS:
            raise InputError(f"reward {design!r} is not paid by the monitor (one of {', '.join(DESIGNS)})")
        self.spec, self.design, self.dt = spec, design, sample_time(dt)
        self.columns, self.runs = tuple(columns), int(runs)
        self.formula = judged_formula(spec, None)
        h = formula_horizon(self.formula)
        seconds = h if math.isfinite(h) else WINDOW_S
        self.window = max(1, int(math.floor(seconds / self.dt + 1e-9)) + 1)
        """``robustness-window``: samples in a window (its first sample and the formula's horizon after it)."""
        self._trace = np.zeros((self.runs, 16, len(self.columns)))
        self._k = -1
        from mitlc.spec.grades import Grader  # the propositions' largest margins over the state box

        scales = [s for row in Grader.of(spec, sorted(A.atoms(self.formula))).scales for s in row]
        self.bound = max(scales, default=1.0)
        """What an infinite robustness is paid as (``-inf``: no witness in the window or trace, as an
        ``F[1,2]`` over a window of 1 s; ``+inf``: a vacuous ``G``): the largest margin in size that any
        proposition has over the state box, so every payment is finite."""

    def reset(self, x0: np.ndarray) -> None:
        """Start every run's trace at ``x0`` ``(R, n)``."""
        x0 = np.asarray(x0, dtype=float)
        if x0.ndim != 2 or x0.shape[1] != len(self.columns):
            raise InputError(f"states must be (runs, {len(self.columns)}), got {x0.shape}")
        if x0.shape[0] != self._trace.shape[0]:
            self.runs = x0.shape[0]
            self._trace = np.zeros((self.runs, 16, len(self.columns)))
        self._trace[:, 0] = x0
        self._k = 0

    def _states(self, a: int, b: int) -> dict[str, np.ndarray]:
        return {c: self._trace[:, a : b + 1, i] for i, c in enumerate(self.columns)}

    def step(self, x: np.ndarray, last: bool) -> np.ndarray:
        """The reward ``(R,)`` of entering ``x`` ``(R, n)``; ``last``: the trial ends with this sample."""
        if self._k < 0:
            raise InputError("TraceReward.step before reset")
        k = self._k = self._k + 1
        if k >= self._trace.shape[1]:
            grown = np.zeros((self.runs, 2 * self._trace.shape[1], len(self.columns)))
            grown[:, :k] = self._trace[:, :k]
            self._trace = grown
        self._trace[:, k] = x
        if self.design == "robustness-window":
            return self._judged(max(0, k + 1 - self.window), k)[1]
        if not last:
            return np.zeros(self.runs)
        satisfied, rob = self._judged(0, k)
        return np.where(np.isnan(rob), np.nan, satisfied) if self.design == "sparse" else rob

    def _judged(self, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        """Verdict and robustness of samples ``a .. b``; nan for a run whose states there are not
        finite (a diverging learner: its trainer stops that run, the monitor would refuse it)."""
        ok = np.isfinite(self._trace[:, a : b + 1]).all(axis=(1, 2))
        satisfied, rob = np.zeros(self.runs), np.full(self.runs, np.nan)
        if ok.any():
            rows = {c: v[ok] for c, v in self._states(a, b).items()}
            s, r = verdict(self.spec, rows, self.dt, self.formula)
            satisfied[ok], rob[ok] = s, np.clip(r, -self.bound, self.bound)
        return satisfied, rob
