"""SACPN's fast trial kernel (mitlc.learn.sacpn.simd, kernel = simd) against the exact one and numpy.

The fast kernel is the exact kernel with two changes: its sums over features are reassociated
(fastmath's ``reassoc`` on those loops only) and its exp and cos are its own vectorisable ones.
So it is tested in three parts:

* with ``exact_parts`` (numpy's pairwise sums, the C library's exp and cos) it must be the exact
  kernel **to the bit**: uncompiled (plain Python, no numba needed) on every spec kind and variant
  of ``tests/test_kernel.py``, compiled on three (P4, N1, a mass-damper spec);
* its exp and cos within **1 ulp** of the C library's;
* the fast path itself against the numpy reference over a whole short training (``TRIALS`` trials
  of ``RUNS`` runs at the spec's horizon) on P1..P5, N2 and a nested spec: the parameters within
  ``RTOL_TRAINING`` of their size, the returns within the same, and the monitor's verdicts on the
  final greedy policies identical.

Why a short training: any difference in the last place (the fast path's, or numpy's own AVX-512
exp against the C library's, which the exact kernel meets on such a machine) grows as a training
goes on, and where a run's trajectory crosses a proposition's threshold one way in one path and the
other way in the other, the two trainings part (measured, R = 4, seed 1: after 5 trials the
parameters agreed within 1.6e-12 of their size on all seven specs; after 10, P2's and P4's differed
by 3e-3 and 0.5, and so did the exact kernel's against numpy on this AVX-512 machine: 3e-3 and 1e-2).
That was an AVX-512 Xeon. On an AMD EPYC with AVX-512 (2026-12-08, the same numpy, numba and seed) P4
grows faster: 5.1e-12 after 4 trials, 2.0e-9 after 5, 1.7e-6 after 6 (about 400 times a trial), the
six others 1.7e-12 at most after 5. ``RTOL_TRAINING`` = 1e-6 (it was 1e-9, which P4 passed by 2.0e-9 on
that machine) leaves a margin of 500 there and of a million on the Xeon, and a slip in the kernel (a
wrong row, sign or step) gives differences of order 1.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_kernel import (
    SMALL,
    SPECS,
    TIMED,
    UNICYCLE,
    UNICYCLE_SMALL,
    VARIANTS,
    rs_of,
)

from mitlc.errors import TrainingError
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.learn.sacpn import kernel as fk
from mitlc.learn.sacpn import simd as sk
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.spec.parse import load_spec, parse_spec

RUNS, TRIALS = 4, 5
RTOL_TRAINING = 1e-6
"""The fast path against numpy after ``TRIALS`` trials, relative to the parameters' largest entry."""


def same_as_exact(rs, settings: SacpnSettings, jit, trials: int = 2, runs: int = 3, ramp: int = 0) -> None:
    """``trials`` trials of the exact kernel and of the fast one with ``exact_parts``: equal bits."""
    a = Sacpn(rs, settings, runs=runs, seed=3)
    b = Sacpn(rs, settings, runs=runs, seed=3)
    a.ramp_trials = b.ramp_trials = ramp
    exact, fast = a.fused_trial(jit), b.fused_trial(jit, simd=True, exact_parts=True)
    for _ in range(trials):
        ra, rb = exact(), fast()
        a.trial += 1
        b.trial += 1
        assert np.array_equal(ra, rb)
        assert np.array_equal(a.xi, b.xi) and np.array_equal(a.theta, b.theta)
    assert np.abs(a.theta).max() > 0  # it learned something


# ------------------------------------------------------------ the layout, to the bit


@pytest.mark.parametrize("name", SPECS)
@pytest.mark.parametrize("variant", range(len(VARIANTS)))
def test_uncompiled_simd_kernel_with_exact_parts_is_the_exact_kernel(name: str, variant: int) -> None:
    same_as_exact(rs_of(name), SacpnSettings(kernel="numpy", **SMALL, **VARIANTS[variant]), fk.identity)


@pytest.mark.parametrize("name", TIMED)
def test_uncompiled_simd_kernel_with_timed_obligations(name: str) -> None:
    for variant in VARIANTS:
        same_as_exact(rs_of(name), SacpnSettings(kernel="numpy", **SMALL, **variant), fk.identity)


