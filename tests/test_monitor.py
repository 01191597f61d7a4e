"""The MITL monitor: hand-made traces per operator, the thesis's five specs,
a brute-force reference on random formulas, the formula round trip, and
``mitlc check`` through click's CliRunner."""

from __future__ import annotations

import json
import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.cli import main
from mitlc.errors import CompileError, InputError, SpecError
from mitlc.monitor.offline import MonitorResult, monitor, offsets, signals, state_columns
from mitlc.plants.base import wrap_angle
from mitlc.spec import ast as A
from mitlc.spec.parse import load_spec, parse_formula, parse_spec

try:
    from tests.strategies import formulas, grid_intervals, state_formulas
except ImportError:  # tests/ itself is on sys.path (pytest's rootdir-less import)
    from strategies import formulas, grid_intervals, state_formulas  # type: ignore[no-redef]

ROOT = Path(__file__).resolve().parent.parent
PI = math.pi

# Three propositions whose robustness is the signal itself: rho(a) = x - 0 = x.
ABC = parse_spec(
    """
prop a = x > 0
prop b = y > 0
prop c = z > 0
formula a
"""
)


def run(text: str, dt: float = 0.5, **sig: list[float]) -> MonitorResult:
    """Monitor formula ``text`` over the ABC spec; keyword args give x, y, z."""
    states = {name: np.array(values, dtype=float) for name, values in sig.items()}
    n = len(next(iter(states.values())))
    for name in ("x", "y", "z"):
        states.setdefault(name, np.zeros(n))
    return monitor(ABC, states, dt, parse_formula(text))


def verdict(text: str, dt: float = 0.5, **sig: list[float]) -> tuple[bool, float]:
    res = run(text, dt, **sig)
    return bool(res.satisfied[0]), float(res.robustness[0])


# ------------------------------------------------------------ interval offsets


@pytest.mark.parametrize(
    "text, dt, expected",
    [
        ("[0,1]", 0.5, (0, 2)),
        ("[0,1)", 0.5, (0, 1)),
        ("(0,1]", 0.5, (1, 2)),
        ("(1,2]", 0.5, (3, 4)),
        ("(0.5,1)", 0.5, (2, 1)),  # no sample offset inside
        ("[1,1]", 0.5, (2, 2)),
        ("[0.3,0.6]", 0.1, (3, 6)),  # 0.3/0.1 is 2.9999999999999996 in floats
        ("(0.3,0.6)", 0.1, (4, 5)),
        ("[0.1,0.2]", 0.03, (4, 6)),
        ("[2,inf)", 0.03, (67, math.inf)),
        ("(2,inf)", 0.5, (5, math.inf)),
    ],
)
def test_offsets(text: str, dt: float, expected: tuple[int, float]) -> None:
    f = parse_formula(f"F{text} a")
    assert offsets(f.interval, dt) == expected


# ------------------------------------------------------------ operators, by hand
# dt = 0.5 throughout: samples at 0, 0.5, 1, 1.5, 2; interval ends fall exactly on them.

F_TRACE = [-1.0, -2.0, 3.0, -4.0, -5.0]
G_TRACE = [1.0, 2.0, -3.0, 4.0, 5.0]


@pytest.mark.parametrize(
    "text, sat, rob",
    [
        ("F[0,1] a", True, 3.0),
        ("F[0,1) a", False, -1.0),  # t = 1 excluded
        ("F(1,2] a", False, -4.0),  # t = 1 excluded
        ("F[1,2] a", True, 3.0),
        ("F(0,1] a", True, 3.0),
        ("F(0.5,1) a", False, -math.inf),  # no sample inside
        ("F[1,1] a", True, 3.0),
        ("F[3,4] a", False, -math.inf),  # after the trace: strong
        ("F[1.5,9] a", False, -4.0),  # window cut at the end of the trace
        ("F a", True, 3.0),
    ],
)
def test_eventually(text: str, sat: bool, rob: float) -> None:
    assert verdict(text, x=F_TRACE) == (sat, rob)


@pytest.mark.parametrize(
    "text, sat, rob",
    [
        ("G[0,1] a", False, -3.0),
        ("G[0,1) a", True, 1.0),
        ("G(1,2] a", True, 4.0),
        ("G[1,2] a", False, -3.0),
        ("G(0.5,1) a", True, math.inf),  # no sample inside: vacuous
        ("G[3,4] a", True, math.inf),  # after the trace: weak
        ("G(1,9] a", True, 4.0),
        ("G a", False, -3.0),
    ],
)
def test_globally(text: str, sat: bool, rob: float) -> None:
    assert verdict(text, x=G_TRACE) == (sat, rob)


def test_globally_violation_time_and_failing() -> None:
    res = run("G[0,1] a", x=G_TRACE)
    assert res.violation_time[0] == 1.0 and res.failing == ("a",)
    res = run("F[0,1) a", x=F_TRACE)
    assert res.violation_time[0] == 0.5 and res.failing == ("F[0,1) a",)
    res = run("F[1.5,9] a", x=F_TRACE)  # decided at the last sample
    assert res.violation_time[0] == 2.0
    res = run("F[3,4] a", x=F_TRACE)  # decided by the trace length alone
    assert res.violation_time[0] == 0.0
    assert math.isnan(run("G a", x=[1.0, 1.0]).violation_time[0])


UA = [1.0, 1.0, 1.0, -1.0, 1.0]
UB = [-1.0, -1.0, 2.0, 3.0, -1.0]


@pytest.mark.parametrize(
    "text, sat, rob",
    [
        # j = 2: min(b2, a0, a1) = 1; j = 3: min(3, a0..a2) = 1; j = 4: min(-1, a3 = -1)
        ("a U[1,2] b", True, 1.0),
        ("a U(1,2] b", True, 1.0),
        ("a U(1.5,2] b", False, -1.0),
        ("a U b", True, 1.0),
        ("a U[0,0.5] b", False, -1.0),
        ("a U[0,1) b", False, -1.0),
        ("a U[1,1] b", True, 1.0),
        ("a U[3,9] b", False, -math.inf),
        ("true U[1,2] b", True, 3.0),  # F[1,2] b
    ],
)
def test_until(text: str, sat: bool, rob: float) -> None:
    assert verdict(text, x=UA, y=UB) == (sat, rob)


