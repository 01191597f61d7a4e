"""The online monitor says what the offline monitor says about every prefix, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.errors import InputError
from mitlc.monitor.offline import monitor
from mitlc.monitor.online import OnlineMonitor
from mitlc.spec import ast as A
from mitlc.spec.library import shipped_specs
from mitlc.spec.parse import load_spec, parse_formula, parse_spec

try:
    from tests.strategies import formulas, grid_intervals
except ImportError:  # tests/ itself is on sys.path
    from strategies import formulas, grid_intervals  # type: ignore[no-redef]

ABC = parse_spec("prop a = x > 0\nprop b = y > 0\nprop c = z > 0\nformula a\n")
VALUES = np.array([-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0])


def _every_prefix(spec, f, X: np.ndarray, dt: float, cols: tuple[str, ...]) -> OnlineMonitor:
    """Feed ``X`` (R, N, n) sample by sample; after each, compare with the offline monitor."""
    R, n, _ = X.shape
    mon = OnlineMonitor(spec, dt, f, runs=R)
    for k in range(n):
        got = mon.update(X[:, k])
        ref = monitor(spec, {c: X[:, : k + 1, i] for i, c in enumerate(cols)}, dt, f)
        assert got.satisfied.tolist() == ref.satisfied.tolist(), (str(f), k)
        assert got.robustness.tolist() == ref.robustness.tolist(), (str(f), k)
    return mon


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    f=formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 8), max_leaves=10),
    n=st.integers(1, 60),
    seed=st.integers(0, 2**32 - 1),
)
def test_every_prefix_as_offline(f: A.Formula, n: int, seed: int) -> None:
    """Random formulas of every node type (windows up to 8 s at 0.5 s, so traces of 60 samples
    seal many values) on three runs at once."""
    X = np.random.default_rng(seed).choice(VALUES, size=(3, n, 3))
    _every_prefix(ABC, f, X, 0.5, ("x", "y", "z"))


@pytest.mark.parametrize("name", sorted(n for n in shipped_specs() if n.startswith("pendulum/")))
def test_shipped_specs_every_prefix(name: str) -> None:
    """The shipped pendulum specs (formula and check lines) on random-walk traces past every horizon."""
    spec = load_spec(name)
    dt = float(spec.param("dt"))
    n = int(round(spec.horizon / dt)) + 1 if spec.horizon else 200
    rng = np.random.default_rng(7)
    q = np.cumsum(rng.normal(0, 0.25, (2, n)), axis=1) + rng.uniform(-3, 3, (2, 1))
    qdot = rng.normal(0, 3, (2, n))
    X = np.stack([q, qdot], axis=2)
    for f in {spec.formula, spec.monitor_formula} - {None}:
        mon = _every_prefix(spec, f, X, dt, spec.plant.state_names)
        assert mon.k == n - 1


@pytest.mark.parametrize(
    ("text", "constant"),
    [
        ("F G a", True),  # P1: unbounded over unbounded, monotone
        ("G F a & G !b", True),
        ("F[0,2] G a", True),
        ("G (a -> F[0,1] b)", True),
        ("a U b", True),
        ("G[0,1] F[1,2] a", True),
        ("a U G b", False),  # an unbounded until over an unbounded operand
        ("F (G a & true)", True),  # a constant side keeps the other's monotony
        ("F G[0,1] G a", True),  # a bounded window of a monotone signal is monotone: its value at one end
        ("G F[0,1] F a", True),
        ("G (a U b)", False),  # an unbounded G over a non-monotone unbounded until
        ("F (a & G b)", False),
    ],
)
def test_constant_time_says_which_parts_are_read_again(text: str, constant: bool) -> None:
    f = parse_formula(text)
    mon = OnlineMonitor(ABC, 0.5, f)
    assert mon.constant_time is constant
    X = np.random.default_rng(1).choice(VALUES, size=(1, 40, 3))
    for k in range(40):
        mon.update(X[:, k])
    assert mon._bool.growing is (not constant)


def test_bounded_formula_is_final_after_its_horizon() -> None:
    """G[0,1] a at 0.5 s reads 3 samples: later samples change nothing and cost nothing."""
    mon = OnlineMonitor(ABC, 0.5, parse_formula("G[0,1] a"))
    for x in (1.0, 2.0, 0.5):
        mon.update([x, 0.0, 0.0])
    assert mon.satisfied.tolist() == [True] and mon.robustness.tolist() == [0.5]
    for _ in range(50):
        mon.update([-5.0, 0.0, 0.0])
    assert mon.satisfied.tolist() == [True] and mon.robustness.tolist() == [0.5]
    assert not mon._bool.memo  # answered from the final values alone


def test_by_hand() -> None:
    """F G a on a prefix is its last sample; a U b waits for b with a holding."""
    mon = OnlineMonitor(ABC, 0.5, parse_formula("F G a"))
    seen = [float(mon.update([x, 0, 0]).robustness[0]) for x in (1.0, -1.0, 2.0, 0.5)]
    assert seen == [1.0, -1.0, 2.0, 0.5]
    mon = OnlineMonitor(ABC, 0.5, parse_formula("a U b"))
    seen = [bool(mon.update([x, y, 0]).satisfied[0]) for x, y in ((1, -1), (1, -1), (1, 1), (-1, -1))]
    assert seen == [False, False, True, True]


def test_periodic_angles_wrap_and_reset_forgets() -> None:
    spec = parse_spec("plant pendulum\nprop up = abs(q) < 0.3\nformula G up\n")
    mon = OnlineMonitor(spec, 0.05)
    assert bool(mon.update([2 * math.pi + 0.1, 0.0]).satisfied[0])  # 2 pi + 0.1 is 0.1
    assert not bool(mon.update([1.0, 0.0]).satisfied[0])
    mon.reset()
    assert mon.k == -1 and bool(mon.update({"q": [0.0], "qdot": [1.0]}).satisfied[0])


@pytest.mark.parametrize(
    ("sample", "message"),
    [
        ([1.0, 2.0], "must have shape (1, 3)"),
        ([[1.0, 2.0, math.nan]], "'z' is not finite"),
        ({"x": [1.0]}, "no values for state variable"),
        ({"x": [1.0, 2.0], "y": [0.0], "z": [0.0]}, "one per run"),
    ],
)
def test_bad_samples(sample, message: str) -> None:
    mon = OnlineMonitor(ABC, 0.5, parse_formula("a U (b & c)"))
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        mon.update(sample)


@pytest.mark.parametrize(("dt", "runs"), [(0.0, 1), (math.inf, 1), ("x", 1), (0.5, 0)])
def test_bad_settings(dt, runs) -> None:
    with pytest.raises(InputError):
        OnlineMonitor(ABC, dt, runs=runs)


@pytest.mark.parametrize(
    "text",
    [
        # unbounded F, G over bounded operands, windows starting later than t (the running aggregate)
        "F[1,inf) G[0,1] a",
        "G[1.5,inf) F[0,1] a",
        "F[0,inf) (a & F[0.5,1] b)",
        # unbounded until over bounded operands (the running until), with and without a late start
        "a U[1,inf) b",
        "F[0,1] a U[1.5,inf) G[0,0.5] b",
        "(a | b) U[0,inf) F[0.5,1] c",
        "a R[1,inf) G[0,1] b",
        # bounded windows over unbounded operands, starting later than t
        "F[1,2] G a",
        "G[1,2.5] F b",
        "F[0.5,2] (a U b)",
        "a U[1,2] G b",
        # a running until asked for a window that ends before the prefix does
        "F[0,2] (a U F[0,3] b)",
        "G[0,1.5] (a U[0.5,inf) G[0,2] b)",
        # unbounded over unbounded, monotone (one end of the window) and not (the prefix again)
        "F[1,inf) G a",
        "G[1,inf) F a",
        "F[1,inf) (G a & F b)",
        "G[0.5,inf) (F a | G b)",
        "G (a U[1,inf) b)",
        "F[1,inf) (a U G b)",
        # windows that start past a short prefix, constants in the operands
        "F[3,inf) a",
        "G[2,inf) (true & F[0,1] a)",
        "F[1,inf) (false | G[0,1] b)",
    ],
)
@pytest.mark.parametrize("seed", range(4))
def test_each_evaluation_path_every_prefix(text: str, seed: int) -> None:
    """Every path of the online evaluation (running aggregates, running untils, bounded windows
    over unbounded operands, monotone ends, the prefix read again), with windows that start
    later than their sample, on four runs of 30 samples: every prefix as the offline monitor."""
    X = np.random.default_rng(seed).choice(VALUES, size=(4, 30, 3))
    _every_prefix(ABC, parse_formula(text), X, 0.5, ("x", "y", "z"))


def test_a_bad_sample_is_named_by_its_run_and_index() -> None:
    """Two good samples, then run 1's x is nan: sample 2 of run 1, and the monitor keeps what it had."""
    mon = OnlineMonitor(ABC, 0.5, parse_formula("F a"), runs=2)
    mon.update(np.zeros((2, 3)))
    mon.update(np.ones((2, 3)))
    with pytest.raises(InputError, match=r"state variable 'x' is not finite \(run 1, sample 2: nan\)"):
        mon.update([[0.0, 0.0, 0.0], [math.nan, 0.0, 0.0]])
    assert mon.k == 1 and mon.satisfied.tolist() == [True, True]
