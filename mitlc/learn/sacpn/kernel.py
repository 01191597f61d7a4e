"""SACPN's fused trial kernel: one compiled loop over the runs and steps of a trial.

:meth:`mitlc.learn.sacpn.Sacpn._trial` is the reference: about forty numpy calls
per step on ``(R, places, features)`` arrays, where at ``R = 30`` the interpreter's
overhead dominates. :func:`trial_kernel` builds the same trial as *plain Python*
over explicit loops (runs outer, steps inner, features innermost) and compiles it
with numba (``nopython``, ``fastmath=False``: IEEE order, no fused multiply-adds)
when numba is installed (``pip install mitlc[fast]``).

How the two are kept in step
----------------------------
There is one algorithm written twice, vectorised and scalar, and nothing may drift:

* the kernel is plain Python, so ``tests/test_kernel.py`` runs it *uncompiled*
  (``jit`` the identity) on small problems and checks its returns and parameters
  equal the numpy trial's **to the bit**; a change to one that the other does not
  mirror fails that test, with or without numba installed;
* the compiled kernel is checked the same way on P1..P5, N1..N4 and a mass-damper spec;
* the timed obligations' engine (:mod:`mitlc.runtime.obligation_kernel`, the same plain-Python
  rule) is checked against :class:`~mitlc.runtime.obligations.TimedState` after every sample of
  random formulas and traces (``tests/test_obligation_kernel.py``);
* the plant's physics is written once (``ode`` of :mod:`mitlc.plants`, or the
  pendulum's fused constants) and each plant's :attr:`~mitlc.plants.base.Plant.kernel_step`
  is tested bit for bit against the batched step;
* every sum is numpy's pairwise ``add.reduce`` order (:func:`~mitlc.plants.base.pairwise_sum_for`):
  the numpy trial sums its dot products with ``add.reduce``, not BLAS (whose order
  depends on the CPU), and the kernel repeats that order;
* numba's ``sin``, ``cos`` and ``exp`` are the C library's, and so are numpy's float64
  ones on x86-64 up to AVX2. On a CPU with AVX-512, numpy uses its own SIMD code, which
  rounds some results differently in the last place: there the two paths agree to about
  1e-13 of the parameters' size after a few trials, not to the bit (the tests check the
  bits with numpy held to its baseline, ``NPY_DISABLE_CPU_FEATURES``, and a tolerance
  otherwise).

Scope: ODE plants with a ``kernel_step`` (any number of inputs), environments whose numpy twin has a
step for one copy (:meth:`~mitlc.plants.gym_twins.Twin.kernel_physics`: Pendulum-v1 and
MountainCarContinuous-v0; :func:`env_step`
reads the state variables off its observation), RBF features without warped axes, nets
whose transitions and rewards are fully tabulated, with or without timed
obligations (nested intervals under ``clock = standard``: their sub-nets' tokens
are moved after each table look-up by a per-run engine over arrays,
:mod:`mitlc.runtime.obligation_kernel`, compiled in only for such nets), except
timed obligations in a net whose tables are compact (a code then indexes the
reachable markings, so a token cannot move by code arithmetic; none of the shipped
specs). The predicates are compiled from their syntax trees (data, never text) to
Python source by :func:`mitlc.runtime.atoms.atom_source`. Anything else trains on
the numpy path (:func:`unsupported` says why).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from mitlc.plants.base import pairwise_sum_for
from mitlc.runtime.obligation_kernel import no_obligations, obligation_kernel

__all__ = [
    "numba_available",
    "jit",
    "identity",
    "Parts",
    "env_step",
    "exact_parts",
    "trial_kernel",
    "rbf_kernel",
    "unsupported",
]


def numba_available() -> bool:
    """True when numba can be imported (``mitlc[fast]``)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def jit(fn: Callable) -> Callable:
    """``fn`` compiled by numba in nopython mode, IEEE order kept (no fastmath), numpy's
    error model (a division by zero gives inf or NaN, as in the numpy trial)."""
    import numba

    return numba.njit(fastmath=False, error_model="numpy", nogil=True)(fn)


def identity(fn: Callable) -> Callable:
    """The uncompiled kernel's ``jit``."""
    return fn


# ---------------------------------------------------------------- features and the trial