def test_until_needs_left_only_before_the_witness() -> None:
    # b at t = 1 and a false from t = 1 on: a holds on [0, 1), which is enough
    assert verdict("a U[1,1] b", x=[2.0, 2.0, -5.0], y=[-1.0, -1.0, 4.0]) == (True, 2.0)
    # ... but not for a witness at t = 0.5 <= the failure of a
    assert verdict("a U[0,0.5] b", x=[-5.0, 2.0], y=[-1.0, 4.0]) == (False, -1.0)


def test_until_failing() -> None:
    res = run("a U(1.5,2] b", x=UA, y=UB)  # a fails at 1.5, before b could come at 2
    assert (res.failing, res.violation_time[0]) == (("a",), 1.5)
    res = run("a U[0,0.5] b", x=UA, y=UB)  # the window passes without b
    assert (res.failing, res.violation_time[0]) == (("a U[0,0.5] b",), 0.5)


@pytest.mark.parametrize(
    "text, x, y, sat, rob",
    [
        # min_j max(b_j, max_{i<j} a_i) over j in {0, 1, 2}
        ("a R[0,1] b", [-1.0, 2.0, -1.0], [1.0, -3.0, -2.0], False, -1.0),
        ("a R[0,1] b", [-1.0, 2.0, -1.0], [1.0, 0.5, -2.0], True, 0.5),
        ("a R(0,1] b", [-1.0, 2.0, -1.0], [-9.0, 0.5, -2.0], True, 0.5),
        ("a R b", [-1.0, -1.0, -1.0], [1.0, 2.0, 3.0], True, 1.0),  # weak: G b
        ("false R[0,1] b", [0.0, 0.0, 0.0], [1.0, 2.0, -3.0], False, -3.0),  # G[0,1] b
        ("a R[5,6] b", [-1.0, -1.0, -1.0], [-1.0, -1.0, -1.0], True, math.inf),
    ],
)
def test_release(text: str, x: list[float], y: list[float], sat: bool, rob: float) -> None:
    assert verdict(text, x=x, y=y) == (sat, rob)


def test_release_failing() -> None:
    res = run("a R[0,1] b", x=[-1.0, 2.0, -1.0], y=[1.0, -3.0, -2.0])
    assert (res.failing, res.violation_time[0]) == (("b",), 0.5)


@pytest.mark.parametrize(
    "text, x, y, sat, rob",
    [
        # (a U[0,1] b) | G[0,1] a
        ("a W[0,1] b", [1.0, 2.0, 3.0, -1.0], [-1.0, -1.0, -1.0, -1.0], True, 1.0),
        ("a W[0,1) b", [1.0, 2.0, -3.0, -1.0], [-1.0, -1.0, -1.0, -1.0], True, 1.0),
        ("a W[0,1] b", [1.0, -2.0, 3.0, 1.0], [-1.0, -1.0, -1.0, -1.0], False, -1.0),
        ("a W[0,1] b", [1.0, -2.0, 3.0, 1.0], [-1.0, 0.5, -1.0, -1.0], True, 0.5),
        ("a W b", [1.0, 1.0, 1.0], [-1.0, -1.0, -1.0], True, 1.0),
    ],
)
def test_weak_until(text: str, x: list[float], y: list[float], sat: bool, rob: float) -> None:
    assert verdict(text, x=x, y=y) == (sat, rob)


def test_weak_until_failing() -> None:
    res = run("a W[0,1] b", x=[1.0, -2.0, 3.0, 1.0], y=[-1.0, -1.0, -1.0, -1.0])
    assert (res.failing, res.violation_time[0]) == (("a",), 0.5)


@pytest.mark.parametrize(
    "text, sat, rob, failing",
    [
        ("a", True, 2.0, None),
        ("!a", False, -2.0, "!a"),
        ("a & b", False, -3.0, "b"),
        ("a | b", True, 2.0, None),
        ("!a | b", False, -2.0, "!a | b"),
        ("a -> b", False, -2.0, "b"),
        ("b -> a", True, 3.0, None),
        ("a <-> b", False, -2.0, "a <-> b"),
        ("a <-> !b", True, 2.0, None),
        ("true", True, math.inf, None),
        ("false", False, -math.inf, "false"),
        ("7 * b", False, -3.0, "b"),  # weights change neither truth nor robustness
        ("a & (3 * b | false)", False, -3.0, "3 * b | false"),
    ],
)
def test_boolean(text: str, sat: bool, rob: float, failing: str | None) -> None:
    res = run(text, x=[2.0], y=[-3.0])
    assert (bool(res.satisfied[0]), float(res.robustness[0]), res.failing[0]) == (sat, rob, failing)
    if sat:
        assert math.isnan(res.violation_time[0])
    else:
        assert res.violation_time[0] == 0.0


def test_and_blames_the_earliest_failure() -> None:
    res = run("F[0,1] a & G b", x=[-1.0, -1.0, -1.0, -1.0], y=[1.0, 1.0, 1.0, -1.0])
    assert res.failing == ("F[0,1] a",) and res.violation_time[0] == 1.0
    res = run("F[0,1] a & G b", x=[-1.0, -1.0, -1.0, -1.0], y=[1.0, -1.0, 1.0, -1.0])
    assert res.failing == ("b",) and res.violation_time[0] == 0.5


def test_nested_relative_intervals() -> None:
    # F[1,1] G[0,0.5] a at 0 looks at samples 2 and 3 (t = 1, 1.5): relative reading
    assert verdict("F[1,1] G[0,0.5] a", x=[-1.0, -1.0, 2.0, 3.0, -1.0]) == (True, 2.0)
    assert verdict("F[1,1] G[0,0.5] a", x=[-1.0, -1.0, 2.0, -3.0, 1.0]) == (False, -3.0)


@pytest.mark.parametrize(
    "pred, rob",
    [
        ("x < 1", 1.0 - 0.25),
        ("x <= 1", 1.0 - 0.25),
        ("x > 1", 0.25 - 1.0),
        ("x >= 1", 0.25 - 1.0),
        ("x == 1", -0.75),
        ("x != 1", 0.75),
        ("0 < x < 0.5", 0.25),
        ("0 < x < 0.375", 0.125),
        ("not x < 1", -0.75),
        ("x < 1 and y > 4", -2.0),
        ("x < 1 or y > 4", 0.75),
        ("abs(x - 1) < y", 1.25),
        ("sqrt(x) < 1", 0.5),
    ],
)
def test_predicate_robustness(pred: str, rob: float) -> None:
    spec = parse_spec(f"prop p = {pred}\nformula p")
    res = monitor(spec, {"x": np.array([0.25]), "y": np.array([2.0])}, 1.0)
    assert res.robustness[0] == rob
    assert bool(res.satisfied[0]) == (rob > 0)


