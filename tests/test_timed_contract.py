"""The contract between the timed obligation net and the monitor (docs/semantics.md, section 7).

For each of 1800 random formulas (depth up to 4, every operator, nested bounded and unbounded
intervals, open and closed ends, some off the sample grid) the net is run on *every*
trace of 6 samples over two propositions (4096 traces), and the monitor judges the
same traces.  Grouping the traces by their first ``k + 1`` samples gives, for every
prefix, the exact set of its continuations, so the tests check:

(a) the net records a violation (or a success) at sample ``k`` only when every
    continuation of the prefix is violating (satisfying);
(b) at the last sample the net's verdict is the monitor's;
(c) for a deadline part (a temporal operator over state formulas, at the root or
    under untimed operators) the violation is recorded at the first sample at
    which no continuation can meet it, and never changes afterwards.
"""

from __future__ import annotations

import numpy as np
import pytest
import strategies
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.monitor.offline import monitor
from mitlc.petri.timed import FAILED, FALSE, MET, PENDING, TRUE, ObligationTree
from mitlc.runtime.obligations import TimedState
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_spec
from mitlc.spec.passes import normal_form

N = 5  # samples 0..5
L = N + 1
SPEC = parse_spec("prop a = x > 0.5\nprop b = y > 0.5\nformula a")
CODES = np.arange(4**L)
BITS = np.stack([(CODES >> (2 * j)) & 3 for j in range(L)], axis=1)  # (traces, samples) atom codes
STATES = np.stack([BITS & 1, BITS >> 1], axis=2).astype(float)  # columns x, y


def truth_at(k: int) -> dict[str, np.ndarray]:
    return {"a": (BITS[:, k] & 1).astype(bool), "b": (BITS[:, k] >> 1).astype(bool)}


def run(f: A.Formula, dt: float = 1.0) -> tuple[np.ndarray, TimedState]:
    """The net's verdict after each sample, ``(traces, L)``."""
    state = TimedState(ObligationTree.build(normal_form(f)), dt, len(CODES), N)
    out = np.empty((len(CODES), L), dtype=np.int8)
    for k in range(L):
        state.observe(truth_at(k))
        out[:, k] = state.verdict()
    return out, state


