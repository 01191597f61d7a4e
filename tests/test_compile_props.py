"""Properties of the compiler over random formulas (depth <= 6, 4 propositions)."""

from __future__ import annotations

import re

import numpy as np
import strategies
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from mitlc.petri import reward as R
from mitlc.petri.compile import compile_spec
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_formula, parse_spec

PROPS = "prop a = x < 0\nprop b = x > 1\nprop c = y < 0\nprop d = 0 < x < 1 and y > 2\n"


def formulas(depth: int = 6) -> st.SearchStrategy[A.Formula]:
    """Formulas over the four propositions, intervals on a 0.5 s grid, nested at most ``depth``."""
    return strategies.formulas(atoms="abcd", interval=strategies.grid_intervals(0.5, 6), max_leaves=12).filter(
        lambda f: A.depth(f) <= depth
    )


def subnet_invariants(net) -> None:
    """Every sub-net holds one token, initially and after any firing."""
    for _s_idx, sub in enumerate(net.subnets):
        assert int(net.M0[list(sub.places)].sum()) == 1
        for t in sub.transitions:
            row = net.D[t]
            inside = row[list(sub.places)]
            assert inside.sum() == 0 and sorted(inside[inside != 0].tolist()) == [-1, 1]
            outside = np.delete(row, list(sub.places))
            assert not outside.any(), "a transition touches another sub-net"
    covered = sorted(i for sub in net.subnets for i in sub.places)
    assert covered == list(range(len(net.places)))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(formulas())
def test_random_formulas_compile(f: A.Formula) -> None:
    spec = parse_spec(PROPS + f"formula {f}\n", "random.mitl")
    assert spec.formula == f
    rs = compile_spec(spec)
    net = rs.net
    subnet_invariants(net)
    assert net.D.shape == (len(net.transitions), len(net.places))
    # the reward is finite on every one-step move from M0
    m0 = net.M0[None, :]
    moves = [m0]
    for t in range(len(net.transitions)):
        if (net.D_minus[t] <= net.M0).all():
            moves.append(net.fire(net.M0, np.eye(len(net.transitions), dtype=np.int64)[t])[None, :])
    now = np.concatenate(moves)
    prev = np.repeat(m0, len(now), axis=0)
    values = rs.reward.evaluate(prev, now)
    assert np.isfinite(values).all()
    lo, hi = R.bounds(rs.reward)  # and within the bounds the compiler's guarantees are built on
    assert (values >= lo - 1e-9).all() and (values <= hi + 1e-9).all()
    # the reward prints as text that names only the net's places
    text = str(rs.reward)
    assert set(re.findall(r"p_[A-Za-z0-9_<>=.]+", text)) <= set(net.place_names), text


@settings(max_examples=150, deadline=None)
@given(formulas(depth=4))
def test_reachable_markings_keep_one_token_per_subnet(f: A.Formula) -> None:
    rs = compile_spec(parse_spec(PROPS + f"formula {f}\n"))
    net = rs.net
    assume(np.prod([len(s.places) for s in net.subnets]) <= 4096)  # counted, not silently passed
    for m in net.reachable_markings():
        for sub in net.subnets:
            assert int(m[list(sub.places)].sum()) == 1


def test_size_grows_linearly() -> None:
    """Nested <-> would double the formula; shared sub-nets keep the net linear."""
    counts, sizes = [], []
    f: A.Formula = parse_formula("F a U b")
    for _ in range(6):
        f = A.Iff(f, A.Until(A.Eventually(A.Atom("c")), A.Atom("d")))
        sizes.append(A.size(parse_spec(PROPS + f"formula {f}\n").formula))
        counts.append(len(compile_spec(parse_spec(PROPS + f"formula {f}\n")).net.places))
    assert sizes[-1] == 6 * 3 + 2  # the formula as written grows linearly ...
    assert counts == [18] * 6  # ... and so does the net: the desugared copies share sub-nets