@pytest.mark.parametrize("violations", ["permanent", "counted"])
def test_uncompiled_simd_kernel_with_violations_and_the_penalty_ramp(violations: str) -> None:
    for value in ("known", "learned"):
        st = SacpnSettings(kernel="numpy", violation_value=value, **SMALL)
        same_as_exact(rs_of("pendulum/p2_avoid", violations), st, fk.identity, trials=3, ramp=2)


@pytest.mark.parametrize("formula", ["F G goal", "F G goal & 10 * G !rock"])
def test_uncompiled_simd_kernel_with_two_inputs(formula: str) -> None:
    rs = compile_spec(parse_spec(UNICYCLE.format(formula)))
    for variant in VARIANTS:
        same_as_exact(rs, SacpnSettings(kernel="numpy", **UNICYCLE_SMALL, **variant), fk.identity, trials=3)


@pytest.mark.parametrize("name", ["pendulum/p4_alternate", "pendulum/n1_reach_in_time", SPECS[-1]])
def test_compiled_simd_kernel_with_exact_parts_is_the_exact_kernel(name: str) -> None:
    pytest.importorskip("numba")
    same_as_exact(rs_of(name), SacpnSettings(kernel="numpy"), fk.jit, trials=3)


# ------------------------------------------------------------ exp and cos