def prefix_verdicts(sat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(all continuations satisfy, all violate)`` for every trace's prefix of each length, ``(traces, L)``."""
    every, none = np.empty((len(CODES), L), bool), np.empty((len(CODES), L), bool)
    for k in range(L):
        group = CODES % (4 ** (k + 1))  # the first k + 1 samples
        n_sat = np.bincount(group, weights=sat, minlength=4 ** (k + 1))
        size = np.bincount(group, minlength=4 ** (k + 1))
        every[:, k] = n_sat[group] == size[group]
        none[:, k] = n_sat[group] == 0
    return every, none


intervals = st.one_of(strategies.grid_intervals(step=1.0, max_end=4), strategies.grid_intervals(step=0.5, max_end=7))
nested = strategies.formulas(atoms=("a", "b"), interval=intervals, max_leaves=6).filter(lambda f: A.depth(f) <= 4)


@settings(max_examples=900, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(nested)
def test_never_early_and_exact_at_the_end(f: A.Formula) -> None:
    verdict, _ = run(f)
    sat = monitor(SPEC, STATES, 1.0, formula=f).satisfied
    every, none = prefix_verdicts(sat)
    # (a) sound at every prefix, both ways
    assert not np.any((verdict == FALSE) & ~none), f"premature violation of {f}"
    assert not np.any((verdict == TRUE) & ~every), f"premature success of {f}"
    # decided values never change
    decided = verdict != PENDING
    assert np.all(verdict[:, 1:][decided[:, :-1]] == verdict[:, :-1][decided[:, :-1]])
    # (b) the end verdict is the monitor's
    np.testing.assert_array_equal(verdict[:, -1] == TRUE, sat, err_msg=str(f))
    assert not np.any(verdict[:, -1] == PENDING)


deadline_ops = st.sampled_from(["F", "G", "U", "R"])
states = strategies.state_formulas(atoms=("a", "b"), max_leaves=3)


@st.composite
def deadline_parts(draw: st.DrawFn) -> A.Formula:
    op, iv = draw(deadline_ops), draw(intervals)
    left, right = draw(states), draw(states)
    part: A.Formula = {
        "F": lambda: A.Eventually(right, iv),
        "G": lambda: A.Globally(right, iv),
        "U": lambda: A.Until(left, right, iv),
        "R": lambda: A.Release(left, right, iv),
    }[op]()
    if draw(st.booleans()):  # a state context that does not decide it
        part = A.And(part, A.Const(True)) if draw(st.booleans()) else A.Or(part, A.Const(False))
    return part


@settings(max_examples=300, deadline=None)
@given(deadline_parts())
def test_deadline_recorded_at_the_first_sample_that_decides_it(f: A.Formula) -> None:
    verdict, _ = run(f)
    sat = monitor(SPEC, STATES, 1.0, formula=f).satisfied
    every, none = prefix_verdicts(sat)
    # (c) exact: decided as soon as the prefix decides it
    np.testing.assert_array_equal(verdict == FALSE, none, err_msg=str(f))
    np.testing.assert_array_equal(verdict == TRUE, every, err_msg=str(f))


def test_bounded_response_missed_deadline_by_hand() -> None:
    """``G (a -> F[0,2] b)``: a at samples 1 and 4, b at 2 only; the second response misses at 6."""
    f = A.Globally(A.Implies(A.Atom("a"), A.Eventually(A.Atom("b"), A.Interval(0, 2))))
    tree = ObligationTree.build(normal_form(f))
    state = TimedState(tree, 1.0, 1, 7)
    a = [0, 1, 0, 0, 1, 0, 0, 0]
    b = [0, 0, 1, 0, 0, 0, 0, 0]
    seen = []
    for k in range(8):
        state.observe({"a": np.array([bool(a[k])]), "b": np.array([bool(b[k])])})
        seen.append(int(state.places()[tree.root][0]))
    assert seen.index(FAILED) == 6  # the obligation from t = 4 ends at t = 6 without b
    (f_node,) = [i for i in tree.temporal if tree.nodes[i].op == "F"]
    assert state.clocks()[f_node][0] != state.clocks()[f_node][0]  # nan: no live instance after the failure


def test_reach_and_stay_in_time_by_hand() -> None:
    """``F[0,2] G g``: g from t = 1 on meets it; the G obligation stays live after 2 s."""
    f = A.Eventually(A.Globally(A.Atom("g")), A.Interval(0, 2))
    tree = ObligationTree.build(f)
    state = TimedState(tree, 1.0, 2, 5)
    g = np.array([[0, 1, 1, 1, 1, 1], [0, 0, 0, 1, 1, 1]], dtype=bool)  # the second run is late
    places = []
    for k in range(6):
        state.observe({"g": g[:, k]})
        places.append(state.places())
    G = tree.nodes[tree.root].children[0]
    assert [int(p[G][0]) for p in places[:5]] == [1, 1, 1, 1, 1]  # open: the next sample keeps it
    assert [int(p[tree.root][1]) for p in places] == [1, 1, 4, 4, 4, 4]  # failed once 2 s pass without g
    assert [int(p[tree.root][0]) for p in places] == [1, 1, 2, 2, 2, MET]  # open, then waits on G, met at the end


# ------------------------------------------------------------------ through the compiler and the runtime

DT, STEPS = 0.5, 10
PENDULUM = f"plant pendulum(dt = {DT})\nhorizon {STEPS * DT}\nprop a = q > 0\nprop b = qdot > 0\n"


def _has_timed_part(f: A.Formula) -> bool:
    from mitlc.petri.timed import needs_obligations

    temporal = (A.Eventually, A.Globally, A.Until, A.Release)
    return any(isinstance(n, temporal) and needs_obligations(n) for n in A.walk(normal_form(f)))


timed_roots = (
    strategies.formulas(atoms=("a", "b"), interval=strategies.grid_intervals(step=0.5, max_end=6), max_leaves=6)
    .filter(lambda f: A.depth(f) <= 4)
    .filter(_has_timed_part)
)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(timed_roots, st.lists(st.integers(0, 3), min_size=STEPS + 1, max_size=STEPS + 1))
def test_compiled_timed_parts_end_where_the_monitor_does(f: A.Formula, codes: list[int]) -> None:
    """Every timed part of a compiled random formula (a conjunct reached through & and weights) ends in
    met exactly when the monitor says it holds, with --violations permanent charging its failure."""
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.petri.reading import flatten, strip_weights
    from mitlc.runtime import NetRuntime

    spec = parse_spec(PENDULUM + f"formula {f}\n")
    rs = compile_spec(spec, CompileOptions(violations="permanent"))
    assert rs.timed
    bits = np.array(codes)
    x = np.stack([np.where(bits & 1, 1.0, -1.0), np.where(bits & 2, 1.0, -1.0)], axis=1)[None]  # (1, N+1, 2)
    rt = NetRuntime(rs)
    M = rt.reset(x[:, 0])
    rewards = []
    for k in range(STEPS):
        M1 = rt.step(M, x[:, k + 1], (k + 1) * DT)
        rewards.append(float(rt.reward(M, M1)[0]))
        M = M1
    assert np.all(np.isfinite(rewards))
    names = rs.net.place_names
    conjuncts = [str(c) for c in flatten(strip_weights(rs.normal_form), A.And)]
    for tn in rs.timed:
        root = dict(tn.subnets)[tn.tree.root]
        places = [names[i] for i in rs.net.subnets[root].places]
        marked = [p for p, i in zip(places, rs.net.subnets[root].places, strict=True) if M[0, i]]
        assert len(marked) == 1 and marked[0].startswith(("p_met_", "p_failed_")), marked
        sat = bool(monitor(spec, x, DT, formula=tn.tree.formula).satisfied[0])
        assert marked[0].startswith("p_met_") == sat, (str(tn.tree.formula), marked)
        if str(tn.tree.formula) in conjuncts:  # watched: its failure is charged
            assert (names.index(marked[0].replace("p_met_", "p_failed_")) in np.flatnonzero(M[0])) == (not sat)


def test_check_net_reports_what_the_runtime_recorded(tmp_path) -> None:
    """``mitlc check --net``: reached within 2 s and held, but obs1 crossed at 0.39 s on the way."""
    import json as _json
    from pathlib import Path

    from click.testing import CliRunner

    from mitlc.cli.main import main

    spec = Path(__file__).resolve().parent.parent / "specs" / "pendulum" / "n1_reach_in_time.mitl"
    t = np.arange(101) * 0.03
    trace = tmp_path / "tr.csv"
    paths = [("through", np.interp(t, [0, 1.2, 3], [3.0, 0, 0])), ("late", np.interp(t, [0, 2.7, 3], [-3.0, 0, 0]))]
    for name, q in paths:
        qdot = np.gradient(q, 0.03)
        rows = "".join(f"{a:.2f},{float(b)!r},{float(c)!r}\n" for a, b, c in zip(t, q, qdot, strict=True))
        trace.write_text("t,q,qdot\n" + rows)
        r = CliRunner().invoke(main, ["check", str(spec), str(trace), "--net", "--json"])
        assert r.exit_code == 1, r.output
        net = _json.loads(r.output)["net"]
        if name == "through":  # the safety part's violation, at the monitor's time; the timed part is met
            assert net["violated"] == ["p_violated_G_not_obs1"] and net["violation_time"] == 0.39
            assert net["obligations"] == [{"formula": "F[0,2] G goal", "verdict": "met"}]
        else:  # too slow: decided at 1.98 s, the window's last sample (2 / 0.03 is not a sample)
            assert net["violated"] == ["p_failed_F2"] and net["violation_time"] == 1.98
            assert net["obligations"] == [{"formula": "F[0,2] G goal", "verdict": "failed"}]


@pytest.mark.parametrize(
    "formula",
    [
        "G (a -> F[0,{b}] b)",
        "F[0,{b}] G a",
        "G[0,{b}] F[{b},{c}] a",
        "a U[0,{c}] (G[0,{b}] b)",
        "b R[0,{b}] F[0,{c}] a",
    ],
)
def test_the_net_does_not_grow_with_the_bounds_or_the_sample_period(formula: str) -> None:
    """Places and transitions depend on the operators only: bounds 0.5 .. 50 s, dt 0.01 .. 0.1 s."""
    from mitlc.petri.compile import compile_spec

    shapes = set()
    for b, c, dt in [(0.5, 1.0, 0.1), (2.0, 3.0, 0.05), (50.0, 80.0, 0.01)]:
        spec = parse_spec(
            f"plant pendulum(dt = {dt})\nhorizon 100\nprop a = q > 0\nprop b = qdot > 0\n"
            f"formula {formula.format(b=b, c=c)}\n"
        )
        rs = compile_spec(spec)
        assert rs.timed
        shapes.add((rs.net.place_names, rs.net.D.shape))
    assert len(shapes) == 1


@pytest.mark.parametrize(
    ("formula", "rewards"),
    [
        # F[0,1] G a: a never holds in the window, so the obligation fails at t = 1 (sample 2); from
        # then on the net pays what it still needs (a's +1 / -1) less one: 0 with a, -2 without
        ("F[0,1] G a", [-1.0, -1.0, -2.0, 0.0, 0.0, -2.0, 0.0, 0.0]),
        # 2 * (F[0,1] G a): the weight scales the failed term as it does the rest
        ("2 * F[0,1] G a", [-2.0, -2.0, -4.0, 0.0, 0.0, -4.0, 0.0, 0.0]),
    ],
)
def test_a_failed_obligation_still_pulls_towards_what_it_needs(formula: str, rewards: list[float]) -> None:
    """Once a timed obligation has failed, paying 0 would beat trying (-1 per step away from the goal)
    and learners learned to give up; the failed place pays the state formula it needs, less one."""
    from mitlc.petri.compile import compile_spec
    from mitlc.runtime import NetRuntime

    spec = parse_spec(f"plant pendulum(dt = 0.5)\nhorizon 4\nprop a = q > 0\nprop b = qdot > 0\nformula {formula}\n")
    rs = compile_spec(spec)
    assert "p_failed_" in str(rs.reward)
    q = [-1, -1, -1, -1, 1, 1, -1, 1, 1]
    x = np.array([[[v, 0.0] for v in q]], dtype=float)
    rt = NetRuntime(rs)
    M, got = rt.reset(x[:, 0]), []
    for k in range(8):
        M1 = rt.step(M, x[:, k + 1], (k + 1) * 0.5)
        got.append(float(rt.reward(M, M1)[0]))
        M = M1
    assert got == rewards
