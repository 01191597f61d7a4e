"""The one-run online monitor on Python numbers says what the offline monitor says about every
prefix, bit for bit, as the array online monitor does (tests/test_online.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.errors import InputError
from mitlc.monitor.offline import monitor
from mitlc.monitor.online import OnlineMonitor
from mitlc.monitor.scalar import ScalarOnlineMonitor
from mitlc.spec import ast as A
from mitlc.spec.library import shipped_specs
from mitlc.spec.parse import load_spec, parse_formula, parse_spec

try:
    from tests.strategies import formulas, grid_intervals
except ImportError:  # tests/ itself is on sys.path
    from strategies import formulas, grid_intervals  # type: ignore[no-redef]

ABC = parse_spec("prop a = x > 0\nprop b = y > 0\nprop c = z > 0\nformula a\n")
VALUES = [-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0]
# every comparison, chains, and/or/not inside a proposition, functions numpy computes
MIXED = parse_spec(
    """
prop a = x > 0 and not y == 0.5
prop b = -1 <= y < z or x != 1
prop c = sin(x) * 2 >= y / 3 or sqrt(z) <= exp(x) - 1
formula a
"""
)


def _every_prefix(spec, f, X: np.ndarray, dt: float, cols: tuple[str, ...]) -> ScalarOnlineMonitor:
    """Feed one run ``X`` (N, n) sample by sample; after each, compare with the offline monitor."""
    mon = ScalarOnlineMonitor(spec, dt, f)
    for k in range(X.shape[0]):
        got = mon.update([float(v) for v in X[k]])
        ref = monitor(spec, {c: X[None, : k + 1, i] for i, c in enumerate(cols)}, dt, f)
        assert got == (bool(ref.satisfied[0]), float(ref.robustness[0])), (str(f), k)
        assert (mon.satisfied, mon.robustness) == got
    return mon


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    f=formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 8), max_leaves=10),
    n=st.integers(1, 60),
    seed=st.integers(0, 2**32 - 1),
)
def test_every_prefix_as_offline(f: A.Formula, n: int, seed: int) -> None:
    """Random formulas of every node type (windows up to 8 s at 0.5 s) on random traces."""
    X = np.random.default_rng(seed).choice(VALUES, size=(n, 3))
    _every_prefix(ABC, f, X, 0.5, ("x", "y", "z"))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    f=formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 4), max_leaves=6),
    n=st.integers(1, 30),
    seed=st.integers(0, 2**32 - 1),
)
def test_propositions_as_offline(f: A.Formula, n: int, seed: int) -> None:
    """Propositions of every comparison and numpy function, on real-valued samples: the robustness
    of an atom is the same float (nan margins read as 0, as the offline monitor reads them)."""
    rng = np.random.default_rng(seed)
    X = np.where(rng.random((n, 3)) < 0.3, rng.choice([0.5, 1.0, 0.0, -1.0], (n, 3)), rng.normal(0, 2, (n, 3)))
    _every_prefix(MIXED, f, X, 0.5, ("x", "y", "z"))


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    f=formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 6), max_leaves=8),
    n=st.integers(1, 40),
    seed=st.integers(0, 2**32 - 1),
)
def test_as_the_array_online_monitor(f: A.Formula, n: int, seed: int) -> None:
    """The same verdict, robustness and ``constant_time`` as :class:`OnlineMonitor` of one run."""
    X = np.random.default_rng(seed).choice(VALUES, size=(n, 3))
    one, arr = ScalarOnlineMonitor(ABC, 0.5, f), OnlineMonitor(ABC, 0.5, f)
    assert one.constant_time is arr.constant_time
    for k in range(n):
        v = arr.update(X[k])
        assert one.update(list(X[k])) == (bool(v.satisfied[0]), float(v.robustness[0])), (str(f), k)


@pytest.mark.parametrize("name", sorted(n for n in shipped_specs() if n.startswith("pendulum/")))
def test_shipped_specs_every_prefix(name: str) -> None:
    """The shipped pendulum specs (formula and check lines) on random walks past every horizon,
    angles unwrapped (the monitor wraps them as the offline one does)."""
    spec = load_spec(name)
    dt = float(spec.param("dt"))
    n = int(round(spec.horizon / dt)) + 1 if spec.horizon else 120
    rng = np.random.default_rng(11)
    q = np.cumsum(rng.normal(0, 0.25, n)) + rng.uniform(-9, 9)
    X = np.stack([q, rng.normal(0, 3, n)], axis=1)
    for f in {spec.formula, spec.monitor_formula} - {None}:
        mon = _every_prefix(spec, f, X, dt, spec.plant.state_names)
        assert mon.k == n - 1


def test_reset_forgets_and_columns_are_named() -> None:
    mon = ScalarOnlineMonitor(ABC, 0.5, parse_formula("F G a"), columns=("z", "y", "x"))
    assert [mon.update([0.0, 0.0, x])[1] for x in (1.0, -1.0, 2.0)] == [1.0, -1.0, 2.0]
    mon.reset()
    assert mon.k == -1 and mon.update([0.0, 0.0, -3.0]) == (False, -3.0)


@pytest.mark.parametrize(
    ("sample", "message"),
    [
        ([1.0, 2.0], "a sample must have 3 values (x, y, z), got 2"),
        ([1.0, math.nan, 0.0], "state variable 'y' is not finite (sample 0: nan)"),
    ],
)
def test_bad_samples(sample: list[float], message: str) -> None:
    mon = ScalarOnlineMonitor(ABC, 0.5, parse_formula("a U (b & c)"))
    with pytest.raises(InputError) as e:
        mon.update(sample)
    assert e.value.message == message


def test_a_column_missing_is_one_line() -> None:
    with pytest.raises(InputError) as e:
        ScalarOnlineMonitor(ABC, 0.5, parse_formula("a U b"), columns=("x", "z"))
    assert e.value.message == "no column for state variable y"