def test_boundary_robustness_zero_either_verdict() -> None:
    strict = parse_spec("prop p = x < 1\nformula p")
    weak = parse_spec("prop p = x <= 1\nformula p")
    at = {"x": np.array([1.0])}
    assert (bool(monitor(strict, at, 1.0).satisfied[0]), monitor(strict, at, 1.0).robustness[0]) == (False, 0.0)
    assert (bool(monitor(weak, at, 1.0).satisfied[0]), monitor(weak, at, 1.0).robustness[0]) == (True, 0.0)


def test_not_a_number_in_a_predicate_is_boundary() -> None:
    spec = parse_spec("prop p = sqrt(x) < 1\nformula p")
    res = monitor(spec, {"x": np.array([-1.0])}, 1.0)
    assert (bool(res.satisfied[0]), res.robustness[0]) == (False, 0.0)


# ------------------------------------------------------------ the thesis's five specs
# Pendulum; q is the angle from upright, wrapped to [-pi, pi).

THESIS = {
    "p1": "prop kappa = abs(q) < 0.3\nformula F G kappa",
    "p2": "prop kappa = abs(q) < 0.3\nprop psi = 0.3 < q < pi/2 + 0.5\nformula F G kappa & 10 * G !psi",
    "p3": "prop kappa = abs(q) < 0.3\nprop psi = 0.3 < q < pi/2 + 0.5\nprop upsilon = abs(qdot) < 10\n"
    "formula F G kappa & 10 * G !psi & 10 * G upsilon",
    "p4": "prop kappa = -pi/2 - 0.5 < q < -pi/2 + 0.3\nprop upsilon = pi/2 - 0.3 < q < pi/2 + 0.5\n"
    "prop psi = -pi < q < -pi/2 - 0.5 or pi/2 + 0.5 < q < pi\n"
    "formula 5 * G F kappa & 5 * G F upsilon & 25 * G !psi",
    "p5": "prop kappa = -pi < q < -pi + 0.5 or pi - 0.5 < q < pi\n"
    "formula 2 * !kappa U(1,2] (3 * kappa U(2,inf) G !kappa)\n"
    "check G[0,1] !kappa & F[1,2] kappa & F[2,3] G !kappa",
}


@cache
def thesis(name: str):
    return parse_spec("plant pendulum(u_max = 10)\n" + THESIS[name])


def pend(name: str, q: list[float], qdot: list[float] | None = None, dt: float = 0.5, formula: str | None = None):
    qdot = [0.0] * len(q) if qdot is None else qdot
    states = np.stack([np.array(q), np.array(qdot)], axis=1)  # (N+1, 2), plant order q, qdot
    return monitor(thesis(name), states, dt, None if formula is None else parse_formula(formula))


def W(q: float) -> float:
    """``q`` wrapped to [-pi, pi) as the monitor sees it (may differ from q in the last bit)."""
    return float(wrap_angle(np.array(q)))


def outcome(res: MonitorResult) -> tuple:
    return bool(res.satisfied[0]), float(res.robustness[0]), float(res.violation_time[0]), res.failing[0]


def same(a: tuple, b: tuple) -> bool:
    return all(
        (x == y) or (isinstance(x, float) and math.isnan(x) and math.isnan(y)) for x, y in zip(a, b, strict=True)
    )


@pytest.mark.parametrize("name", sorted(THESIS))
def test_thesis_spec_files_state_the_same(name: str) -> None:
    files = sorted((ROOT / "specs" / "pendulum").glob(f"{name}_*.mitl"))
    if not files:
        pytest.skip("spec file not written yet")
    spec, inline = load_spec(files[0]), thesis(name)
    assert spec.formula == inline.formula
    if inline.check is not None:
        assert spec.check == inline.check
    assert {p.name: p.pred for p in spec.props} == {p.name: p.pred for p in inline.props}
    assert spec.plant_name == "pendulum"


def test_p1() -> None:
    # G kappa holds from t = 1 on; its robustness is then min over q = 0.25, 0.125, -0.25
    assert same(outcome(pend("p1", [3.0, 1.0, 0.25, 0.125, -0.25])), (True, 0.3 - 0.25, math.nan, None))
    # never settles: F G kappa is decided at the last sample
    assert same(outcome(pend("p1", [3.0, 0.25, 0.125, 1.0])), (False, 0.3 - 1.0, 1.5, "F G kappa"))


def test_p1_wraps_the_angle() -> None:
    q = [2 * PI + 0.125, -2 * PI - 0.125]
    res = pend("p1", q)
    assert bool(res.satisfied[0])
    # F G kappa: the best suffix is the last sample alone
    assert res.robustness[0] == 0.3 - abs(float(wrap_angle(np.array(q[1]))))
    assert not pend("p1", [PI + 0.125, PI + 0.125]).satisfied[0]  # wraps to near -pi


def test_p2() -> None:
    q = [3.0, 2.0, 1.0, 0.25, 0.125]
    # kappa settles at t = 1.5; but q = 2 and q = 1 are in psi (0.3 < q < 2.07):
    # the deepest is q = 1, robustness -(1 - 0.3); first entry at t = 0.5
    assert same(outcome(pend("p2", q)), (False, -(1.0 - 0.3), 0.5, "!psi"))
    # swinging up the other way round avoids psi
    q = [3.0, -2.0, -1.0, -0.25, 0.125]
    # the least margins: kappa at q = 0.125, and psi's lower end at q = 0.125 too
    assert same(outcome(pend("p2", q)), (True, 0.3 - 0.125, math.nan, None))


def test_p3() -> None:
    q, qdot = [0.25, 0.125, 0.0, 0.0], [0.0, 12.0, 0.0, 0.0]
    assert same(outcome(pend("p3", q, qdot)), (False, 10.0 - 12.0, 0.5, "upsilon"))
    assert same(outcome(pend("p3", q, [0.0, 9.5, 0.0, 0.0])), (True, 0.3 - 0.25, math.nan, None))


def test_p4_is_unsatisfiable_on_finite_traces() -> None:
    # G F kappa & G F upsilon needs both kappa and upsilon at the last sample
    # (strong F on a finite trace), and they are disjoint.
    q = [-1.6, 1.6, -1.6, 1.6]  # alternating kappa, upsilon, never psi
    rho_kappa_last = (-PI / 2 + 0.3) - W(1.6)
    assert same(outcome(pend("p4", q)), (False, rho_kappa_last, 1.5, "F kappa"))
    rng = np.random.default_rng(4)
    res = monitor(thesis("p4"), rng.uniform(-PI, PI, size=(50, 20, 2)), 0.1)
    assert not res.satisfied.any()