def rbf_kernel(jit_fn: Callable) -> Callable:
    """``rbf(x, counts, periodic, lo, hi, k, centres, g, phi)``: :class:`~mitlc.learn.features.RbfFeatures`
    of one state into ``phi``, each axis's kernels in ``g`` (the same operations in the same order)."""
    psum = pairwise_sum_for(jit_fn)

    def rbf(x, counts, periodic, lo, hi, k, centres, g, phi):
        size = 1
        phi[0] = 1.0
        first = True
        for i in range(counts.shape[0]):
            n = counts[i]
            if n == 1:
                continue
            z = x[i]
            if periodic[i]:  # exp(2k cos(z - c) - 2k)
                k2 = 2.0 * k[i]
                for j in range(n):
                    g[i, j] = np.exp(np.cos(z - centres[i, j]) * k2 - k2)
            else:  # exp(-k (z - c)^2), z clipped
                zi = np.minimum(np.maximum(z, lo[i]), hi[i])
                mk = -k[i]
                for j in range(n):
                    d = zi - centres[i, j]
                    g[i, j] = np.exp(d * mk * d)
            s = psum(g[i], 0, n)
            for j in range(n):
                g[i, j] = g[i, j] / s
            if first:
                for j in range(n):
                    phi[j] = g[i, j]
                first = False
            else:  # phi[a n + b] = phi[a] g[b], in place from the end
                for a in range(size - 1, -1, -1):
                    pa = phi[a]
                    for b in range(n - 1, -1, -1):
                        phi[a * n + b] = pa * g[i, b]
            size *= n

    return jit_fn(rbf)


class Parts(NamedTuple):
    """What a fused trial computes its features and its sums over the marked rows with, compiled;
    :func:`trial_kernel` is one loop over any such parts (:func:`exact_parts`, the exact kernel's;
    :func:`mitlc.learn.sacpn.simd.simd_parts`, the fast kernel's), calling them as follows:

    * ``scratch(centres, F)``: the features' scratch ``work``, allocated once per trial (any value
      ``rbf`` takes: an array, a tuple of arrays);
    * ``rbf(x, counts, periodic, lo, hi, k, centres, work, phi)``: the features of one state into
      ``phi`` (:class:`~mitlc.learn.features.RbfFeatures`);
    * ``dot(w, rows, code, K, phi, F, prod, tk)``: ``sum_j w[rows[code, j]] . phi`` over the ``K``
      marked rows (``w`` ``(P, F)``: the critic's), ``prod`` ``(F,)`` and ``tk`` ``(>= K,)`` scratch;
    * ``dot_in(w, i, rows, code, K, phi, F, prod, tk)``: the same for input ``i``'s rows of the
      actor's ``w`` ``(P, m, F)``.
    """

    scratch: Callable
    rbf: Callable
    dot: Callable
    dot_in: Callable


def exact_parts(jit_fn: Callable) -> Parts:
    """The exact kernel's parts (:class:`Parts`), compiled by ``jit_fn``: :func:`rbf_kernel`'s features
    (the C library's exp and cos), and each dot product's products rounded, then summed in numpy's
    pairwise order, as is the sum over the rows."""
    psum = pairwise_sum_for(jit_fn)

    def scratch(centres, F):
        return np.empty(centres.shape)  # each axis's kernels (rbf_kernel's g)

    def dot(w, rows, code, K, phi, F, prod, tk):
        # sum over the K marked rows of w . phi, each sum and the sum over rows pairwise
        for j in range(K):
            row = rows[code, j]
            for f in range(F):
                prod[f] = w[row, f] * phi[f]
            tk[j] = psum(prod, 0, F)
        return psum(tk, 0, K)

    def dot_in(w, i, rows, code, K, phi, F, prod, tk):  # the same over input i's actor rows
        for j in range(K):
            row = rows[code, j]
            for f in range(F):
                prod[f] = w[row, i, f] * phi[f]
            tk[j] = psum(prod, 0, F)
        return psum(tk, 0, K)

    return Parts(jit_fn(scratch), rbf_kernel(jit_fn), jit_fn(dot), jit_fn(dot_in))


