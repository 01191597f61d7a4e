"""The one-run offline monitor on Python numbers (mitlc.monitor.scalar_offline) says what the
offline monitor says about a whole trace: the verdict, the robustness, the violation time and
the failing part, the same floats (bit for bit but for the sign of a zero, which numpy's
maximum and minimum pick as their SIMD loops do)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.monitor.offline import monitor
from mitlc.monitor.scalar import ScalarOnlineMonitor, _pred, _pred_compiled
from mitlc.monitor.scalar_offline import ScalarTraceMonitor
from mitlc.spec import ast as A
from mitlc.spec import predicates as P
from mitlc.spec.library import shipped_specs
from mitlc.spec.parse import load_spec, parse_spec

try:
    from tests.strategies import formulas, grid_intervals, intervals
except ImportError:  # tests/ itself is on sys.path
    from strategies import formulas, grid_intervals, intervals  # type: ignore[no-redef]

ABC = parse_spec("prop a = x > 0\nprop b = y > 0\nprop c = z > 0\nformula a\n")
VALUES = [-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0]
MIXED = parse_spec(
    """
prop a = x > 0 and not y == 0.5
prop b = -1 <= y < z or x != 1
prop c = sin(x) * 2 >= y / 3 or sqrt(z) <= exp(x) - 1
formula a
"""
)


def _bits(v: float) -> bytes:
    """A float's bits, a zero's sign left out (see the module's docstring)."""
    return np.float64(v if v else 0.0).tobytes()


def _same(spec, f, X: np.ndarray, dt: float, cols: tuple[str, ...] = ("x", "y", "z")) -> None:
    """The scalar trace monitor's verdict of the run ``X`` (N, n) is the offline monitor's, to the bit."""
    got = ScalarTraceMonitor(spec, dt, f, columns=cols).judge(X.tolist())
    ref = monitor(spec, {c: X[None, :, i] for i, c in enumerate(cols)}, dt, f)
    violation = float(ref.violation_time[0])
    want = (
        bool(ref.satisfied[0]),
        float(ref.robustness[0]),
        None if math.isnan(violation) else violation,
        ref.failing[0],
    )
    assert got[0] == want[0] and got[3] == want[3], (str(f), got, want)
    assert _bits(got[1]) == _bits(want[1]), (str(f), got, want)
    assert (got[2] is None) == (want[2] is None) and (got[2] is None or _bits(got[2]) == _bits(want[2])), (
        str(f),
        got,
        want,
    )


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    f=formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 8), max_leaves=10),
    n=st.integers(1, 60),
    seed=st.integers(0, 2**32 - 1),
)
def test_as_offline_on_the_grid(f: A.Formula, n: int, seed: int) -> None:
    """Random formulas of every node type (windows up to 8 s at 0.5 s) on random traces with ties."""
    _same(ABC, f, np.random.default_rng(seed).choice(VALUES, size=(n, 3)), 0.5)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    f=formulas(atoms=("a", "b", "c"), interval=intervals(), max_leaves=8),
    n=st.integers(1, 40),
    dt=st.sampled_from([0.05, 0.3, 1.0, 2.5]),
    seed=st.integers(0, 2**32 - 1),
)
def test_as_offline_off_the_grid(f: A.Formula, n: int, dt: float, seed: int) -> None:
    """Intervals of any ends (open, closed, unbounded, empty of samples) at several sample times."""
    _same(ABC, f, np.random.default_rng(seed).choice(VALUES, size=(n, 3)), dt)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    f=formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 4), max_leaves=6),
    n=st.integers(1, 30),
    seed=st.integers(0, 2**32 - 1),
)
def test_propositions_as_offline(f: A.Formula, n: int, seed: int) -> None:
    """Propositions of every comparison and numpy function on real-valued samples."""
    rng = np.random.default_rng(seed)
    X = np.where(rng.random((n, 3)) < 0.3, rng.choice([0.5, 1.0, 0.0, -1.0], (n, 3)), rng.normal(0, 2, (n, 3)))
    _same(MIXED, f, X, 0.5)