P4_CHECK = "G !psi & F (kappa & F (upsilon & F kappa))"  # what specs/pendulum/p4_alternate.mitl checks


def test_p4_alternation_check() -> None:
    q = [-1.6, 1.6, -1.6]  # kappa, upsilon, kappa: the margins of kappa and upsilon are the least
    rob = min((-PI / 2 + 0.3) - W(-1.6), W(1.6) - (PI / 2 - 0.3))  # q as the plant wraps it
    assert same(outcome(pend("p4", q, formula=P4_CHECK)), (True, rob, math.nan, None))
    q = [-1.6, 1.6, 0.0, 0.0]  # never back to kappa
    assert same(outcome(pend("p4", q, formula=P4_CHECK)), (False, -(PI / 2 - 0.3), 1.5, P4_CHECK[9:]))
    files = sorted((ROOT / "specs" / "pendulum").glob("p4_*.mitl"))
    if files and load_spec(files[0]).check is not None:
        assert str(load_spec(files[0]).check) == P4_CHECK


def test_p5_check() -> None:
    q = [0.0, 1.0, 2.0, 3.0, -3.0, 2.0, 1.0]  # t = 0 .. 3: out, in kappa at 1.5 and 2, out
    # G[0,1] !kappa: -(2 - (pi - 0.5)); F[1,2] kappa: pi - 3; F[2,3] G !kappa: -(2 - (pi - 0.5))
    assert same(outcome(pend("p5", q)), (True, PI - 3.0, math.nan, None))
    late = [0.0, 1.0, 2.0, 2.0, 2.0, 3.0, 1.0]  # kappa only at 2.5 s
    assert same(outcome(pend("p5", late)), (False, 2.0 - (PI - 0.5), 2.0, "F[1,2] kappa"))
    early = [0.0, 3.0, 2.0, 3.0, 1.0, 1.0, 1.0]  # kappa at 0.5 s
    assert same(outcome(pend("p5", early)), (False, -(PI - 3.0), 0.5, "!kappa"))


def test_p5_formula_unsatisfiable_in_three_seconds_under_standard_semantics() -> None:
    q = [0.0, 1.0, 2.0, 3.0, -3.0, 2.0, 1.0]
    res = pend("p5", q, formula=str(thesis("p5").formula))
    # the nested U(2,inf) at t in (1,2] needs a witness after 3 s: none inside the trace
    assert same(outcome(res), (False, -math.inf, 1.5, "!kappa"))
    res = pend("p5", [0.0] * 7, formula=str(thesis("p5").formula))
    assert not res.satisfied[0] and res.robustness[0] == -math.inf


# ------------------------------------------------------------ inputs and API


def test_states_as_array_mapping_and_batch_agree() -> None:
    spec = thesis("p3")
    rng = np.random.default_rng(0)
    x = rng.uniform(-4, 4, size=(5, 11, 2)) * np.array([1.0, 4.0])
    batch = monitor(spec, x, 0.3)
    mapping = monitor(spec, {"q": x[:, :, 0], "qdot": x[:, :, 1]}, 0.3)
    for r in range(5):
        single = monitor(spec, x[r], 0.3)
        assert single.satisfied[0] == batch.satisfied[r] == mapping.satisfied[r]
        assert single.robustness[0] == batch.robustness[r] == mapping.robustness[r]
        assert single.failing[0] == batch.failing[r] == mapping.failing[r]
        assert same((single.violation_time[0],), (batch.violation_time[r],))
    assert state_columns(spec) == ("q", "qdot")


def test_no_plant_columns_are_sorted_names() -> None:
    spec = parse_spec("prop p = y > 0\nprop r = x > 0\nformula G (p & !r)")
    assert state_columns(spec) == ("x", "y")
    res = monitor(spec, np.array([[-1.0, 1.0], [-2.0, 2.0]]), 1.0)
    assert bool(res.satisfied[0]) and res.robustness[0] == 1.0


@pytest.mark.parametrize(
    "states, dt, message",
    [
        (np.zeros((3, 3)), 0.1, "states have 3 columns, expected 2 (q, qdot)"),
        (np.zeros(3), 0.1, "states must have shape"),
        ({"q": np.zeros(3)}, 0.1, "no values for state variable qdot"),
        ({"q": np.zeros(3), "qdot": np.zeros(4)}, 0.1, "different shapes"),
        (np.array([[0.0, np.nan]]), 0.1, "state variable 'qdot' is not finite"),
        (np.zeros((3, 2)), 0.0, "sample time must be positive"),
        (np.zeros((3, 2)), math.nan, "sample time must be positive"),
        (np.zeros((0, 2)), 0.1, "at least one sample"),
    ],
)
def test_bad_states(states, dt: float, message: str) -> None:
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        monitor(thesis("p3"), states, dt)


def test_undefined_proposition_and_unknown_node() -> None:
    with pytest.raises(SpecError, match="undefined proposition 'nope'"):
        monitor(thesis("p1"), np.zeros((2, 2)), 0.1, parse_formula("F nope"))

    class Strange(A.Formula):
        __slots__ = ()

    with pytest.raises(CompileError, match="Strange"):
        monitor(thesis("p1"), np.zeros((2, 2)), 0.1, Strange())
    spec = parse_spec("prop p = x and x > 0\nformula p")
    with pytest.raises(CompileError, match="'x' is a number, not a condition"):
        monitor(spec, {"x": np.zeros(2)}, 0.1)


def test_signals_per_subformula() -> None:
    s = signals(
        ABC, {"x": np.array([-1.0, 2.0, -3.0]), "y": np.zeros(3), "z": np.zeros(3)}, 1.0, parse_formula("G F[0,1] a")
    )
    assert list(s) == ["G F[0,1] a", "F[0,1] a", "a"]
    assert s["F[0,1] a"].tolist() == [[2.0, 2.0, -3.0]]
    assert s["G F[0,1] a"].tolist() == [[-3.0, -3.0, -3.0]]


# ------------------------------------------------------------ brute-force reference