def trial_kernel(
    plant_step: Callable, atoms: Callable, jit_fn: Callable, one_input: bool, timed: bool, parts: Parts | None = None
) -> Callable:
    """The fused trial for one plant step and one atom-code function, compiled by ``jit_fn``;
    ``one_input``: the plant has one input; ``timed``: for nets with timed obligations (else
    their engine is left out: a shorter compile); ``parts``: the features and the sums over the
    marked rows (:class:`Parts`, compiled by ``jit_fn`` too), :func:`exact_parts` when None (the
    exact kernel; :func:`mitlc.learn.sacpn.simd.simd_trial_kernel` passes the fast ones).

    ``trial(x, noise, code0, xi, theta, ret, next_code, clock, reward_tab, reward_full,
    marked, marked_c, pen, pen_left, pc, fc..., scalars, u_lo, u_hi, ..., flags, obligations...,
    timed)`` runs every run's steps of Algorithm 1 as :meth:`~mitlc.learn.sacpn.Sacpn._trial_numpy`
    does, updating ``x``, ``xi``, ``theta`` and ``ret`` in place. ``xi`` is ``(R, P, m, F)`` and
    ``noise`` ``(N, R, m)`` for ``m`` inputs, each saturated to its own box ``[u_lo, u_hi]``;
    ``plant_step`` takes ``u`` as a number when ``one_input`` (the
    :attr:`~mitlc.plants.base.Plant.kernel_step` of a plant with one input), else as ``(m,)``.
    With ``timed`` the timed obligations' tokens are moved after each table look-up as
    :meth:`~mitlc.runtime.NetRuntime.advance_code` moves them
    (:mod:`mitlc.runtime.obligation_kernel`; ``obligations...`` are its arrays).
    """
    scratch, rbf, dot, dot_in = exact_parts(jit_fn) if parts is None else parts
    obligations = obligation_kernel(jit_fn) if timed else jit_fn(no_obligations)
    if one_input:
        scalar_step = plant_step

        def step_one(x, u, c, w):
            scalar_step(x, u[0], c, w)

        plant_step = jit_fn(step_one)

    def trial(
        X,
        noise,
        code0,
        xi,
        theta,
        ret,
        next_code,
        clock,
        reward_tab,
        reward_full,
        marked,
        marked_c,
        pen,
        pen_left,
        pc,
        nwork,
        counts,
        periodic,
        lo,
        hi,
        kw,
        centres,
        gamma,
        gl,
        a_c,
        a_a,
        u_lo,
        u_hi,
        inv_k,
        inv_kc,
        current,
        applied,
        bootstrap,
        known,
        full,
        o_nodes,
        o_truth,
        o_temporal,
        o_mem,
        o_regs,
        timed,
    ):
        R, P, m, F = xi.shape[0], xi.shape[1], xi.shape[2], xi.shape[3]
        N = noise.shape[0]
        K, KC = marked.shape[1], marked_c.shape[1]
        phi = np.empty(F)
        phi_next = np.empty(F)
        prod = np.empty(F)
        tk = np.empty(max(K, KC))
        work = scratch(centres, F)
        w = np.empty(nwork)
        e = np.empty((P, F)) if current else np.empty((1, F))
        u, u_sat, a, du, coef = np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty(m)
        for r in range(R):
            x = X[r]
            xr, th = xi[r], theta[r]
            e[:, :] = 0.0
            scale = 1.0
            code = code0[r]
            if timed:  # the obligations start on the first sample: their tokens' places in code
                ac = atoms(x)
                code = obligations(0, ac, code, o_nodes, o_truth, o_temporal, o_mem, o_regs)
            rbf(x, counts, periodic, lo, hi, kw, centres, work, phi)
            for i in range(m):
                u[i] = dot_in(xr, i, marked, code, K, phi, F, prod, tk) * inv_k
            for k in range(N):
                # act: u_k = pi(x_k) + du_k, each input saturated to its box
                for i in range(m):
                    nz = noise[k, r, i]
                    if applied:
                        u_sat[i] = np.maximum(np.minimum(u[i], u_hi[i]), u_lo[i])
                        a[i] = np.maximum(np.minimum(u_sat[i] + nz, u_hi[i]), u_lo[i])
                        du[i] = a[i] - u_sat[i]
                    else:
                        u_sat[i] = u[i]
                        a[i] = u[i] + nz
                        du[i] = nz
                # the plant and the net move
                plant_step(x, a, pc, w)
                ac = atoms(x)
                code1 = next_code[clock[k], code, ac]
                if timed:  # NetRuntime.advance_code: the obligations' tokens, which the tables keep
                    code1 = obligations(k + 1, ac, code1, o_nodes, o_truth, o_temporal, o_mem, o_regs)
                rew = reward_tab[code, code1]
                ret[r] += rew if full else reward_full[code, code1]
                rbf(x, counts, periodic, lo, hi, kw, centres, work, phi_next)
                # TD error with Theta_k
                delta = dot(th, marked_c, code, KC, phi, F, prod, tk) * -inv_kc
                delta += rew
                if bootstrap or k < N - 1:
                    delta += dot(th, marked_c, code1, KC, phi_next, F, prod, tk) * (gamma * inv_kc)
                if known:
                    delta += pen[code] * pen_left[k] - (gamma * pen_left[k + 1]) * pen[code1]
                # actor, per input
                for i in range(m):
                    coef[i] = delta * du[i]
                    if applied:
                        over = (u[i] - u_sat[i]) * coef[i]
                        coef[i] *= 1.0 if over <= 0.0 else 0.0
                # critic
                scale *= gl
                if scale < 1e-100:
                    for i in range(e.shape[0]):
                        for f in range(F):
                            e[i, f] *= scale
                    scale = 1.0
                if current:
                    for i in range(m):
                        c_i = coef[i] * (a_a * inv_k)
                        for j in range(K):
                            row = marked[code, j]
                            for f in range(F):
                                xr[row, i, f] += c_i * phi[f]
                    c_e = inv_kc / scale
                    for j in range(KC):
                        row = marked_c[code, j]
                        for f in range(F):
                            e[row, f] += c_e * phi[f]
                    sv = delta * (a_c * scale)
                    for i in range(P):
                        for f in range(F):
                            th[i, f] += e[i, f] * sv
                else:
                    for i in range(m):
                        c_i = coef[i] * a_a
                        for j in range(K):
                            row = marked[code1, j]
                            for f in range(F):
                                xr[row, i, f] += c_i * phi[f]
                    c_e = 1.0 / scale
                    for f in range(F):
                        e[0, f] += phi[f] * c_e
                    sv = delta * (a_c * scale)
                    for j in range(KC):
                        row = marked_c[code1, j]
                        for f in range(F):
                            th[row, f] += e[0, f] * sv
                # next policy output with Xi_k+1
                code = code1
                phi, phi_next = phi_next, phi
                for i in range(m):
                    u[i] = dot_in(xr, i, marked, code, K, phi, F, prod, tk) * inv_k

    return jit_fn(trial)


