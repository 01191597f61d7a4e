"""The averaged robustness (mitlc.monitor.offline.mean_robustness), the policy search's score of a
violated rollout: hand-computed values, and a brute-force evaluation of its definition on random
formulas and traces (every G's window minimum replaced by the window's mean, everything else as the
robustness)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.monitor.offline import MEAN_BOUND, mean_robustness, monitor, window_mean
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_formula, parse_spec

try:
    from tests.strategies import formulas, grid_intervals
except ImportError:  # tests/ itself is on sys.path (pytest's rootdir-less import)
    from strategies import formulas, grid_intervals  # type: ignore[no-redef]

ABC = parse_spec(
    """
prop a = x > 0
prop b = y > 0
prop c = z > 0
formula a
"""
)


def _clip(v: float) -> float:
    return min(max(v, -MEAN_BOUND), MEAN_BOUND)


def reference(f: A.Formula, rho: dict[str, list[float]], dt: float, n: int):
    """The definition sample by sample, O(N^2) per operator: {(node, k): averaged robustness}."""
    memo: dict = {}

    def window(interval: A.Interval, k: int) -> list[int]:
        return [j for j in range(n - k) if interval.contains(j * dt)]

    def mean(g: A.Formula, interval: A.Interval, k: int) -> float:
        vals = [_clip(ev(g, k + j)) for j in window(interval, k)]
        return sum(vals) / len(vals) if vals else math.inf

    def until(g: A.Until | A.WeakUntil, k: int) -> float:
        rob, left = -math.inf, math.inf  # left's minimum over [k, k + j)
        for j in range(n - k):
            if g.interval.contains(j * dt):
                rob = max(rob, min(ev(g.right, k + j), left))
            left = min(left, ev(g.left, k + j))
        return rob

    def ev(g: A.Formula, k: int) -> float:
        key = (g, k)
        if key in memo:
            return memo[key]
        if isinstance(g, A.Const):
            out = math.inf if g.value else -math.inf
        elif isinstance(g, A.Atom):
            out = rho[g.name][k]
        elif isinstance(g, A.Not):
            out = -ev(g.child, k)
        elif isinstance(g, A.Weighted):
            out = ev(g.child, k)
        elif isinstance(g, A.And):
            out = min(ev(g.left, k), ev(g.right, k))
        elif isinstance(g, A.Or):
            out = max(ev(g.left, k), ev(g.right, k))
        elif isinstance(g, A.Implies):
            out = max(-ev(g.left, k), ev(g.right, k))
        elif isinstance(g, A.Iff):
            a, b = ev(g.left, k), ev(g.right, k)
            out = min(max(-a, b), max(a, -b))
        elif isinstance(g, A.Eventually):
            out = max((ev(g.child, k + j) for j in window(g.interval, k)), default=-math.inf)
        elif isinstance(g, A.Globally):
            out = mean(g.child, g.interval, k)
        elif isinstance(g, A.Until):
            out = until(g, k)
        elif isinstance(g, A.WeakUntil):
            upto = A.Interval(0, g.interval.hi, True, g.interval.hi_closed)
            out = max(until(g, k), mean(g.left, upto, k))
        elif isinstance(g, A.Release):  # not (not a U not b)
            rob, left = math.inf, -math.inf
            for j in range(n - k):
                if g.interval.contains(j * dt):
                    rob = min(rob, max(ev(g.right, k + j), left))
                left = max(left, ev(g.left, k + j))
            out = rob
        else:  # pragma: no cover
            raise TypeError(g)
        memo[key] = out
        return out

    return ev


VALUES = st.sampled_from([-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 0.3])


@st.composite
def traces(draw, min_len: int = 1, max_len: int = 14):
    n = draw(st.integers(min_len, max_len))
    return {name: draw(st.lists(VALUES, min_size=n, max_size=n)) for name in ("x", "y", "z")}


SMALL = formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 6), max_leaves=6)


def _same(got: float, want: float) -> bool:
    if math.isinf(want):
        return got == want
    return math.isclose(got, want, rel_tol=1e-9, abs_tol=1e-9 * MEAN_BOUND * 1e-6)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(f=SMALL, sig=traces(), dt=st.sampled_from([0.5, 0.25, 1.0]))
def test_equals_the_definition(f: A.Formula, sig: dict[str, list[float]], dt: float) -> None:
    n = len(sig["x"])
    ref = reference(f, {"a": sig["x"], "b": sig["y"], "c": sig["z"]}, dt, n)
    states = {k: np.array(v) for k, v in sig.items()}
    got = mean_robustness(ABC, states, dt, f)
    assert got.shape == (1,)
    assert _same(float(got[0]), ref(f, 0)), (str(f), float(got[0]), ref(f, 0))
    res = monitor(ABC, states, dt, f, blame=False, mean=True)
    assert res.mean_robustness is not None and res.mean_robustness.tolist() == got.tolist()


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(f=formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 6), max_leaves=6, constants=False), sig=traces())
def test_without_g_it_is_the_robustness(f: A.Formula, sig: dict[str, list[float]]) -> None:
    """A formula with no G (nor the G part of a W) has the robustness itself as its averaged robustness."""
    if any(isinstance(g, (A.Globally, A.WeakUntil)) for g in A.walk(f)):
        return
    states = {k: np.array(v) for k, v in sig.items()}
    assert mean_robustness(ABC, states, 0.5, f).tolist() == monitor(ABC, states, 0.5, f).robustness.tolist()


def test_hand_computed() -> None:
    # x over 5 samples at dt = 1: a's robustness is x itself
    x = np.array([[-3.0, 1.0, 2.0, -1.0, 4.0], [1.0, 1.0, 1.0, 1.0, 1.0]])
    states = {"x": x, "y": np.zeros_like(x), "z": np.zeros_like(x)}
    assert mean_robustness(ABC, states, 1.0, parse_formula("G a")).tolist() == [0.6, 1.0]  # (−3+1+2−1+4)/5
    assert mean_robustness(ABC, states, 1.0, parse_formula("G[1,2] a")).tolist() == [1.5, 1.0]
    # F takes the best of its window's means: from samples 0, 1, 2 to the end 0.6, 1.5 and 5/3
    assert mean_robustness(ABC, states, 1.0, parse_formula("F[0,2] G a")).tolist() == [5 / 3, 1.0]
    # the robustness takes the worst sample: -3 and 1
    assert monitor(ABC, states, 1.0, parse_formula("G a")).robustness.tolist() == [-3.0, 1.0]
    # G past the trace's end: the empty window's identity, as the robustness's
    assert mean_robustness(ABC, states, 1.0, parse_formula("G[9,10] a")).tolist() == [math.inf, math.inf]


def test_window_mean() -> None:
    x = np.array([[1.0, 2.0, 3.0, 4.0, 5.0]])
    assert window_mean(x, 0, 1).tolist() == [[1.5, 2.5, 3.5, 4.5, 5.0]]
    assert window_mean(x, 2, math.inf).tolist() == [[4.0, 4.5, 5.0, math.inf, math.inf]]
    assert window_mean(np.array([[np.inf, 0.0]]), 0, 1).tolist() == [[MEAN_BOUND / 2, 0.0]]


def test_swing_up_scores_above_staying_down() -> None:
    """The reason for the score: a pendulum that reaches the top and falls back, and one that stays at
    the bottom, have the same robustness for 'F[0,2] G up' (the worst sample) and different averages."""
    spec = parse_spec("prop up = abs(q) < 0.2\nformula F[0,2] G up")
    t = np.arange(0, 4.01, 0.5)
    down = np.full_like(t, np.pi)
    visit = np.where((t >= 1.5) & (t <= 3.0), 0.0, np.pi)
    q = np.stack([down, visit])
    rob = monitor(spec, {"q": q}, 0.5).robustness
    assert rob[0] == pytest.approx(rob[1])
    avg = mean_robustness(spec, {"q": q}, 0.5)
    assert avg[1] > avg[0]
