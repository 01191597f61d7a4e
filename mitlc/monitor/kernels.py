"""The monitor's array kernels: the two lattices, sample offsets of an interval, and
sliding-window and until operators over a leading run axis.

Each kernel works on ``(R, L)`` arrays, run by run in one numpy pass, the same code
for verdicts (:data:`BOOL`) and robustness (:data:`REAL`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.spec.ast import TIME_TOL, offsets

__all__ = ["Lattice", "BOOL", "REAL", "TIME_TOL", "offsets", "shift", "window", "until", "until_unbounded"]

# ----------------------------------------------------------------- lattices


@dataclass(frozen=True)
class Lattice:
    """Booleans or reals with their join, meet, bottom and top."""

    name: str
    join: np.ufunc
    meet: np.ufunc
    bottom: Any
    top: Any
    dtype: type

    def neg(self, x: np.ndarray) -> np.ndarray:
        return ~x if self.dtype is bool else -x

    def full(self, shape: tuple[int, ...], value: Any) -> np.ndarray:
        return np.full(shape, value, dtype=self.dtype)


BOOL = Lattice("bool", np.logical_or, np.logical_and, False, True, bool)
REAL = Lattice("real", np.maximum, np.minimum, -np.inf, np.inf, float)


# ----------------------------------------------------------------- intervals


# ----------------------------------------------------------------- kernels


def shift(x: np.ndarray, j: int, fill: Any) -> np.ndarray:
    """``y[:, k] = x[:, k + j]``, ``fill`` past the end."""
    if j == 0:
        return x
    R, L = x.shape
    out = np.full((R, L), fill, dtype=x.dtype)
    if j < L:
        out[:, : L - j] = x[:, j:]
    return out


def window(x: np.ndarray, lo: int, hi: float, op: np.ufunc, ident: Any) -> np.ndarray:
    """``y[:, k] = op(x[:, k+lo .. min(k+hi, N)])``, ``ident`` where the window is empty.

    By doubling (a sparse table): the ``op`` of every ``p`` consecutive samples for ``p = 1, 2, 4, ...``
    up to the largest power of two ``p <= w``, each one vectorised ``op`` over all runs and samples
    from the last; then two such windows, overlapping, cover each window of ``w`` samples. ``op`` is
    idempotent (max, min, or, and), so the overlap changes no value: ``log2(w) + 1`` whole-array
    operations, where scanning blocks (van Herk/Gil-Werman) took ``op.accumulate``, whose inner loop
    takes one element at a time (a policy search's 512 rollouts of 181 samples and a window of 81
    samples: 7 operations).

    >>> x = np.array([[3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0]])
    >>> window(x, 1, 3, np.maximum, -np.inf)
    array([[  4.,   5.,   9.,   9.,   9.,   2., -inf]])
    """
    R, L = x.shape
    out = np.full((R, L), ident, dtype=x.dtype)
    if lo > L - 1 or hi < lo:
        return out
    hi_i = int(min(hi, L - 1))
    w = hi_i - lo + 1
    z = x[:, lo:]
    n = z.shape[1]
    if w >= n:  # every window reaches the end of the trace: a suffix scan
        out[:, :n] = op.accumulate(z[:, ::-1], axis=1)[:, ::-1]
        return out
    if w == 1:
        out[:, :n] = z
        return out
    # doubling: y[k] = op(z[k .. k + p - 1]) for p = 1, 2, 4, .. up to the largest power of two <= w, then
    # two overlapping windows of p samples cover each window of w (the trace padded with the identity)
    # (two buffers in turn)
    y = np.full((R, n + w), ident, dtype=x.dtype)
    y[:, :n] = z
    spare = np.empty_like(y)
    p, m = 1, n + w
    while 2 * p <= w:
        m -= p
        op(y[:, :m], y[:, p : p + m], out=spare[:, :m])
        y, spare = spare, y
        p *= 2
    op(y[:, :n], y[:, w - p : w - p + n], out=out[:, :n])
    return out


_SMALL = 64


def until_unbounded(phi: np.ndarray, psi: np.ndarray, lat: Lattice) -> np.ndarray:
    """``U[k] = join_j meet(psi[k+j], meet(phi[k .. k+j-1]))``: untimed strong until.

    It is the backward recurrence ``U[k] = join(psi[k], meet(phi[k], U[k+1]))``,
    ``U[N+1] = bottom``. The trace is cut into about sqrt(L) blocks; the
    recurrence runs inside all blocks at once, then across the block starts
    (the same problem, solved recursively), then one fix-up pass. Linear work.

    >>> phi = np.array([[True, True, False, True, True]])
    >>> psi = np.array([[False, False, True, False, False]])
    >>> until_unbounded(phi, psi, BOOL)
    array([[ True,  True,  True, False, False]])
    """
    R, L = phi.shape
    if L <= _SMALL:
        out: np.ndarray = np.empty((R, L), dtype=lat.dtype)
        cur = lat.full((R,), lat.bottom)
        for k in range(L - 1, -1, -1):
            cur = lat.join(psi[:, k], lat.meet(phi[:, k], cur))
            out[:, k] = cur
        return out
    B = math.isqrt(L - 1) + 1
    nb = -(-L // B)
    pad = nb * B - L
    if pad:
        phi = np.concatenate([phi, lat.full((R, pad), lat.top)], axis=1)
        psi = np.concatenate([psi, lat.full((R, pad), lat.bottom)], axis=1)
    # layout (B, R, nb): offset inside the block first, so each step is contiguous
    ph = np.ascontiguousarray(phi.reshape(R, nb, B).transpose(2, 0, 1))
    ps = np.ascontiguousarray(psi.reshape(R, nb, B).transpose(2, 0, 1))
    inner = np.empty_like(ps)
    cur = lat.full((R, nb), lat.bottom)
    for i in range(B - 1, -1, -1):
        cur = lat.join(ps[i], lat.meet(ph[i], cur))
        inner[i] = cur
    phi_suffix = lat.meet.accumulate(ph[::-1], axis=0)[::-1]
    # U at the start of each block, then at the start of the next block
    starts = until_unbounded(phi_suffix[0], inner[0], lat)
    after = shift(starts, 1, lat.bottom)
    U = lat.join(inner, lat.meet(phi_suffix, after[None, :, :]))
    return U.transpose(1, 2, 0).reshape(R, nb * B)[:, :L]


def until(phi: np.ndarray, psi: np.ndarray, lo: int, hi: float, lat: Lattice) -> np.ndarray:
    """Strong ``phi U_[lo,hi] psi`` in sample offsets.

    ``U_[lo,hi](k) = meet(G_[0,lo-1] phi (k), (F_[0,hi-lo] psi & phi U psi)(k + lo))``;
    the second part holds because ``phi U_[0,c] psi = F_[0,c] psi & phi U psi``
    on discrete time (the first witness of ``psi`` inside the window is one).
    """
    R, L = phi.shape
    if hi < lo or lo > L - 1:
        return lat.full((R, L), lat.bottom)
    core = until_unbounded(phi, psi, lat)
    if hi - lo < L - 1:
        core = lat.meet(core, window(psi, 0, hi - lo, lat.join, lat.bottom))
    out = shift(core, lo, lat.bottom)
    if lo > 0:
        out = lat.meet(out, window(phi, 0, lo - 1, lat.meet, lat.top))
    return out
