"""Sparse nets (issue #17, part 4): D-, D+ kept in compressed rows, region nets stepped by the
region that holds, and the compiler linear in the formula on the nets that used to be quadratic."""

from __future__ import annotations

import re

import numpy as np
import pytest
import strategies
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from mitlc.errors import CompileError, MitlError
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.petri.net import Incidence, Net
from mitlc.petri.regions import state_groups
from mitlc.runtime import NetRuntime
from mitlc.spec import predicates as P
from mitlc.spec.parse import parse_spec


def _balanced(parts: list[str]) -> str:
    """``a & b & ...`` as a balanced tree (a flat chain past 256 operands is refused by the parser)."""
    if len(parts) == 1:
        return parts[0]
    h = len(parts) // 2
    return f"({_balanced(parts[:h])}) & ({_balanced(parts[h:])})"


def disjoint_spec(n: int) -> str:
    """``n`` provably disjoint propositions ``a_i = i <= x < i + 1``, each eventually reached."""
    defs = "".join(f"prop a_{i} = {i} <= x < {i + 1}\n" for i in range(n))
    return f"{defs}formula {_balanced([f'F a_{i}' for i in range(n)])}\n"


# ------------------------------------------------------------------ the sparse matrices


def test_incidence_round_trips_and_multiplies_as_the_dense_matrix() -> None:
    rng = np.random.default_rng(0)
    for _ in range(50):
        a = rng.integers(-2, 3, size=(int(rng.integers(0, 6)), int(rng.integers(1, 6)))) * (rng.random((1, 1)) < 0.8)
        inc = Incidence.from_dense(a)
        np.testing.assert_array_equal(inc.toarray(), a)
        assert np.all(inc.data != 0) and inc.nnz == np.count_nonzero(a)
        np.testing.assert_array_equal(inc.transpose().toarray(), a.T)
        x = rng.integers(0, 2, size=(3, a.shape[0]))
        np.testing.assert_array_equal(inc.left_multiply(x), x @ a)
        np.testing.assert_array_equal(inc.left_multiply(x[0]), x[0] @ a)
        assert inc == Incidence.from_dense(a.copy())
    ones = Incidence.ones((2, 3), [1, 0, 1, 1], [2, 1, 0, 2])  # (1, 2) given twice is still 1
    assert ones.toarray().tolist() == [[0, 1, 0], [1, 0, 1]]
    assert ones.single_columns().tolist() == [1, -1]
    assert Incidence.from_dense([[0, 2], [0, 0], [1, 0]]).single_columns().tolist() == [-1, -1, 0]
    with pytest.raises(ValueError, match="column index"):
        Incidence((1, 2), [0, 1], [2], [1])


def test_compiled_nets_keep_d_sparse_and_their_dense_views_equal() -> None:
    rs = compile_spec(parse_spec("prop a = x < 0\nprop b = x > 1\nprop c = y < 0\nformula F[0,1] a & G (b | c)"))
    net = rs.net
    assert isinstance(net.pre, Incidence) and isinstance(net.post, Incidence)
    np.testing.assert_array_equal(net.D_minus, net.pre.toarray())
    np.testing.assert_array_equal(net.D, net.D_plus - net.D_minus)
    assert net.D is net.D and not net.D.flags.writeable  # computed once, read-only
    # the same net built from dense matrices, as before
    dense = Net(net.places, net.transitions, net.subnets, net.D_minus, net.D_plus, net.M0)
    assert dense.pre == net.pre and dense.post == net.post
    assert dense.reachable_markings().__len__() == len(net.reachable_markings())
    for p in range(len(net.places)):  # the dense reading of successors
        want = []
        for t in range(len(net.transitions)):
            if net.D_minus[t, p]:
                want.extend(int(j) for j in np.flatnonzero(net.D_plus[t]))
        assert net.successors(p) == tuple(dict.fromkeys(want))
    rng = np.random.default_rng(1)
    fired = rng.integers(0, 2, size=(5, len(net.transitions)))
    np.testing.assert_array_equal(net.fire(net.M0, fired), fired @ net.D + net.M0)
    assert net.place_index("p_a") == net.place_names.index("p_a")
    with pytest.raises(ValueError):
        net.place_index("p_nowhere")


def test_500_disjoint_propositions_compile_to_one_sparse_region_net() -> None:
    """One region net of 501 places (no proposition covers x < 0): 501 x 500 transitions and one per
    eventually, whose dense D-, D+ and D would take 3 GB each; the compressed rows take 12 MB."""
    rs = compile_spec(parse_spec(disjoint_spec(500)))
    net = rs.net
    assert len(rs.groups) == 1 and len(rs.groups[0]) == 500
    (region,) = [s for s in net.subnets if s.role == "region"]
    assert len(region.places) == 501 and len(region.transitions) == 501 * 500
    assert len(net.transitions) == 501 * 500 + 500 and len(net.places) == 501 + 2 * 500
    assert net.pre.nnz == net.post.nnz == len(net.transitions)
    assert net.pre.nbytes + net.post.nbytes < 16 * 2**20  # dense: 2 x 251,000 x 1,501 x 8 B = 6 GB
    with pytest.raises(CompileError, match=re.escape("251,000 x 1,501")):
        _ = net.D_minus
    with pytest.raises(CompileError, match="sparse form"):
        _ = net.D
    assert net.successors(region.places[3]) == tuple(p for p in region.places if p != region.places[3])
    # the runtime steps it by the region that holds: x = 7.5 is a_7, x = -1 none of them
    rt = NetRuntime(rs, state_names=("x",))
    assert [s for s, _ in rt.rule.regions] == [net.subnets.index(region)]
    M = rt.reset(np.array([[0.5], [7.5]]))
    M1 = rt.step_direct(M, np.array([[-1.0], [499.2]]), 0.1)
    here = [net.places[region.places[int(np.argmax(M1[r, list(region.places)]))]].name for r in range(2)]
    assert net.places[region.places[-1]].label == "none"
    assert here == [net.places[region.places[-1]].name, "p_a_499"]