@pytest.mark.parametrize("name", sorted(n for n in shipped_specs() if n.startswith("pendulum/")))
def test_shipped_specs(name: str) -> None:
    """The shipped pendulum specs on random walks past their horizons, angles far outside [-pi, pi)."""
    spec = load_spec(name)
    cols = spec.plant.state_names
    rng = np.random.default_rng(7)
    for n in (1, 2, 17, 90):
        for _ in range(8):
            X = np.cumsum(rng.normal(0, 0.8, (n, len(cols))), axis=0) + rng.normal(0, 4, len(cols))
            _same(spec, None, X, 0.05, cols)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    f=formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 6), max_leaves=8),
    n=st.integers(1, 40),
    seed=st.integers(0, 2**32 - 1),
)
def test_from_the_online_monitors_signals(f: A.Formula, n: int, seed: int) -> None:
    """judge_signals on the propositions' signals the one-run online monitor kept is judge on the rows."""
    X = np.random.default_rng(seed).choice(VALUES, size=(n, 3)).tolist()
    online = ScalarOnlineMonitor(ABC, 0.5, f)
    for x in X:
        online.update(x)
    mon = ScalarTraceMonitor(ABC, 0.5, f)
    truth, rob = online.signals()
    if not set(mon.names) <= set(truth):  # a proposition the online monitor's core formula left out
        return
    got = mon.judge_signals(truth, rob, n)
    want = mon.judge(X)
    assert got[0] == want[0] and got[2:] == want[2:] and _bits(got[1]) == _bits(want[1])


_TERMS = st.one_of(
    st.sampled_from(["x", "y", "z"]).map(P.Var),
    st.sampled_from([0.0, 0.5, -1.0, 3.0, math.inf]).map(P.Num),
)
_ARITH = st.recursive(
    _TERMS,
    lambda c: st.one_of(
        st.builds(P.BinOp, st.sampled_from(["+", "-", "*", "/"]), c, c),
        c.map(P.Neg),
        st.builds(lambda fn, a: P.Call(fn, (a,)), st.sampled_from(["abs", "sqrt", "sin", "cos", "tan", "exp"]), c),
        st.builds(lambda fn, a, b: P.Call(fn, (a, b)), st.sampled_from(["min", "max", "atan2"]), c, c),
    ),
    max_leaves=4,
)
_CMP = st.builds(
    lambda ops, terms: P.Compare(tuple(terms[: len(ops) + 1]), tuple(ops)),
    st.lists(st.sampled_from(["<", "<=", ">", ">=", "==", "!="]), min_size=1, max_size=3),
    st.lists(_ARITH, min_size=4, max_size=4),
)
_BOOL = st.recursive(
    _CMP, lambda c: st.one_of(c.map(P.PNot), st.builds(P.PAnd, c, c), st.builds(P.POr, c, c)), max_leaves=4
)
_VALUE = st.one_of(st.sampled_from([0.0, -0.0, 0.5, 1.0, -1.0, 3.0, math.inf, -math.inf, math.nan]), st.floats())


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_BOOL, st.lists(st.tuples(_VALUE, _VALUE, _VALUE), min_size=1, max_size=5))
def test_generated_predicates_are_the_closures(pred: P.Pred, samples: list) -> None:
    """A proposition as one generated function gives the closures' truth and robustness, to the bit
    (every operation and function, chains, and/or/not, nan, infinities and signed zeros)."""
    columns = {"x": 0, "y": 1, "z": 2}
    fast, ref = _pred_compiled(pred, columns), _pred(pred, columns)
    with np.errstate(all="ignore"):
        for x in samples:
            (ta, ra), (tb, rb) = fast(list(x)), ref(list(x))
            assert ta is tb or (ta == tb and type(ta) is type(tb)), (str(pred), x)
            assert np.float64(ra).tobytes() == np.float64(rb).tobytes(), (str(pred), x, ra, rb)
