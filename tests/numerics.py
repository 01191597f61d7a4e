"""Whether this machine's numpy computes float64 sin, cos and exp as the C library does.

numba's compiled code calls the C library; numpy calls it too on x86-64 up to AVX2, but on
a machine with AVX-512 it uses its own SIMD code, which rounds some results differently in
the last place. The fused kernel and the numpy trial then agree within ``RTOL``, not to the
bit; ``same`` compares as tightly as this machine allows.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["LIBM", "RTOL", "same"]


def _numpy_is_libm() -> bool:
    """Whether this process's numpy gives the C library's float64 sin, cos and exp, bit for bit."""
    x = np.random.default_rng(0).uniform(-40.0, 40.0, 4096)
    pairs = ((np.sin, math.sin), (np.cos, math.cos), (np.exp, math.exp))
    return all(np.array_equal(f(x), np.array([g(v) for v in x])) for f, g in pairs)


LIBM = _numpy_is_libm()
RTOL = 1e-10  # AVX-512 numpy against the C library over 3 trials: 1.2e-13 at most (P4)


def same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal bits where numpy is the C library (``LIBM``); else equal within ``RTOL`` of ``a``'s size."""
    if LIBM:
        return bool(np.array_equal(a, b))
    return bool(np.allclose(a, b, rtol=0.0, atol=RTOL * max(float(np.abs(a).max()), 1.0)))
