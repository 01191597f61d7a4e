"""Classical step-response criteria measured on trajectories (thesis section 2-2-2).

The four measures of Figure 2-3, for a step from ``q0 = q[0]`` to the set-point
``s``, on samples ``q[k]`` at ``t = k dt``, vectorised over a leading run axis:

* **overshoot** ``M_p``: how far the position goes past the set-point, as a
  fraction of the step: ``max(0, max_k (q_k - s) / (s - q0))`` (so ``q_peak =
  s + M_p (s - q0)``, (3-1));
* **rise time** ``t_r``: from the first time 10% of the step is done to the
  first time 90% is done, each crossing interpolated linearly between samples;
  ``inf`` when 90% is never reached;
* **settling time** ``t_s``: the time after which ``|q - s|`` stays within
  ``band * |s - q0|`` until the end (the last exit from the band, interpolated);
  0 if the band is never left, ``inf`` if the trajectory ends outside it;
* **steady-state error** ``e_ss``: ``|q_N - s|`` at the end of the trajectory
  (absolute, in the units of ``q``).

A zero step (``q0 == s``) has no overshoot and zero rise time.

>>> import numpy as np
>>> q = np.array([-1.0, -0.8, -0.4, 0.0, 0.1, 0.02, 0.0, 0.0])   # one run, dt = 0.1
>>> m = measure(q, 0.1, setpoint=0.0)
>>> [round(float(v[0]), 12) for v in (m.overshoot, m.rise_time, m.settling_time, m.steady_state_error)]
[0.1, 0.225, 0.5, 0.0]
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from mitlc.errors import InputError
from mitlc.spec.model import CRITERIA, Requirement, Spec

__all__ = ["Measured", "Verdict", "measure", "check", "TOLERANCE", "DEFAULT_SETTLING_BAND"]

DEFAULT_SETTLING_BAND = 0.02
"""Settling band (fraction of the step) when a requirement gives none (the common 2%)."""

TOLERANCE = 1e-9
"""Bounds are compared with this slack to absorb floating-point rounding."""


@dataclass
class Measured:
    """Measured criteria, one entry per run (arrays of shape ``(R,)``)."""

    overshoot: np.ndarray
    rise_time: np.ndarray
    settling_time: np.ndarray
    steady_state_error: np.ndarray
    band: float

    def get(self, name: str) -> np.ndarray:
        if name not in CRITERIA:
            raise InputError(f"unknown criterion '{name}' (known: {', '.join(CRITERIA)})")
        return getattr(self, name)


@dataclass
class Verdict:
    """Pass/fail per requirement (``passed[name]`` of shape ``(R,)``) and the measures."""

    measured: dict[str, np.ndarray]
    passed: dict[str, np.ndarray]
    requirements: tuple[Requirement, ...]

    @property
    def all(self) -> np.ndarray:
        """Runs that meet every requirement."""
        out = np.ones(len(next(iter(self.measured.values()))), dtype=bool)
        for p in self.passed.values():
            out &= p
        return out

    def rates(self) -> dict[str, float]:
        """Fraction of runs passing each requirement, and ``all``."""
        out = {name: float(p.mean()) for name, p in self.passed.items()}
        out["all"] = float(self.all.mean())
        return out


def _as_runs(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    if q.ndim == 1:
        q = q[None]
    if q.ndim != 2 or q.shape[1] < 2:
        raise InputError(f"trajectories must have shape (runs, samples) with at least 2 samples, got {q.shape}")
    if not np.isfinite(q).all():
        raise InputError("trajectories contain NaN or inf")
    return q


def _progress(q: np.ndarray, setpoint: float) -> np.ndarray:
    """Fraction of the step done: 0 at ``q0``, 1 at the set-point (1 everywhere for a zero step)."""
    step = setpoint - q[:, :1]
    zero = np.abs(step) < 1e-12
    safe = np.where(zero, 1.0, step)
    return np.where(zero, 1.0, (q - q[:, :1]) / safe)


def _first_crossing(p: np.ndarray, level: float, dt: float) -> np.ndarray:
    """Interpolated first time ``p >= level`` (``inf`` if never)."""
    reached = p >= level
    hit = reached.any(axis=1)
    k = reached.argmax(axis=1)
    rows = np.arange(p.shape[0])
    prev = np.maximum(k - 1, 0)
    p0, p1 = p[rows, prev], p[rows, k]
    frac = np.where(k > 0, (level - p0) / np.where(p1 > p0, p1 - p0, 1.0), 0.0)
    t = np.where(k > 0, (prev + frac) * dt, 0.0)
    return np.where(hit, t, np.inf)


def measure(q: np.ndarray, dt: float, setpoint: float = 0.0, band: float = DEFAULT_SETTLING_BAND) -> Measured:
    """Measure the four criteria on trajectories ``q (R, N+1)`` (or ``(N+1,)``) sampled every ``dt``."""
    if not dt > 0:
        raise InputError(f"sample time must be positive, got {dt}")
    if not 0 < band < 1:
        raise InputError(f"settling band must be a fraction in (0, 1), got {band}")
    q = _as_runs(q)
    s = float(setpoint)
    p = _progress(q, s)
    overshoot = np.maximum(0.0, p.max(axis=1) - 1.0)
    t10, t90 = _first_crossing(p, 0.1, dt), _first_crossing(p, 0.9, dt)
    rise = np.where(np.isfinite(t90), t90 - np.where(np.isfinite(t10), t10, 0.0), np.inf)

    err = np.abs(q - s)
    width = band * np.abs(s - q[:, 0])
    outside = err > width[:, None]
    N = q.shape[1] - 1
    ever = outside.any(axis=1)
    last = N - outside[:, ::-1].argmax(axis=1)
    rows = np.arange(q.shape[0])
    nxt = np.minimum(last + 1, N)
    e0, e1 = err[rows, last], err[rows, nxt]
    frac = np.where(e0 > e1, (e0 - width) / np.where(e0 > e1, e0 - e1, 1.0), 0.0)
    settling = np.where(last == N, np.inf, (last + frac) * dt)
    settling = np.where(ever, settling, 0.0)
    return Measured(overshoot, rise, settling, err[:, -1], band)


def check(
    requirements: Spec | Iterable[Requirement],
    q: np.ndarray,
    dt: float,
    setpoint: float | None = None,
) -> Verdict:
    """Pass/fail of each requirement on trajectories ``q (R, N+1)``.

    ``requirements`` is a :class:`~mitlc.spec.model.Spec` (its ``setpoint`` is used) or
    requirements with an explicit ``setpoint``.  A requirement passes when
    ``lo <= measured <= hi`` (with :data:`TOLERANCE`).

    >>> from mitlc.spec.model import Requirement
    >>> ramp = np.linspace(-1.0, 0.0, 11)            # 1 m in 1 s, sampled every 0.1 s
    >>> v = check([Requirement("overshoot", 0, 0), Requirement("rise_time", 0.6, 0.8)], ramp, 0.1)
    >>> {k: bool(p[0]) for k, p in v.passed.items()}, round(float(v.measured["rise_time"][0]), 12)
    ({'overshoot': True, 'rise_time': True}, 0.8)
    """
    if isinstance(requirements, Spec):
        reqs = tuple(requirements.requirements)
        s = requirements.setpoint if setpoint is None else setpoint
    else:
        reqs = tuple(requirements)
        s = 0.0 if setpoint is None else setpoint
    if not reqs:
        raise InputError("no requirements to check")
    measured: dict[str, np.ndarray] = {}
    passed: dict[str, np.ndarray] = {}
    for r in reqs:
        band = r.band if r.band is not None else DEFAULT_SETTLING_BAND
        value = measure(q, dt, s, band).get(r.name)
        measured[r.name] = value
        passed[r.name] = (value >= r.lo - TOLERANCE) & (value <= r.hi + TOLERANCE)
    return Verdict(measured, passed, reqs)
