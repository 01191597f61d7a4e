"""The compiled net's timing and violation places agree with the monitor on what they track.

Random top-level parts F_I a, G_I a and a U_[0,b] c (intervals on the sample grid)
over random traces: the net's done / late / failed / violated places end up
marked exactly when the monitor says the part was met or failed.
"""

from __future__ import annotations

import numpy as np
import strategies
from hypothesis import given, settings
from hypothesis import strategies as st

from mitlc.monitor.offline import monitor
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.runtime import NetRuntime
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_spec

DT, N = 0.5, 12
SPEC = f"plant pendulum(dt = {DT})\nhorizon {N * DT}\nprop a = q > 0\nprop c = qdot > 0\nformula {{formula}}\n"


def run_net(rs, x: np.ndarray) -> np.ndarray:
    rt = NetRuntime(rs)
    m = rt.reset(x[:, 0])
    for k in range(N):
        m = rt.step(m, x[:, k + 1], (k + 1) * DT)
    return m


def place(rs, prefix: str) -> int:
    (i,) = [i for i, p in enumerate(rs.net.places) if p.name.startswith(prefix)]
    return i


signs = st.lists(st.booleans(), min_size=N + 1, max_size=N + 1)


def trace(a: list[bool], c: list[bool]) -> np.ndarray:
    return np.array([[[1.0 if ai else -1.0, 1.0 if ci else -1.0] for ai, ci in zip(a, c, strict=True)]])


finite = strategies.grid_intervals(DT, N, unbounded=False)


@settings(max_examples=150, deadline=None)
@given(finite, signs)
def test_eventually_done_and_late(interval: A.Interval, a: list[bool]) -> None:
    a[0] = False  # the net reads x_1 on; a sample 0 outside a makes both readings the same
    f = A.Eventually(A.Atom("a"), interval)
    spec = parse_spec(SPEC.format(formula=f))
    rs = compile_spec(spec, CompileOptions(violations="permanent"))
    m = run_net(rs, trace(a, [False] * (N + 1)))
    met = bool(monitor(spec, trace(a, [False] * (N + 1)), DT).satisfied[0])
    assert m[0, place(rs, "p_done_a")] == met
    assert m[0, place(rs, "p_late_a")] == (not met)


@settings(max_examples=150, deadline=None)
@given(finite, signs)
def test_globally_violated(interval: A.Interval, a: list[bool]) -> None:
    a[0] = True
    f = A.Globally(A.Atom("a"), interval)
    spec = parse_spec(SPEC.format(formula=f))
    rs = compile_spec(spec, CompileOptions(violations="permanent"))
    m = run_net(rs, trace(a, [False] * (N + 1)))
    held = bool(monitor(spec, trace(a, [False] * (N + 1)), DT).satisfied[0])
    assert m[0, place(rs, "p_violated_G_a")] == (not held)


@settings(max_examples=150, deadline=None)
@given(st.integers(1, N).map(lambda i: i * DT), signs, signs)
def test_bounded_until_failed_or_met(b: float, a: list[bool], c: list[bool]) -> None:
    a[0], c[0] = True, False  # sample 0 keeps the until open in both readings
    f = A.Until(A.Atom("a"), A.Atom("c"), A.Interval(0, b))
    spec = parse_spec(SPEC.format(formula=f))
    rs = compile_spec(spec, CompileOptions(violations="permanent"))
    m = run_net(rs, trace(a, c))
    met = bool(monitor(spec, trace(a, c), DT).satisfied[0])
    assert m[0, place(rs, "p_after_")] == met
    assert m[0, place(rs, "p_failed_")] == (not met)