def _ulps(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    both_nan = np.isnan(got) & np.isnan(want)
    same = (got == want) | both_nan
    with np.errstate(invalid="ignore"):
        return np.where(same, 0.0, np.abs(got - want) / np.spacing(np.abs(want)))


@pytest.mark.parametrize("compiled", [False, True])
def test_exp_and_cos_within_an_ulp_of_the_c_library(compiled: bool) -> None:
    if compiled:
        pytest.importorskip("numba")
    jit = fk.jit if compiled else fk.identity
    exp_v, cos_v = sk.exp_vec_for(jit), sk.cos_vec_for(jit)
    rng = np.random.default_rng(4)
    n = 20000 if compiled else 1500
    special = [0.0, -0.0, 1e-300, -1e-300, 709.7, 709.8, -708.0, -744.0, -745.2, -746.0, -800.0]
    x = np.concatenate([rng.uniform(-745.0, 709.0, n), rng.uniform(-3.0, 3.0, n), special])
    x = np.concatenate([x, [math.inf, -math.inf, math.nan]])
    a = x.copy()
    s1, s2 = np.empty(len(a)), np.empty(len(a))
    with np.errstate(over="ignore"):  # plain Python: numpy scalars say when exp overflows to inf
        exp_v(a, 0, len(a), s1, s2, s1.view(np.int64), s2.view(np.int64))
    want = np.array([math.exp(v) if v < 709.8 else math.inf for v in x[:-3]] + [math.inf, 0.0, math.nan])
    assert _ulps(a, want).max() <= 1.0
    # the periodic features' angles, and far beyond them
    y = np.concatenate([rng.uniform(-7.0, 7.0, n), rng.uniform(-100.0, 100.0, n), [0.0, math.pi / 2, -math.pi]])
    c = y.copy()
    cos_v(c, 0, len(c))
    want = np.array([math.cos(v) for v in y])
    # near a zero of cos, 1 ulp of the result is tiny: compare there to the argument's rounding instead
    err = np.abs(c - want)
    assert np.all((err <= np.spacing(np.abs(want))) | (err <= 1e-16 * np.maximum(np.abs(y), 1.0)))


# ------------------------------------------------------------ the fast path against numpy

TRAINED = [
    "pendulum/p1_swing_up",
    "pendulum/p2_avoid",
    "pendulum/p3_avoid_speed_limit",
    "pendulum/p4_alternate",
    "pendulum/p5_timed_visit",
    "pendulum/n2_hold_up",
    "nested: 3 * G (a -> F[0,0.5] b)",
]


@pytest.mark.parametrize("name", TRAINED)
def test_fast_path_within_tolerance_of_numpy_over_a_training(name: str) -> None:
    """``TRIALS`` trials of ``RUNS`` runs at the spec's horizon (a whole training, penalty ramp and
    all) on numpy and on the fast path from one seed: parameters and returns within
    ``RTOL_TRAINING``, and the same verdicts of the final greedy policies."""
    pytest.importorskip("numba")
    from mitlc.sweep.race import greedy_verdicts

    rs = rs_of(name)
    a = Sacpn(rs, SacpnSettings(kernel="numpy"), runs=RUNS, seed=1)
    b = Sacpn(rs, SacpnSettings(kernel="simd"), runs=RUNS, seed=1)
    assert (b.kernel, b.kernel_reason) == ("simd", None)
    ra, rb = a.train(TRIALS), b.train(TRIALS)
    for x, y in ((a.xi, b.xi), (a.theta, b.theta), (ra, rb)):
        size = float(np.abs(x).max())
        assert size > 0
        assert float(np.abs(x - y).max()) <= RTOL_TRAINING * size
    va, _ = greedy_verdicts(a)
    vb, _ = greedy_verdicts(b)
    assert np.array_equal(va, vb)


def test_fast_path_is_deterministic_and_a_run_does_not_depend_on_R() -> None:
    pytest.importorskip("numba")
    rs = rs_of("pendulum/p4_alternate")
    a = Sacpn(rs, SacpnSettings(kernel="simd"), runs=3, seed=2)
    b = Sacpn(rs, SacpnSettings(kernel="simd"), runs=3, seed=2)
    c = Sacpn(rs, SacpnSettings(kernel="simd"), runs=2, seed=2)
    ra, rb, rc = a.train(3), b.train(3), c.train(3)
    assert np.array_equal(ra, rb) and np.array_equal(a.xi, b.xi) and np.array_equal(a.theta, b.theta)
    assert np.array_equal(ra[:2], rc) and np.array_equal(a.xi[:2], c.xi) and np.array_equal(a.theta[:2], c.theta)


def test_fast_path_compiles_its_sums_with_reassociation_only() -> None:
    """The disk cache writes the three sums with fastmath's reassoc and nsz flags, the leaf functions
    (which allocate nothing) without reference counts, and every other function as the exact
    kernel's (IEEE order)."""
    pytest.importorskip("numba")
    from mitlc.learn import jitcache

    agent = Sacpn(rs_of("pendulum/p1_swing_up"), SacpnSettings(kernel="numpy"), runs=1)
    agent.fused_trial(fk.identity, simd=True)
    source, _ = jitcache.module_source(agent._kernel_fn, "test")
    lines = [line for line in source.splitlines() if not line.startswith("_jit = ")]  # the module's own _jit
    jits = [line for line in lines if " = _jit(" in line or " = numba.njit(" in line]
    sums = [line for line in jits if "fastmath={'nsz', 'reassoc'}" in line]
    leaves = [line for line in jits if "fastmath=False" in line and "_nrt=False" in line]
    assert len(sums) == 3 and all("_nrt=False" in line for line in sums)
    assert len(leaves) == 5  # exp, cos, the features, the critic's and the actor's marked rows
    assert "fastmath=True" not in source and "contract" not in source
    assert len(jits) - len(sums) - len(leaves) == sum(" = _jit(" in line for line in jits) >= 5


# ------------------------------------------------------------ the setting


def test_kernel_simd_setting(monkeypatch: pytest.MonkeyPatch) -> None:
    rs = rs_of("pendulum/p1_swing_up")
    SacpnSettings(kernel="simd").check()
    with pytest.raises(TrainingError, match="unknown kernel"):
        SacpnSettings(kernel="lanes").check()
    if fk.numba_available():
        agent = Sacpn(rs, SacpnSettings(kernel="simd"))
        assert (agent.kernel, agent.kernel_reason) == ("simd", None)
        assert Sacpn(rs, SacpnSettings()).kernel == "numba"  # auto stays the exact kernel
    monkeypatch.setattr(fk, "numba_available", lambda: False)
    with pytest.raises(TrainingError, match="kernel = simd needs numba"):
        Sacpn(rs, SacpnSettings(kernel="simd"))


def test_kernel_simd_falls_back_saying_why() -> None:
    """Outside the kernels' scope (here a reward that reads the state), kernel = simd trains on the
    numpy path and says why."""
    pytest.importorskip("numba")  # without it kernel = simd is refused (test_kernel_simd_setting)
    spec = load_spec("pendulum/p1_swing_up")
    rs = compile_spec(spec, CompileOptions.from_spec(spec, reward="shaped"))
    agent = Sacpn(rs, SacpnSettings(kernel="simd"), runs=1, seed=0)
    assert agent.kernel == "numpy"
    why = fk.unsupported(agent)
    assert why is not None and sk.unsupported(agent) == why
    assert agent.kernel_reason == f"kernel = simd cannot: {why}; nor the exact kernel"
    agent.train(1)
