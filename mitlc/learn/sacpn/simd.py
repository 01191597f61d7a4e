"""SACPN's fast trial kernel (``kernel = simd``): the exact kernel with its feature loops vectorised.

The exact kernel (:mod:`mitlc.learn.sacpn.kernel`) keeps numpy's pairwise order in every sum and
calls the C library's ``exp``, ``cos`` and ``sin``: scalar code, about 2 us per run-step on P1,
most of it in the dot products over the features (each a product loop, then a pairwise sum) and
in the RBF features (thirty ``exp`` and ``cos`` calls per sample). This kernel is the same loop,
:func:`mitlc.learn.sacpn.kernel.trial_kernel` itself (runs outer, steps inner, features innermost,
one run's arrays in the first-level cache), given other parts (:func:`simd_parts`, its
:class:`~mitlc.learn.sacpn.kernel.Parts`: the features and the sums over the marked rows), with
three changes:

* **the sums are reassociated**: the dot products ``w . phi``, their sum over the marked rows and
  the features' normalising sums are plain loops compiled with fastmath's ``reassoc`` (and ``nsz``) flags only,
  so the compiler sums them in vector registers, blocks of features in parallel partial sums,
  instead of numpy's pairwise order (:func:`sum_for`);
* **exp and cos are this module's own** (:func:`exp_vec_for`, :func:`cos_vec_for`: range
  reduction and Taylor polynomials in plain IEEE arithmetic, within 1 ulp of the C library's,
  tested), called once per sample on all the kernels' arguments at once, since the C library's
  are scalar calls that no loop vectorises;
* the features' outer product is written forward into a second buffer (the exact kernel's is in
  place from the end): the same products.

The leaf functions (the features, the dots, the sums, exp and cos: none allocates) are compiled
without numba's reference counting (:data:`LEAF`), which otherwise costs two atomic operations per
array argument per call, more than a short loop's work. Everything else is the exact kernel's code,
the same order: the plant's step
(:attr:`~mitlc.plants.base.Plant.kernel_step`, the C library's ``sin``), the predicates
(:func:`~mitlc.runtime.atoms.compile_atoms`), the tables, the timed obligations' engine
(:mod:`mitlc.runtime.obligation_kernel`) and the updates (plain loops, IEEE, no fused
multiply-adds: only the sums above carry a fastmath flag).

With ``exact_parts=True`` (for the tests) the sums are numpy's pairwise ones and exp and cos the
C library's: the kernel then gives the exact kernel's numbers to the bit, which tests everything
but those two changes. Without it (the fast path) a run's numbers differ from the exact kernel's
in the last places of each sum, exp and cos, and like any such difference these grow as a training
goes on: ``tests/test_simd.py`` bounds them against the numpy reference over whole trainings. A
seed gives the same numbers every time on one machine, and a run's numbers do not depend on ``R``
(each run goes through the same code); another machine's vector width may group the partial sums
differently.

Scope: that of the exact kernel (:func:`unsupported` gives its reasons).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from fractions import Fraction
from typing import Any

import numpy as np

from mitlc.learn.sacpn import kernel as fk
from mitlc.plants.base import pairwise_sum_for

__all__ = [
    "REASSOC",
    "LEAF",
    "SUMS",
    "compile_leaf",
    "exp_vec_for",
    "cos_vec_for",
    "sum_for",
    "simd_parts",
    "simd_trial_kernel",
    "unsupported",
]

REASSOC = frozenset({"reassoc", "nsz"})
"""The fastmath flags of the fast path's sums (and only of them): reassociation (and the sign of a
zero sum), which lets a loop's sum go in vector registers. No ``contract`` (fused multiply-adds),
no approximate functions, no assumption that numbers are finite."""

LEAF = {"_nrt": False}
"""numba options of the fast path's leaf functions, which allocate nothing: no reference counting
(numba's compiled functions count a reference to each array argument on entry and on exit, two
atomic operations per array per call: more than the work of a short loop)."""

SUMS = {"fastmath": REASSOC, "_nrt": False}
"""numba options of the fast path's sums: :data:`LEAF`'s, and :data:`REASSOC`."""


def compile_leaf(jit_fn: Callable, fn: Callable, options: dict) -> Callable:
    """``fn`` compiled by ``jit_fn`` with ``options`` (:data:`LEAF`, :data:`SUMS`) on top of
    :func:`mitlc.learn.sacpn.kernel.jit`'s where ``jit_fn`` is that, and marked with them for
    :mod:`mitlc.learn.jitcache` (``__mitlc_jit__``), which compiles the plain function graph."""
    setattr(fn, "__mitlc_jit__", options)  # noqa: B010 (an attribute functions do not declare)
    if jit_fn is not fk.jit:
        return jit_fn(fn)
    import numba

    kw: dict[str, Any] = {"fastmath": False, "error_model": "numpy", "nogil": True}
    kw.update({k: set(v) if k == "fastmath" else v for k, v in options.items()})
    return numba.njit(**kw)(fn)


# ---------------------------------------------------------------- exp and cos, vectorisable

_LOG2E = 1.4426950408889634
_LN2 = Fraction(
    "0.693147180559945309417232121458176568075500134360255254120680009493393621969694715605863326996418687542"
)
_PI = Fraction(
    "3.14159265358979323846264338327950288419716939937510582097494459230781640628620899862803482534211706798"
)


def _split(x: Fraction, bits: int) -> float:
    """``x`` rounded to ``bits`` significant bits (a multiple of it by a small integer is then exact)."""
    e = math.floor(math.log2(x))
    scale = Fraction(2) ** (bits - 1 - e)
    return float(Fraction(round(x * scale)) / scale)


_LN2_HI = _split(_LN2, 32)
_LN2_LO = float(_LN2 - Fraction(_LN2_HI))
_PIO2_1 = _split(_PI / 2, 33)
_PIO2_2 = _split(_PI / 2 - Fraction(_PIO2_1), 33)
_PIO2_3 = float(_PI / 2 - Fraction(_PIO2_1) - Fraction(_PIO2_2))
_TWO_OVER_PI = float(2 / _PI)
_MAGIC = 6755399441055744.0  # 1.5 * 2^52: kf + _MAGIC holds the integer kf in its low bits
_MAGIC_BITS = 0x4338000000000000
_E = [1.0 / math.factorial(i) for i in range(14)]  # exp's Taylor coefficients to y^13
_S = [(-1.0) ** i / math.factorial(2 * i + 1) for i in range(8)]  # sin's, to y^15
_C = [(-1.0) ** i / math.factorial(2 * i) for i in range(9)]  # cos's, to y^16


def exp_vec_for(jit_fn: Callable) -> Callable:
    """``exp_vec(a, lo, n, s1, s2, b1, b2)``: ``a[lo : lo + n] = exp(a[lo : lo + n])`` in place;
    ``s1``, ``s2`` float64 scratch of at least ``n`` and ``b1``, ``b2`` their int64 views; compiled
    by ``jit_fn``.

    ``exp(t) = 2^k exp(y)``, ``k = round(t / ln 2)``, ``y = t - k ln 2`` (ln 2 in two parts, the first
    with 32 bits, so ``k ln2_hi`` is exact), ``exp(y)`` by its Taylor polynomial to ``y^13`` (its
    remainder under ``1e-17`` for ``|y| <= ln 2 / 2``), and ``2^k`` as two powers of two built in
    their bits (so that results below ``2^-1022`` round as they should, down to 0). Within 1 ulp of
    the C library's (tested); ``t`` is clamped to ``[-760, 710]``, past which exp is 0 or inf anyway."""
    e0, e1, e2, e3, e4, e5, e6, e7, e8, e9, e10, e11, e12, e13 = _E
    ln2_hi, ln2_lo, log2e, magic, magic_bits = _LN2_HI, _LN2_LO, _LOG2E, _MAGIC, _MAGIC_BITS

    def exp_vec(a, lo, n, s1, s2, b1, b2):
        for q in range(n):
            r = lo + q
            t = np.minimum(np.maximum(a[r], -760.0), 710.0)
            kf = np.floor(t * log2e + 0.5)
            kf = 0.0 if kf != kf else kf  # NaN: NaN from the polynomial, any finite k
            y = (t - kf * ln2_hi) - kf * ln2_lo
            p = e13
            p = p * y + e12
            p = p * y + e11
            p = p * y + e10
            p = p * y + e9
            p = p * y + e8
            p = p * y + e7
            p = p * y + e6
            p = p * y + e5
            p = p * y + e4
            p = p * y + e3
            p = p * y + e2
            p = p * y + e1
            p = p * y + e0
            a[r] = p
            k1 = np.floor(kf * 0.5)
            s1[q] = k1 + magic
            s2[q] = (kf - k1) + magic
        for q in range(n):  # 2^k1, 2^k2 (each in [-548, 512])
            b1[q] = (b1[q] - magic_bits + 1023) << 52
            b2[q] = (b2[q] - magic_bits + 1023) << 52
        for q in range(n):
            a[lo + q] = (a[lo + q] * s1[q]) * s2[q]

    return compile_leaf(jit_fn, exp_vec, LEAF)