def reference(f: A.Formula, rho: dict[str, list[float]], dt: float, n: int):
    """Direct definition, O(N^2) per operator: {(node, k): (truth, robustness)}."""
    memo: dict = {}

    def window(interval: A.Interval, k: int) -> list[int]:
        return [j for j in range(n - k) if interval.contains(j * dt)]

    def ev(g: A.Formula, k: int) -> tuple[bool, float]:
        key = (g, k)
        if key in memo:
            return memo[key]
        if isinstance(g, A.Const):
            out = (g.value, math.inf if g.value else -math.inf)
        elif isinstance(g, A.Atom):
            out = (rho[g.name][k] > 0, rho[g.name][k])
        elif isinstance(g, A.Not):
            t, r = ev(g.child, k)
            out = (not t, -r)
        elif isinstance(g, A.Weighted):
            out = ev(g.child, k)
        elif isinstance(g, (A.And, A.Or, A.Implies, A.Iff)):
            (ta, ra), (tb, rb) = ev(g.left, k), ev(g.right, k)
            if isinstance(g, A.And):
                out = (ta and tb, min(ra, rb))
            elif isinstance(g, A.Or):
                out = (ta or tb, max(ra, rb))
            elif isinstance(g, A.Implies):
                out = ((not ta) or tb, max(-ra, rb))
            else:
                out = (ta == tb, min(max(-ra, rb), max(ra, -rb)))
        elif isinstance(g, A.Eventually):
            vals = [ev(g.child, k + j) for j in window(g.interval, k)]
            out = (any(t for t, _ in vals), max((r for _, r in vals), default=-math.inf))
        elif isinstance(g, A.Globally):
            vals = [ev(g.child, k + j) for j in window(g.interval, k)]
            out = (all(t for t, _ in vals), min((r for _, r in vals), default=math.inf))
        elif isinstance(g, (A.Until, A.WeakUntil)):
            # some j in I: right at k+j, and left at every k+i, i < j
            truth, rob = False, -math.inf
            left_t, left_r = True, math.inf  # left over [k, k+j)
            for j in range(n - k):
                if g.interval.contains(j * dt):
                    tb, rb = ev(g.right, k + j)
                    truth = truth or (tb and left_t)
                    rob = max(rob, min(rb, left_r))
                ta, ra = ev(g.left, k + j)
                left_t, left_r = left_t and ta, min(left_r, ra)
            if isinstance(g, A.WeakUntil):
                upto = A.Interval(0, g.interval.hi, True, g.interval.hi_closed)
                vals = [ev(g.left, k + j) for j in window(upto, k)]
                truth = truth or all(t for t, _ in vals)
                rob = max(rob, min((r for _, r in vals), default=math.inf))
            out = (truth, rob)
        elif isinstance(g, A.Release):
            # for every j in I: right at k+j, or left somewhere before it
            truth, rob = True, math.inf
            left_t, left_r = False, -math.inf  # left somewhere in [k, k+j)
            for j in range(n - k):
                if g.interval.contains(j * dt):
                    tb, rb = ev(g.right, k + j)
                    truth = truth and (tb or left_t)
                    rob = min(rob, max(rb, left_r))
                ta, ra = ev(g.left, k + j)
                left_t, left_r = left_t or ta, max(left_r, ra)
            out = (truth, rob)
        else:  # pragma: no cover
            raise TypeError(g)
        memo[key] = out
        return out

    return ev


VALUES = st.sampled_from([-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0])


@st.composite
def traces(draw, min_len: int = 1, max_len: int = 14):
    n = draw(st.integers(min_len, max_len))
    return {name: draw(st.lists(VALUES, min_size=n, max_size=n)) for name in ("x", "y", "z")}


SMALL = formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.5, 6), max_leaves=6)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(f=SMALL, sig=traces(), dt=st.sampled_from([0.5, 0.25, 1.0]))
def test_fast_equals_reference(f: A.Formula, sig: dict[str, list[float]], dt: float) -> None:
    n = len(sig["x"])
    rho = {"a": sig["x"], "b": sig["y"], "c": sig["z"]}
    ref = reference(f, rho, dt, n)
    states = {k: np.array(v) for k, v in sig.items()}
    res = monitor(ABC, states, dt, f)
    truth, rob = ref(f, 0)
    assert bool(res.satisfied[0]) == truth
    assert res.robustness[0] == rob
    for text_node in A.walk(f):
        got = signals(ABC, states, dt, text_node)[str(text_node)][0]
        assert got.tolist() == [ref(text_node, k)[1] for k in range(n)]
    # verdict and robustness sign agree where robustness is not 0
    if rob != 0:
        assert truth == (rob > 0)
    if not truth:
        assert res.failing[0] in {str(g) for g in A.walk(f)}
        assert 0.0 <= res.violation_time[0] <= (n - 1) * dt


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(f=SMALL, sig=traces(), data=st.data())
def test_violation_is_certain_after_its_time(f: A.Formula, sig: dict[str, list[float]], data) -> None:
    """Changing the samples after the violation time never turns the verdict to true."""
    dt = 0.5
    states = {k: np.array(v) for k, v in sig.items()}
    res = monitor(ABC, states, dt, f)
    if res.satisfied[0]:
        return
    cut = int(round(res.violation_time[0] / dt))
    n = len(sig["x"])
    tails = [np.full(n - cut - 1, v) for v in (2.0, -2.0, 0.0)]
    drawn = {k: np.array(data.draw(st.lists(VALUES, min_size=n - cut - 1, max_size=n - cut - 1))) for k in states}
    for mixed in range(5):
        other = {k: v.copy() for k, v in states.items()}
        for i, k in enumerate(other):
            other[k][cut + 1 :] = drawn[k] if mixed == 4 else tails[(i + mixed) % 3]
        assert not monitor(ABC, other, dt, f).satisfied[0]


def _batch(data, count: int, length: int) -> tuple[list[dict[str, list[float]]], dict[str, np.ndarray]]:
    """``count`` drawn traces of ``length`` samples, and the same as one batch ``(count, length)`` per variable."""
    runs = [data.draw(traces(min_len=length, max_len=length)) for _ in range(count)]
    return runs, {k: np.array([r[k] for r in runs]) for k in ("x", "y", "z")}


@settings(max_examples=100, deadline=None)
@given(f=SMALL, data=st.data())
def test_batch_equals_single_runs(f: A.Formula, data) -> None:
    runs, batch = _batch(data, 3, 6)
    res = monitor(ABC, batch, 0.5, f)
    for i, r in enumerate(runs):
        one = monitor(ABC, {k: np.array(v) for k, v in r.items()}, 0.5, f)
        assert (one.satisfied[0], one.robustness[0], one.failing[0]) == (
            res.satisfied[i],
            res.robustness[i],
            res.failing[i],
        )


