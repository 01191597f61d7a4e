"""The exact (Clopper-Pearson) one-sided lower confidence bound of a binomial proportion.

``n`` rollouts drawn independently from a distribution, ``k`` of them satisfied: the lower
bound ``p_lo`` is the smallest satisfaction probability ``p`` under which seeing ``k`` or
more successes still has probability at least ``1 - confidence``:
``P(X >= k | n, p_lo) = 1 - confidence`` (``p_lo = 0`` when ``k = 0``). It is the
``1 - confidence`` quantile of ``Beta(k, n - k + 1)``; here found by bisection on the
binomial tail, summed exactly in log space (no scipy needed).

>>> round(clopper_pearson_lower(100, 100), 6)   # all satisfied: 0.05 ** (1 / 100)
0.970487
>>> clopper_pearson_lower(0, 10)
0.0
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["clopper_pearson_lower", "binomial_upper_tail"]


def _log_binomials(k: int, n: int) -> np.ndarray:
    """``log C(n, i)`` for ``i = k .. n``."""
    lg = np.array([math.lgamma(v + 1.0) for v in range(n + 1)])
    i = np.arange(k, n + 1)
    return lg[n] - lg[i] - lg[n - i]


def _tail(log_c: np.ndarray, k: int, n: int, p: float) -> float:
    i = np.arange(k, n + 1, dtype=float)
    log_pmf = log_c + i * math.log(p) + (n - i) * math.log1p(-p)
    top = float(log_pmf.max())
    return float(min(1.0, math.exp(top) * float(np.exp(log_pmf - top).sum())))


def binomial_upper_tail(k: int, n: int, p: float) -> float:
    """``P(X >= k)`` for ``X ~ Binomial(n, p)``, summed in log space (exact to rounding).

    >>> binomial_upper_tail(2, 2, 0.5)
    0.25
    """
    if k <= 0 or p >= 1.0:
        return 1.0
    if k > n or p <= 0.0:
        return 0.0
    return _tail(_log_binomials(k, n), k, n, p)


def clopper_pearson_lower(k: int, n: int, confidence: float = 0.95) -> float:
    """The exact one-sided lower ``confidence`` bound on the success probability after ``k``
    successes in ``n`` independent trials (``0 <= k <= n``, ``n >= 1``)."""
    if not (isinstance(n, int | np.integer) and n >= 1 and 0 <= k <= n):
        raise ValueError(f"need 0 <= k <= n and n >= 1, got k={k}, n={n}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    alpha = 1.0 - confidence
    if k == 0:
        return 0.0
    if k == n:  # the tail is p ** n: closed form
        return float(alpha ** (1.0 / n))
    k, n = int(k), int(n)
    log_c = _log_binomials(k, n)
    lo, hi = 0.0, 1.0  # tail(lo) < alpha <= tail(hi); the tail rises with p
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if _tail(log_c, k, n, mid) < alpha:
            lo = mid
        else:
            hi = mid
    return hi