def test_1000_bounded_eventuallys_name_their_places_as_before() -> None:
    """_unique resumes each base's suffix search: the names are those of the first-unused rule."""
    parts = [f"F[0,{0.5 + 0.04 * i:.2f}] a" for i in range(1000)]
    text = (
        f"plant pendulum\ninit q in [2.4, pi], qdot = 0\nhorizon 3\nprop a = abs(q) < 0.3\nformula {_balanced(parts)}\n"
    )
    net = compile_spec(parse_spec(text)).net
    names = set(net.place_names)
    assert len(names) == len(net.places) == 3003
    assert {"p_tau_a", "p_done_a"} | {f"p_tau_a_{k}" for k in range(2, 1001)} <= names
    assert "p_tau_a_1" not in names and "p_tau_a_1001" not in names


# ------------------------------------------------------------------ grouping


def _pairwise_groups(spec, names):
    """The grouping rule as it was: each proposition tested against every member of each group."""
    doms = spec.domains()
    groups: list[list[str]] = []
    for name in names:
        pred = spec.prop(name).pred
        for g in groups:
            if all(P.provably_disjoint(pred, spec.prop(m).pred, doms) for m in g):
                g.append(name)
                break
        else:
            groups.append([name])
    return tuple(tuple(g) for g in groups)


PREDICATES = [
    "q < -1",
    "q > 1",
    "-1 <= q <= 1",
    "abs(q) < 0.5",
    "q > 4",
    "q > 0",
    "qdot > 0",
    "qdot < -2 and q > 2",
    "q * q > 1",
    "0.5 < q < 0.7 or q > 3",
    "not (q > 0)",
    "q == 2",
]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from(PREDICATES), min_size=1, max_size=8), st.booleans())
def test_state_groups_are_those_of_the_pairwise_rule(preds: list[str], plant: bool) -> None:
    defs = "".join(f"prop p{i} = {p}\n" for i, p in enumerate(preds))
    spec = parse_spec(
        ("plant pendulum\n" if plant else "") + defs + f"formula {' & '.join(f'F p{i}' for i in range(len(preds)))}"
    )
    names = [f"p{i}" for i in range(len(preds))]
    assert state_groups(spec, names) == _pairwise_groups(spec, names)


# ------------------------------------------------------------------ region stepping


ATOMS = "abcde"


@st.composite
def specs(draw: st.DrawFn) -> tuple[str, CompileOptions]:
    preds = draw(st.lists(st.sampled_from(PREDICATES[:8]), min_size=1, max_size=5))
    atoms = ATOMS[: len(preds)]
    f = draw(strategies.formulas(atoms=atoms, interval=strategies.grid_intervals(0.5, 6), max_leaves=8))
    defs = "".join(f"prop {a} = {p}\n" for a, p in zip(atoms, preds, strict=True))
    options = CompileOptions(
        conjunction=draw(st.sampled_from(["literal", "active"])),
        violations=draw(st.sampled_from(["off", "permanent", "counted"])),
        clock=draw(st.sampled_from(["standard", "trial"])),
    )
    return f"plant pendulum(dt = 0.5)\nhorizon 6\n{defs}formula {f}\n", options


# states in and out of the pendulum's domain (q = 5: "q > 4" and "q > 1" hold together, a tie)
VALUES = [-5.0, -2.0, -1.0, -0.6, 0.0, 0.3, 0.6, 1.0, 2.0, 2.5, 3.5, 5.0]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    specs(),
    st.lists(st.tuples(st.sampled_from(VALUES), st.sampled_from([-3.0, 0.0, 1.0])), min_size=13, max_size=13),
    st.integers(0, 2**16),
)
def test_region_stepping_gives_the_markings_of_the_scanning_rule(spec_opts, states, seed) -> None:
    text, options = spec_opts
    try:
        rs = compile_spec(parse_spec(text), options)
    except MitlError:
        assume(False)
    rt = NetRuntime(rs)
    # every region net with two places or more is stepped by its region
    multi = [s for s, sub in enumerate(rs.net.subnets) if sub.role == "region" and len(sub.places) > 1]
    assert [s for s, _ in rt.rule.regions] == multi
    rng = np.random.default_rng(seed)
    x = np.array(states, dtype=float)[None].repeat(4, axis=0)
    x[1:] = x[1:][:, rng.permutation(len(states))]  # four runs, the same states in other orders
    M = rt.reset(x[:, 0])
    for k in range(len(states) - 1):
        tau = 0.5 * (k + 1) + (0.25 if k % 3 == 0 else 0.0)
        want = rt.step_scanning(M, x[:, k + 1], tau)
        got = rt.step_direct(M, x[:, k + 1], tau)
        np.testing.assert_array_equal(got, want)
        if rt.tables is not None and not rt.timed:
            np.testing.assert_array_equal(rt.step(M, x[:, k + 1], tau), want)
        M = want


def test_nets_copy_and_pickle() -> None:
    """Gymnasium deep-copies an environment's arguments and sweep workers pickle: an
    Incidence survives both, equal to itself."""
    import copy
    import pickle

    from mitlc.petri.compile import compile_spec
    from mitlc.spec.parse import load_spec

    rs = compile_spec(load_spec("pendulum/p2_avoid"))
    for other in (copy.deepcopy(rs), pickle.loads(pickle.dumps(rs)), copy.copy(rs)):
        assert other.net.pre == rs.net.pre and other.net.post == rs.net.post
        np.testing.assert_array_equal(other.net.D, rs.net.D)