def cos_vec_for(jit_fn: Callable) -> Callable:
    """``cos_vec(a, lo, n)``: ``a[lo : lo + n] = cos(a[lo : lo + n])`` in place; compiled by ``jit_fn``.

    ``x = y + j pi/2`` (pi/2 in three parts, the first two with 33 bits: exact products for
    ``|j| < 2^20``), then ``cos`` or ``sin`` of ``y`` (``|y| <= pi/4``) by Taylor polynomials to
    ``y^16`` and ``y^15``, chosen and signed by ``j mod 4`` without a branch. Within 1 ulp of the
    C library's near the features' angles (tested on ``[-100, 100]``)."""
    s1, s2, s3, s4, s5, s6, s7 = _S[1:]
    c2, c3, c4, c5, c6, c7, c8 = _C[2:]
    p1, p2, p3, two_over_pi = _PIO2_1, _PIO2_2, _PIO2_3, _TWO_OVER_PI

    def cos_vec(a, lo, n):
        for q in range(n):
            r = lo + q
            x = a[r]
            j = np.floor(x * two_over_pi + 0.5)
            y = ((x - j * p1) - j * p2) - j * p3
            quad = j - 4.0 * np.floor(j * 0.25)
            z = y * y
            sp = s7
            sp = sp * z + s6
            sp = sp * z + s5
            sp = sp * z + s4
            sp = sp * z + s3
            sp = sp * z + s2
            sp = sp * z + s1
            sn = y + y * z * sp
            cp = c8
            cp = cp * z + c7
            cp = cp * z + c6
            cp = cp * z + c5
            cp = cp * z + c4
            cp = cp * z + c3
            cp = cp * z + c2
            cs = 1.0 - (0.5 * z - z * z * cp)
            v = sn if (quad == 1.0 or quad == 3.0) else cs
            a[r] = -v if (quad == 1.0 or quad == 2.0) else v

    return compile_leaf(jit_fn, cos_vec, LEAF)


