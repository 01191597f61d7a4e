"""The smaller pieces of mitlc/petri/timed.py, pinned by hand and against the monitor: the
earliest witness behind the compiler's horizon warning, and the one-token view of an
obligation's sub-net that the learner sees."""

from __future__ import annotations

import math

import numpy as np
import pytest
import strategies
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.monitor.offline import monitor
from mitlc.petri.compile import compile_spec
from mitlc.petri.timed import earliest_witness
from mitlc.runtime.netruntime import NetRuntime
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_formula, parse_spec
from mitlc.spec.passes import normal_form


@pytest.mark.parametrize(
    ("text", "dt", "first"),
    [
        ("a", 0.1, 0.0),  # a state formula: the first sample
        ("!a & b", 0.1, 0.0),
        ("F[0.5,2] a", 0.1, 0.5),  # lo = 5 samples of 0.1 s
        ("F[0.5,2] a", 0.25, 0.5),  # lo = 2 samples of 0.25 s
        ("F[1,1] a", 0.5, 1.0),  # a point interval on a sample: that sample
        ("F[0.3,2] a", 0.25, 0.5),  # 0.3 s falls between samples: the first one inside is at 0.5 s
        ("F[1,2] F[0.5,1] a", 0.5, 1.5),  # nested: the offsets add up
        ("F[1,2] a & F[3,4] b", 0.5, 3.0),  # both: the later one
        ("F[1,2] a | F[3,4] b", 0.5, 1.0),  # either: the earlier one
        ("3 * F[1,2] a", 0.5, 1.0),  # a weight changes no time
        ("a U[2,3] b", 0.5, 2.0),  # until: its right side at the interval's start
        ("a U[2,3] F[1,2] b", 0.5, 3.0),
        ("G[1,2] F[5,6] a", 0.5, 0.0),  # G needs no witness: an empty trace satisfies it
        ("a R[1,2] F[5,6] b", 0.5, 0.0),
        ("F[0.51,0.55] a", 0.1, math.inf),  # no sample offset in the interval: never
        ("F[0,1] F[0.51,0.55] a", 0.1, math.inf),
    ],
)
def test_earliest_witness_by_hand(text: str, dt: float, first: float) -> None:
    assert earliest_witness(parse_formula(text), dt) == pytest.approx(first, abs=1e-12)


N = 5  # samples 0..5 over two propositions: every trace of each length
CODES = np.arange(4 ** (N + 1))
BITS = np.stack([(CODES >> (2 * j)) & 3 for j in range(N + 1)], axis=1)
STATES = np.stack([BITS & 1, BITS >> 1], axis=2).astype(float)  # columns x, y
SPEC = parse_spec("prop a = x > 0.5\nprop b = y > 0.5\nformula a")

intervals = strategies.grid_intervals(step=0.5, max_end=4)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(f=strategies.formulas(atoms=("a", "b"), interval=intervals, max_leaves=4), dt=st.sampled_from([0.5, 1.0]))
def test_no_trace_shorter_than_the_earliest_witness_satisfies(f: A.Formula, dt: float) -> None:
    """The bound against the monitor: every trace (over two propositions) that ends before the
    earliest witness violates the formula, so the compiler's warning is never wrong."""
    nf = normal_form(f)
    first = earliest_witness(nf, dt)
    for n in range(N + 1):  # traces of n + 1 samples, ending at n * dt
        if n * dt < first - 1e-9:
            sat = monitor(SPEC, STATES[: 4 ** (n + 1), : n + 1], dt, formula=nf).satisfied
            assert not sat.any(), (str(nf), first, n)


def _marked(rs, M: np.ndarray) -> list[str]:
    return [name for name, m in zip(rs.net.place_names, M[0], strict=True) if m]


def test_the_learner_sees_one_token_per_obligation_sub_net_by_hand() -> None:
    """G[0,1] (a -> F[1,1.5] b) at dt = 0.5 s: a at t = 0.5 s starts an F obligation whose
    window is [1, 1.5] s after it, samples t = 1.5 and 2 s; b at t = 1.5 s meets it.

    - t = 0: a is false, no F instance is needed: F's token is idle; G's window [0, 1] s holds
      the next sample: open.
    - t = 0.5: a: the F instance started now waits (its window opens two samples on).
    - t = 1: its window holds the next sample (t = 1.5): open; G's window holds no later sample:
      G waits on the F instance.
    - t = 1.5: b meets F; G has every instance true: met. Nothing lives below it: idle.
    """
    spec = "plant pendulum(dt = 0.5)\nhorizon 3\nprop a = q > 1\nprop b = q < -1\nformula G[0,1] (a -> F[1,1.5] b)\n"
    rs = compile_spec(parse_spec(spec))
    assert rs.net.place_names[:7] == (
        "p_idle_F1",
        "p_open_F1",
        "p_wait_F1",
        "p_open_G2",
        "p_wait_G2",
        "p_met_G2",
        "p_failed_G2",
    )
    rt = NetRuntime(rs, ("q", "qdot"), dt=0.5, steps=6)
    x = np.array([[[q, 0.0] for q in (0.0, 2.0, 0.0, -2.0, 0.0, 0.0, 0.0)]])
    M = rt.reset(x[:, 0])
    seen = [_marked(rs, M)]
    for k in range(1, 7):
        M = rt.step(M, x[:, k], k * 0.5)
        seen.append(_marked(rs, M))
    assert seen == [
        ["p_idle_F1", "p_open_G2", "p_none_a_b"],
        ["p_wait_F1", "p_open_G2", "p_a"],
        ["p_open_F1", "p_wait_G2", "p_none_a_b"],
        ["p_idle_F1", "p_met_G2", "p_b"],
        ["p_idle_F1", "p_met_G2", "p_none_a_b"],
        ["p_idle_F1", "p_met_G2", "p_none_a_b"],
        ["p_idle_F1", "p_met_G2", "p_none_a_b"],
    ]
    # the packed codes decode to the same markings
    code = rt.reset_code(x[:, 0])
    for k in range(1, 7):
        code = rt.step_code(code, x[:, k], k * 0.5)
    np.testing.assert_array_equal(rt.decode(code), M)
