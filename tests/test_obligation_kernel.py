"""The scalar obligation engine (mitlc.runtime.obligation_kernel) against TimedState, its reference.

After every sample of random traces of random formulas with nested intervals (every operator,
open and closed ends, some off the sample grid, unbounded ones), the engine, run one trace at a
time as plain Python, must hold TimedState's values at every start time that can matter, its
liveness everywhere, and move the sub-nets' tokens in a marking code to the places
``TimedState.places`` gives. SACPN's fused kernel runs this engine compiled
(tests/test_kernel.py checks the trials it gives, bit for bit).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import pytest
import strategies
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.petri.timed import NODE_LOCAL, ROOT_LOCAL, ObligationTree, TimedNet
from mitlc.runtime import obligation_kernel as ok
from mitlc.runtime.obligations import TimedState
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_formula
from mitlc.spec.passes import normal_form

STEP = ok.obligation_kernel(lambda fn: fn)  # plain Python
TEMPORAL = (A.Eventually, A.Globally, A.Until, A.Release)


def run_both(f: A.Formula, bits: np.ndarray, dt: float, step: Callable = STEP) -> None:
    """Feed traces ``bits`` ``(runs, samples)`` of atom codes over ``a``, ``b`` to both engines."""
    tree = ObligationTree.build(normal_form(f))
    temporal = tree.temporal
    sizes = [4 if i == tree.root else 3 for i in temporal]
    strides = [int(np.prod(sizes[j + 1 :])) for j in range(len(sizes))]
    tn = TimedNet(tree, tuple((i, j) for j, i in enumerate(temporal)))
    R, L = bits.shape
    arrays = ok.build([tn], ("a", "b"), dt, L - 1, strides, sizes)
    state = TimedState(tree, dt, R, L - 1)
    work = [ok.scratch(arrays) for _ in range(R)]
    rel = arrays.nodes[:, ok.REL]
    for k in range(L):
        state.observe({"a": (bits[:, k] & 1).astype(bool), "b": (bits[:, k] >> 1).astype(bool)})
        where = state.places()
        want = sum(
            (ROOT_LOCAL if i == tree.root else NODE_LOCAL)[where[i]] * strides[j] for j, i in enumerate(temporal)
        )
        for r in range(R):
            code = step(k, int(bits[r, k]), 0, arrays.nodes, arrays.truth, arrays.temporal, *work[r])
            assert code == want[r], (str(f), k, r)
            st_r = work[r][0]  # its state: rows VAL .. MISS_FROM
            for g, node in enumerate(tree.nodes):
                assert np.array_equal(st_r[ok.VAL, g, : rel[g] + 1], state.values[g][r, : rel[g] + 1]), (str(f), k, g)
                if node.op != "state":
                    assert np.array_equal(st_r[ok.LIVE, g, :L] != 0, state.live[g][r]), (str(f), k, g)


intervals = st.one_of(strategies.grid_intervals(step=1.0, max_end=4), strategies.grid_intervals(step=0.5, max_end=7))
nested = (
    strategies.formulas(atoms=("a", "b"), interval=intervals, max_leaves=6)
    .filter(lambda f: A.depth(f) <= 4)
    .filter(lambda f: any(isinstance(n, TEMPORAL) for n in A.walk(normal_form(f))))
)


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(nested, st.integers(1, 12), st.integers(0, 2**32 - 1), st.sampled_from([1.0, 0.5, 0.3]))
def test_engine_is_timed_state(f: A.Formula, steps: int, seed: int, dt: float) -> None:
    bits = np.random.default_rng(seed).integers(0, 4, (5, steps + 1))
    run_both(f, bits, dt)


@pytest.mark.parametrize(
    "text",
    [
        "F[0,2] G[0,1] a",
        "G (a -> F[0,0.5] b)",
        "F[0,1.5] G a",
        "G[0,1] F[1,2] a",
        "a U[0,1] G[0,0.5] b",
        "b R[0.5,2] F[0,0.5] a",
        "G (F[0,0.3] a & F[0,0.3] b)",
    ],
)
def test_engine_on_long_traces(text: str) -> None:
    """The shipped specs' shapes at a pendulum's sample time: windows of tens of samples, 101 samples."""
    rng = np.random.default_rng(7)
    slow = np.repeat(rng.integers(0, 4, (3, 11)), 10, axis=1)[:, :101]  # long stretches of one code
    bits = np.concatenate([slow, rng.integers(0, 4, (2, 101)), np.full((1, 101), 3)])
    run_both(parse_formula(text), bits, 0.03)


@functools.cache
def compiled_step() -> Callable:
    from mitlc.learn.sacpn import kernel as fk

    return ok.obligation_kernel(fk.jit)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(nested, st.integers(1, 12), st.integers(0, 2**32 - 1), st.sampled_from([1.0, 0.5, 0.3]))
def test_compiled_engine_is_timed_state(f: A.Formula, steps: int, seed: int, dt: float) -> None:
    """The engine as the trial kernel runs it: compiled by numba (every op, until and release too)."""
    pytest.importorskip("numba")
    bits = np.random.default_rng(seed).integers(0, 4, (5, steps + 1))
    run_both(f, bits, dt, compiled_step())