# ---------------------------------------------------------------- sums over features


def sum_for(jit_fn: Callable, exact: bool) -> tuple[Callable, Callable, Callable]:
    """``(dot, dot_in, total)``: ``dot(w, row, phi, F, prod)`` is ``sum_f w[row, f] phi[f]``,
    ``dot_in(w, row, i, phi, F, prod)`` is ``sum_f w[row, i, f] phi[f]`` and
    ``total(a, lo, n)`` is ``sum_j a[lo + j]``, ``j < n``. ``exact``: in numpy's pairwise
    order, the products rounded first (the exact kernel's sums, ``prod`` their scratch); else
    plain loops whose sums the compiler may
    reassociate (:data:`SUMS`, :func:`compile_leaf`)."""
    if exact:
        psum = pairwise_sum_for(jit_fn)

        def dot_exact(w, row, phi, F, prod):
            for f in range(F):
                prod[f] = w[row, f] * phi[f]
            return psum(prod, 0, F)

        def dot_in_exact(w, row, i, phi, F, prod):
            for f in range(F):
                prod[f] = w[row, i, f] * phi[f]
            return psum(prod, 0, F)

        def total_exact(a, lo, n):
            return psum(a, lo, n)

        return jit_fn(dot_exact), jit_fn(dot_in_exact), jit_fn(total_exact)

    def dot(w, row, phi, F, prod):
        s = 0.0
        for f in range(F):
            s += w[row, f] * phi[f]
        return s

    def dot_in(w, row, i, phi, F, prod):
        s = 0.0
        for f in range(F):
            s += w[row, i, f] * phi[f]
        return s

    def total(a, lo, n):
        s = 0.0
        for j in range(lo, lo + n):
            s += a[j]
        return s

    return compile_leaf(jit_fn, dot, SUMS), compile_leaf(jit_fn, dot_in, SUMS), compile_leaf(jit_fn, total, SUMS)


# ---------------------------------------------------------------- the trial