def env_step(physics: Callable, observe: Callable, n: int, jit_fn: Callable) -> Callable:
    """One copy's step of an environment with a numpy twin, ``step(x, u, c, w)``
    (:meth:`~mitlc.plants.gym_env.GymSimulator.kernel_step`): ``x`` is the ``n`` state variables, then
    the twin's hidden state; ``u`` is clipped to ``[-c[0], c[0]]`` and rounded to the environment's
    float32 action as :meth:`~mitlc.plants.gym_env.GymSimulator.step` does, the twin's ``physics`` steps
    the hidden state with ``c[1:]`` and writes the observation into ``w``, and ``observe``
    (:func:`mitlc.runtime.atoms.compile_observe`) reads the state variables off it; a copy whose episode
    ended keeps its state (``physics`` returns False), as the simulator keeps it."""

    def step(x, u, c, w):
        a = np.float32(np.minimum(np.maximum(u, -c[0]), c[0]))
        if physics(x[n:], a, c[1:], w):  # a copy whose episode ended keeps its last state
            observe(w, x)

    return jit_fn(step)


def unsupported(agent: Any) -> str | None:
    """Why the fused kernel cannot train ``agent`` (a :class:`~mitlc.learn.sacpn.Sacpn`), or None."""
    plant = agent.plant
    if plant.stepped:
        parts = agent.sim.kernel_step(agent.runs) if hasattr(agent.sim, "kernel_step") else None
        if parts is None:
            return f"plant '{plant.name}' is an environment (stepped, not integrated)"
        if isinstance(parts, str):
            return f"plant '{plant.name}' is an environment, stepped in numpy: {parts}"
    elif plant.kernel_step is None:
        return f"plant '{plant.name}' has no kernel_step (its one-step map for one run)"
    rt = agent.runtime
    if rt.timed and rt.compact:
        return "the net has timed obligations and compact tables (codes index its reachable markings)"
    if agent.rs.paid_by_monitor:
        return f"the reward is the monitor's ({agent.rs.options.reward}), not the net's"
    if rt.graded:
        return "the reward is graded (reward = shaped): it reads the state, not only the marking"
    if rt.tables is None or rt.tables.reward is None:
        return "the net's rewards are not tabulated"
    if any(w is not None for w in agent.features.warps):
        return "the features have warped axes"
    return None