@settings(max_examples=100, deadline=None)
@given(f=SMALL, data=st.data())
def test_no_blame_gives_the_same_numbers_and_no_failing_part(f: A.Formula, data) -> None:
    """``blame=False`` (the policy search's judge) skips naming the failing part and nothing else."""
    _, batch = _batch(data, 4, 7)
    full = monitor(ABC, batch, 0.5, f)
    bare = monitor(ABC, batch, 0.5, f, blame=False)
    assert bare.satisfied.tolist() == full.satisfied.tolist()
    assert bare.robustness.tolist() == full.robustness.tolist()
    np.testing.assert_array_equal(bare.violation_time, full.violation_time)  # nan where satisfied, in both
    assert bare.failing == (None,) * 4
    assert [t is None for t in full.failing] == full.satisfied.tolist()


@settings(max_examples=40, deadline=None)
@given(f=formulas(atoms=("a", "b"), interval=grid_intervals(0.25, 40), max_leaves=4), seed=st.integers(0, 2**32 - 1))
def test_long_traces_against_reference(f: A.Formula, seed: int) -> None:
    """Traces longer than the until kernel's block size (64) and windows of many samples."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(65, 140))
    sig = {k: rng.choice([-2.0, -1.0, 0.0, 1.0, 2.0], size=n) for k in ("x", "y", "z")}
    ref = reference(f, {"a": list(sig["x"]), "b": list(sig["y"])}, 0.25, n)
    res = monitor(ABC, sig, 0.25, f)
    truth, rob = ref(f, 0)
    assert (bool(res.satisfied[0]), float(res.robustness[0])) == (truth, rob)
    assert signals(ABC, sig, 0.25, f)[str(f)][0].tolist() == [ref(f, k)[1] for k in range(n)]


@pytest.mark.parametrize(
    "text", ["a U b", "a U[1,3] b", "a R(0.5,2] b", "!a W[0,4) b", "G (a -> F[0,1] b)", "b U(2,inf) G !a"]
)
def test_long_batch_against_reference(text: str) -> None:
    """Several runs longer than the until kernel's block size, each against the reference."""
    f = parse_formula(text)
    rng = np.random.default_rng(7)
    R, n, dt = 3, 150, 0.25
    sig = {
        k: rng.choice([-2.0, -1.0, 0.0, 1.0, 2.0], size=(R, n), p=[0.1, 0.2, 0.1, 0.3, 0.3]) for k in ("x", "y", "z")
    }
    res = monitor(ABC, sig, dt, f)
    rob = signals(ABC, sig, dt, f)[text]
    for r in range(R):
        ref = reference(f, {"a": list(sig["x"][r]), "b": list(sig["y"][r])}, dt, n)
        assert (bool(res.satisfied[r]), float(res.robustness[r])) == ref(f, 0)
        assert rob[r].tolist() == [ref(f, k)[1] for k in range(n)]


@settings(max_examples=60, deadline=None)
@given(f=state_formulas(atoms=("a", "b")), sig=traces())
def test_state_formula_is_pointwise(f: A.Formula, sig) -> None:
    sig_f = signals(ABC, {k: np.array(v) for k, v in sig.items()}, 1.0, f)[str(f)]
    ref = reference(f, {"a": sig["x"], "b": sig["y"]}, 1.0, len(sig["x"]))
    assert sig_f[0].tolist() == [ref(f, k)[1] for k in range(len(sig["x"]))]


# ------------------------------------------------------------ the round trip


@settings(max_examples=400, deadline=None)
@given(f=formulas())
def test_round_trip(f: A.Formula) -> None:
    assert parse_formula(str(f)) == f


# ------------------------------------------------------------ mitlc check

P5_SPEC = ROOT / "specs" / "pendulum" / "p5_timed_visit.mitl"


@pytest.fixture
def p5(tmp_path: Path) -> Path:
    path = tmp_path / "p5.mitl"
    path.write_text("plant pendulum(u_max = 10)\n" + THESIS["p5"] + "\n", encoding="utf-8")
    return path


@pytest.fixture
def p3(tmp_path: Path) -> Path:
    path = tmp_path / "p3.mitl"
    path.write_text("plant pendulum(u_max = 10)\n" + THESIS["p3"] + "\n", encoding="utf-8")
    return path


def write_csv(path: Path, rows: list[list[float]], header: str = "t,q,qdot") -> Path:
    path.write_text(header + "\n" + "\n".join(",".join(repr(v) for v in row) for row in rows) + "\n")
    return path


GOOD = [0.0, 1.0, 2.0, 3.0, -3.0, 2.0, 1.0]
LATE = [0.0, 1.0, 2.0, 2.0, 2.0, 3.0, 1.0]


def rows(q: list[float], dt: float = 0.5) -> list[list[float]]:
    return [[k * dt, v, 0.0] for k, v in enumerate(q)]


def check(*args: str):
    return CliRunner().invoke(main, ["check", *args])


def test_check_satisfied(p5: Path, tmp_path: Path) -> None:
    res = check(str(p5), str(write_csv(tmp_path / "good.csv", rows(GOOD))))
    assert res.exit_code == 0, res.output
    assert "satisfied" in res.output
    assert f"robustness: {PI - 3.0:.6g}" in res.output


def test_check_violated(p5: Path, tmp_path: Path) -> None:
    res = check(str(p5), str(write_csv(tmp_path / "late.csv", rows(LATE))))
    assert res.exit_code == 1, res.output
    assert "VIOLATED" in res.output
    assert "t = 2 s" in res.output and "F[1,2] kappa" in res.output


def test_check_json_and_npz(p5: Path, tmp_path: Path) -> None:
    t = np.arange(7) * 0.5
    path = tmp_path / "late.npz"
    np.savez(path, t=t, q=np.array(LATE), qdot=np.zeros(7))
    res = check(str(p5), str(path), "--json")
    assert res.exit_code == 1, res.output
    out = json.loads(res.output)
    assert out["satisfied"] is False and out["failing"] == "F[1,2] kappa" and out["violation_time"] == 2.0
    assert out["robustness"] == 2.0 - (PI - 0.5) and out["samples"] == 7 and out["dt"] == 0.5
    np.savez(path, t=t, x=np.stack([np.array(GOOD), np.zeros(7)], axis=1))
    res = check(str(p5), str(path), "--json")
    assert res.exit_code == 0 and json.loads(res.output)["satisfied"] is True