def simd_parts(jit_fn: Callable, exact_parts: bool = False) -> fk.Parts:
    """The fast kernel's parts (:class:`mitlc.learn.sacpn.kernel.Parts`), compiled by ``jit_fn``: the
    features with one exp over all the axes' kernels and the outer product written forward, and the
    sums over the marked rows; ``exact_parts``: with numpy's pairwise sums and the C library's exp and
    cos (then the exact kernel's numbers to the bit), else the fast path's (:func:`sum_for`,
    :func:`exp_vec_for`, :func:`cos_vec_for`)."""
    dot1, dot1_in, total = sum_for(jit_fn, exact_parts)
    if exact_parts:

        def exp_libm(a, lo, n, s1, s2, b1, b2):
            for r in range(lo, lo + n):
                a[r] = np.exp(a[r])

        def cos_libm(a, lo, n):
            for r in range(lo, lo + n):
                a[r] = np.cos(a[r])

        exp_v, cos_v = jit_fn(exp_libm), jit_fn(cos_libm)
    else:
        exp_v, cos_v = exp_vec_for(jit_fn), cos_vec_for(jit_fn)

    def scratch(centres, F):
        # the kernels' arguments (all axes, packed), exp's scratch and its int64 views, the outer product's
        n = centres.shape[0] * centres.shape[1]
        s1, s2 = np.empty(n), np.empty(n)
        return np.empty(n), s1, s2, s1.view(np.int64), s2.view(np.int64), np.empty(F)

    def rbf(x, counts, periodic, lo, hi, k, centres, work, phi):
        # every axis's kernel arguments into arg, one exp over them all, then per axis the
        # normalisation and the outer product (the exact kernel's operations per entry)
        arg, s1, s2, b1, b2, tmp = work
        off = 0
        for i in range(counts.shape[0]):
            n = counts[i]
            if n == 1:
                continue
            z = x[i]
            if periodic[i]:  # exp(2k cos(z - c) - 2k)
                for j in range(n):
                    arg[off + j] = z - centres[i, j]
                cos_v(arg, off, n)
                k2 = 2.0 * k[i]
                for j in range(off, off + n):
                    arg[j] = arg[j] * k2 - k2
            else:  # exp(-k (z - c)^2), z clipped
                zi = np.minimum(np.maximum(z, lo[i]), hi[i])
                mk = -k[i]
                for j in range(n):
                    d = zi - centres[i, j]
                    arg[off + j] = d * mk * d
            off += n
        exp_v(arg, 0, off, s1, s2, b1, b2)
        size = 1
        phi[0] = 1.0
        off = 0
        for i in range(counts.shape[0]):
            n = counts[i]
            if n == 1:
                continue
            s = total(arg, off, n)
            for j in range(off, off + n):
                arg[j] = arg[j] / s
            if size == 1:
                for j in range(n):
                    phi[j] = arg[off + j]
            else:  # phi[a n + b] = phi[a] g[b]
                t = 0
                for a in range(size):
                    pa = phi[a]
                    for b in range(off, off + n):
                        tmp[t] = pa * arg[b]
                        t += 1
                for t in range(size * n):
                    phi[t] = tmp[t]
            size *= n
            off += n

    def dot(w, rows, code, K, phi, F, prod, tk):
        # sum over the K marked rows of w . phi, the sum over rows as total's (the exact: pairwise)
        for j in range(K):
            tk[j] = dot1(w, rows[code, j], phi, F, prod)
        return total(tk, 0, K)

    def dot_in(w, i, rows, code, K, phi, F, prod, tk):  # the same for input i's actor rows
        for j in range(K):
            tk[j] = dot1_in(w, rows[code, j], i, phi, F, prod)
        return total(tk, 0, K)

    leaf = (lambda fn: jit_fn(fn)) if exact_parts else (lambda fn: compile_leaf(jit_fn, fn, LEAF))
    return fk.Parts(jit_fn(scratch), leaf(rbf), leaf(dot), leaf(dot_in))


def simd_trial_kernel(
    plant_step: Callable, atoms: Callable, jit_fn: Callable, one_input: bool, timed: bool, exact_parts: bool = False
) -> Callable:
    """The trial of :func:`mitlc.learn.sacpn.kernel.trial_kernel` (the same loop, the same arguments,
    the same effect on them) with the fast kernel's parts (:func:`simd_parts`; ``exact_parts``: the
    exact kernel's sums, exp and cos, then its numbers to the bit: the test of everything else)."""
    return fk.trial_kernel(plant_step, atoms, jit_fn, one_input, timed, simd_parts(jit_fn, exact_parts))


def unsupported(agent: Any) -> str | None:
    """Why the fast kernel cannot train ``agent``, or None: the exact kernel's reasons
    (:func:`mitlc.learn.sacpn.kernel.unsupported`), no more."""
    return fk.unsupported(agent)