def test_check_formula_option(p5: Path, tmp_path: Path) -> None:
    trace = str(write_csv(tmp_path / "good.csv", rows(GOOD)))
    res = check(str(p5), trace, "--formula", "F[1.5,1.5] kappa")
    assert res.exit_code == 0, res.output
    res = check(str(p5), trace, "--formula", "G !kappa")
    assert res.exit_code == 1 and "!kappa" in res.output and "t = 1.5 s" in res.output
    res = check(str(p5), trace, "--formula", "F kapa")
    assert res.exit_code == 2 and "undefined proposition 'kapa'" in res.output
    res = check(str(p5), trace, "--formula", "F (kappa")
    assert res.exit_code == 2 and "--formula" in res.output


def test_check_a_require_spec_needs_a_formula_option(tmp_path: Path) -> None:
    """A spec of require lines has no formula to judge by: --formula gives one, else one line, exit 2."""
    spec = tmp_path / "req.mitl"
    spec.write_text(
        "plant mass-damper\ninit q in [-1, -0.5], qdot = 0\nsetpoint 0\nprop near = abs(q) < 0.1\n"
        "require overshoot <= 0\n"
    )
    trace = tmp_path / "t.csv"
    trace.write_text("t,q,qdot\n0,-1,0\n0.03,-0.5,0\n0.06,0.05,0\n")
    res = check(str(spec), str(trace), "--formula", "F near")
    assert res.exit_code == 0, res.output
    res = check(str(spec), str(trace))
    assert res.exit_code == 2
    assert res.output.startswith(f"{spec}: error: the spec has no 'formula' nor 'check' line")
    assert "Traceback" not in res.output


def test_check_trace_time_offset(p5: Path, tmp_path: Path) -> None:
    trace = [[10.0 + r[0], r[1], r[2]] for r in rows(LATE)]
    res = check(str(p5), str(write_csv(tmp_path / "late.csv", trace)))
    assert res.exit_code == 1 and "t = 12 s" in res.output


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("a.csv", "t,q\n0,0\n0.5,0\n", "missing column 'qdot'"),
        ("a.csv", "q,qdot\n0,0\n0.5,0\n", "missing column 't'"),
        ("a.csv", "t,q,qdot\n0,0,0\n0.5,0,0\n1.5,0,0\n", "time step is not uniform"),
        ("a.csv", "t,q,qdot\n0,0,0\n", "at least 2 samples"),
        ("a.csv", "t,q,qdot\n0,0,0\n0.5,nan,0\n", "not a finite number"),
        ("a.csv", "t,q,qdot\n0,0,0\n0.5,inf,0\n", "not a finite number"),
        ("a.csv", "t,q,qdot\n0,0,0\n0.5,zero,0\n", "not a number: 'zero'"),
        ("a.csv", "t,q,qdot\n0,0,0\n0.5,0\n", "has 2 fields, the header has 3"),
        ("a.csv", "t,q,qdot\n0,0,0\n0,0,0\n", "time must increase"),
        ("a.csv", "", "empty"),
        ("a.npz", "not a zip file", "cannot read"),
        ("a.txt", "t,q,qdot\n", "must be .csv or .npz"),
    ],
)
def test_check_bad_trace(p3: Path, tmp_path: Path, name: str, content: str, message: str) -> None:
    path = tmp_path / name
    path.write_text(content)
    res = check(str(p3), str(path))
    assert res.exit_code == 2, res.output
    first, *rest = res.output.strip().splitlines()
    # one located error line naming the file and what is wrong, at most a hint after it
    assert first.startswith(f"{path}") and ": error: " in first and message in first, res.output
    assert all(line.startswith("  hint: ") for line in rest) and len(rest) <= 1, res.output


def test_check_bad_npz(p3: Path, tmp_path: Path) -> None:
    path = tmp_path / "a.npz"
    np.savez(path, t=np.arange(3) * 0.5, q=np.zeros(3))
    res = check(str(p3), str(path))
    assert res.exit_code == 2 and "missing array 'qdot'" in res.output
    np.savez(path, t=np.arange(3) * 0.5, x=np.zeros((3, 3)))
    res = check(str(p3), str(path))
    assert res.exit_code == 2 and "'x' has shape (3, 3)" in res.output
    np.savez(path, t=np.arange(3) * 0.5, q=np.zeros(4), qdot=np.zeros(3))
    res = check(str(p3), str(path))
    assert res.exit_code == 2 and "'q' has 4 samples" in res.output


def test_check_missing_files(p5: Path, tmp_path: Path) -> None:
    res = check(str(p5), str(tmp_path / "nope.csv"))
    assert res.exit_code == 2 and "cannot read" in res.output and "nope.csv" in res.output
    res = check(str(tmp_path / "nope.mitl"), str(tmp_path / "nope.csv"))
    assert res.exit_code == 2 and "nope.mitl" in res.output


def test_check_the_shipped_spec(tmp_path: Path) -> None:
    if not P5_SPEC.exists():
        pytest.skip("spec file not written yet")
    res = check(str(P5_SPEC), str(write_csv(tmp_path / "good.csv", rows(GOOD))))
    assert res.exit_code == 0, res.output


@pytest.mark.parametrize("n", [10, 12, 20, 200])  # window past the end, plain loop, blocked scan (> 64 samples)
def test_until_windows_and_empty_intervals_on_long_traces(n):
    """a U[lo,hi] b needs its witness inside the window even when the window starts late, and an
    interval without a sample offset ((1, 1.4) at 0.5 s) is never met: F false, G true, U false."""
    from mitlc.monitor.kernels import BOOL, until

    a = np.ones((1, n), dtype=bool)
    b = np.zeros((1, n), dtype=bool)
    b[0, 8] = True  # the one witness, at offset 8 from the start
    for lo, hi in ((5, 6), (3, 6), (1, 2), (0, 3)):  # (3, 6): lo + hi reaches the end of 10 samples
        got = until(a, b, lo, hi, BOOL)[0]  # the witness must sit lo to hi samples ahead
        want = np.array([k + lo <= 8 <= k + hi for k in range(n)])
        np.testing.assert_array_equal(got, want, err_msg=f"[{lo},{hi}]")
    last = np.zeros((1, n), dtype=bool)
    last[0, -1] = True  # a window one sample short of the trace misses a witness at its end
    got = until(a, last, 0, n - 2, BOOL)[0]
    np.testing.assert_array_equal(got, np.arange(n) >= 1)
    assert not until(a, b, 3, 2, BOOL).any()  # lo > hi: no offset, never
    spec = parse_spec("prop a = x > 0\nprop b = y > 0\nformula F a\n")
    tr = {"x": np.ones((1, n)), "y": np.ones((1, n))}
    for text, value in (("F(1,1.4) a", False), ("G(1,1.4) !a", True), ("a U(1,1.4) b", False)):
        assert monitor(spec, tr, 0.5, parse_formula(text)).satisfied.tolist() == [value], text


# Every trace of 4 samples whose three signals are each -1 or +1 (4096 traces), as one
# batch: an exhaustive reading of "certain" to hold the violation time against.
_N4 = 4
_CODES = np.arange(2 ** (3 * _N4))
_BITS = ((_CODES[:, None] >> np.arange(3 * _N4)) & 1) * 2.0 - 1.0
_ALL4 = {name: _BITS[:, i * _N4 : (i + 1) * _N4] for i, name in enumerate("xyz")}


def _earliest_certain_false(satisfied: np.ndarray) -> np.ndarray:
    """Per trace of ``_ALL4``: the first sample k from which every trace with the same
    samples 0..k is false (inf where the trace is satisfied)."""
    out = np.full(len(satisfied), np.inf)
    for k in range(_N4 - 1, -1, -1):
        cols = [i * _N4 + j for i in range(3) for j in range(k + 1)]
        key = (_BITS[:, cols] > 0) @ (1 << np.arange(len(cols)))
        all_false = np.ones(int(key.max()) + 1, bool)
        np.logical_and.at(all_false, key, ~satisfied)
        out = np.where(all_false[key], float(k), out)
    return out


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(f=SMALL)
def test_violation_time_against_every_continuation(f: A.Formula) -> None:
    """The violation time is never before the verdict is certain (over all 4096 traces
    of 4 samples), and for formulas without constants or repeated atoms whose windows start
    at their own sample it is exactly the first sample from which no continuation satisfies
    the formula."""
    res = monitor(ABC, _ALL4, 0.5, f)
    false = ~res.satisfied
    assert np.isnan(res.violation_time[res.satisfied]).all()
    if not false.any():
        return
    earliest = _earliest_certain_false(res.satisfied)[false] * 0.5
    got = res.violation_time[false]
    assert (got >= earliest).all(), str(f)
    atoms = [g.name for g in A.walk(f) if isinstance(g, A.Atom)]
    # windows that hold their own sample ([0, ...]) are never empty at the trace's end, where an
    # empty G would make a part a constant (F G(0,inf) a is always true) that settles at once
    own = all(g.interval.lo == 0 and g.interval.lo_closed for g in A.walk(f) if hasattr(g, "interval"))
    if own and len(set(atoms)) == len(atoms) and not any(isinstance(g, A.Const) for g in A.walk(f)):
        assert got.tolist() == earliest.tolist(), str(f)


@pytest.mark.parametrize(
    ("text", "x", "y", "when", "blamed"),
    [
        # G fails at 1.5 s, F[0,1] b runs out at 1 s: the F settles first
        ("G[0,2] a & F[0,1] b", [1, 1, 1, -1, 1], [-1] * 5, 1.0, "F[0,1] b"),
        # G fails at 0.5 s, before the F's window ends
        ("G[0,2] a & F[0,1] b", [1, -1, 1, 1, 1], [-1] * 5, 0.5, "a"),
        # the left side of an until fails (0.5 s) before its window opens at 1 s
        ("a U[1,2] b", [1, -1, 1, 1, 1], [-1, -1, 1, 1, 1], 0.5, "a"),
        # a at 0.5 s asks for b within [0.5, 1.5] s; none comes
        ("G (a -> F[0,1] b)", [-1, 1, -1, -1, -1], [-1] * 5, 1.5, "F[0,1] b"),
        # the window of an until passes without a witness
        ("a U[0,1] b", [1, 1, 1, 1, 1], [-1, -1, -1, 1, 1], 1.0, "a U[0,1] b"),
        # the left side failing on the window's last sample is no reason: no witness came
        ("a U[0,1] b", [1, 1, -1, 1, 1], [-1, -1, -1, 1, 1], 1.0, "a U[0,1] b"),
        # a release broken on the trace's last sample, and on its window's last sample
        ("a R b", [-1] * 5, [1, 1, 1, 1, -1], 2.0, "b"),
        ("a R[0,1] b", [-1] * 5, [1, 1, -1, 1, 1], 1.0, "b"),
        # an interval without a sample offset: the until fails at once, as itself
        ("a U(1,1.4) b", [-1] * 5, [1] * 5, 0.0, "a U(1,1.4) b"),
    ],
)
def test_violation_time_and_blame_by_hand(text: str, x: list[float], y: list[float], when: float, blamed: str) -> None:
    res = run(text, x=x, y=y)
    assert not res.satisfied[0]
    assert res.violation_time[0] == when
    assert res.failing[0] == blamed


@settings(max_examples=300, deadline=None)
@given(
    st.integers(1, 40),
    st.integers(1, 120),
    st.integers(0, 130),
    st.one_of(st.integers(0, 130), st.just(math.inf)),
    st.sampled_from(["max", "min", "or", "and"]),
    st.integers(0, 2**32 - 1),
)
def test_sliding_window_is_every_windows_reduction(R, L, lo, width, op_name, seed):
    """kernels.window by doubling against each window reduced on its own: runs x samples of reals with
    ties, infinities and NaN, or of booleans; windows empty, cut by the trace's end, or past it."""
    from mitlc.monitor.kernels import window

    rng = np.random.default_rng(seed)
    op, ident = {"max": (np.maximum, -np.inf), "min": (np.minimum, np.inf)}.get(op_name, (None, None))
    if op is None:
        op, ident = (np.logical_or, False) if op_name == "or" else (np.logical_and, True)
        x = rng.random((R, L)) < rng.random()
    else:
        x = rng.integers(-3, 4, size=(R, L)).astype(float)
        x[rng.random((R, L)) < 0.05] = np.inf
        x[rng.random((R, L)) < 0.05] = -np.inf
        x[rng.random((R, L)) < 0.02] = np.nan
    hi = lo + width
    want = np.full((R, L), ident, dtype=x.dtype)
    for k in range(L):
        a, b = k + lo, int(min(k + hi, L - 1))
        if a <= L - 1 and b >= a:
            want[:, k] = op.reduce(x[:, a : b + 1], axis=1)
    assert np.array_equal(window(x, lo, hi, op, ident), want, equal_nan=True)
