"""Exports read back by tools that are not mitlc: PNML by pm4py, JSON by a JSON Schema
validator (docs/net.schema.json), the graph by networkx."""

from __future__ import annotations

import copy
import json
from collections import Counter
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli import main
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.petri.export import to_dict, to_json, to_networkx, to_pnml
from mitlc.spec.parse import load_spec, parse_spec

ROOT = Path(__file__).resolve().parent.parent
SPECS = sorted((ROOT / "specs" / "pendulum").glob("*.mitl"))
SCHEMA = ROOT / "docs" / "net.schema.json"
IDS = [p.stem for p in SPECS]
VIOLATIONS = ("off", "permanent", "counted")

# pm4py warns that a net read from PNML has no final marking; reward nets have none.
pytestmark = pytest.mark.filterwarnings("ignore:the Petri net has been imported without a specified final marking")

# Specs beyond the thesis's five, so every sub-net role and reward node appears.
EXTRA = {
    "eventually_until": "prop a = x < 1\nprop b = x > 2\nformula F a & (a U b) & F[1,2] b",
    "active_min": "prop a = x < 1\nprop b = y > 0\noption conjunction = active\nformula F[0,1] a & G[1,2] b",
    "or_release": "prop a = x < 1\nprop b = y > 0\nformula (a R b) | G F a",
}


def test_there_are_five_thesis_specs_and_the_nested_timing_ones() -> None:
    assert [i for i in IDS if i.startswith("p")] == [
        "p1_swing_up",
        "p2_avoid",
        "p3_avoid_speed_limit",
        "p4_alternate",
        "p5_timed_visit",
    ]
    assert [i for i in IDS if i.startswith("n")] == [
        "n1_reach_in_time",
        "n2_hold_up",
        "n3_bounded_response",
        "n4_recurring_window",
    ]


def expected_net(rs):
    """Places, transitions, arcs (with weights) and the initial marking, from mitlc's matrices."""
    net = rs.net
    places = Counter(net.place_names)
    transitions = Counter(net.transition_names)
    arcs = Counter()
    for t, tname in enumerate(net.transition_names):
        for p, pname in enumerate(net.place_names):
            if net.D_minus[t, p]:
                arcs[(pname, tname, int(net.D_minus[t, p]))] += 1
            if net.D_plus[t, p]:
                arcs[(tname, pname, int(net.D_plus[t, p]))] += 1
    m0 = {name: int(v) for name, v in zip(net.place_names, net.M0, strict=True) if v}
    return places, transitions, arcs, m0


# ------------------------------------------------------------------ PNML through pm4py


@pytest.mark.parametrize("violations", VIOLATIONS)
@pytest.mark.parametrize("spec_path", SPECS, ids=IDS)
def test_pnml_read_back_by_pm4py(spec_path: Path, violations: str, tmp_path: Path) -> None:
    pm4py = pytest.importorskip("pm4py", reason="pm4py (the PNML reader) is not installed: pip install '.[test-extra]'")
    from pm4py.util.constants import PLACE_NAME_TAG

    spec = load_spec(spec_path)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))
    path = tmp_path / f"{spec_path.stem}.pnml"
    path.write_text(to_pnml(rs), encoding="utf-8")
    net, initial, final = pm4py.read_pnml(str(path))

    name = {p: p.properties[PLACE_NAME_TAG] for p in net.places}
    name.update({t: t.label for t in net.transitions})
    places = Counter(name[p] for p in net.places)
    transitions = Counter(t.label for t in net.transitions)
    arcs = Counter((name[a.source], name[a.target], a.weight) for a in net.arcs)
    m0 = {name[p]: n for p, n in initial.items()}

    want_places, want_transitions, want_arcs, want_m0 = expected_net(rs)
    assert places == want_places
    assert transitions == want_transitions
    assert arcs == want_arcs
    assert m0 == want_m0
    assert not final  # PNML has no final marking; mitlc writes none
    # one token per sub-net; an arc from each input and to each output
    assert sum(m0.values()) == len(rs.net.subnets)
    assert len(net.arcs) == sum(len(t.inputs) + len(t.outputs) for t in rs.net.transitions)
    # all but these have a top-level G part (n3's and n4's are inside timed obligations):
    if violations == "counted" and spec_path.stem not in ("p1_swing_up", "n3_bounded_response", "n4_recurring_window"):
        # its counter p_ok -> p_bad + p_count is a transition with two outputs
        assert any(len(t.outputs) == 2 for t in rs.net.transitions)


def test_pnml_of_problem_2_by_hand(tmp_path: Path) -> None:
    """The region net C-2: three places, a transition between every two of them."""
    pm4py = pytest.importorskip("pm4py", reason="pm4py is not installed: pip install '.[test-extra]'")
    from pm4py.util.constants import PLACE_NAME_TAG

    rs = compile_spec(load_spec(ROOT / "specs" / "pendulum" / "p2_avoid.mitl"))
    path = tmp_path / "p2.pnml"
    path.write_text(to_pnml(rs), encoding="utf-8")
    net, initial, _ = pm4py.read_pnml(str(path))
    places = {p.properties[PLACE_NAME_TAG] for p in net.places}
    assert places == {"p_kappa", "p_psi", "p_none_kappa_psi"}
    moves = {  # place -> transition -> place
        (a.source.properties[PLACE_NAME_TAG], b.target.properties[PLACE_NAME_TAG])
        for a in net.arcs
        for b in net.arcs
        if a.source in net.places and a.target is b.source
    }
    assert moves == {(p, q) for p in places for q in places if p != q}
    assert {p.properties[PLACE_NAME_TAG]: n for p, n in initial.items()} == {"p_none_kappa_psi": 1}


# ------------------------------------------------------------------ networkx


@pytest.mark.parametrize("violations", VIOLATIONS)
@pytest.mark.parametrize("spec_path", SPECS, ids=IDS)
def test_networkx_is_bipartite_with_documented_attributes(spec_path: Path, violations: str) -> None:
    spec = load_spec(spec_path)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))
    net = rs.net
    g = to_networkx(rs)
    assert isinstance(g, nx.DiGraph)
    assert g.graph["formula"] == str(rs.spec.formula)
    places = {n for n, d in g.nodes(data=True) if d["bipartite"] == 0}
    transitions = {n for n, d in g.nodes(data=True) if d["bipartite"] == 1}
    assert places == set(net.place_names) and transitions == set(net.transition_names)
    assert nx.is_bipartite(g)
    assert nx.bipartite.is_bipartite_node_set(g.to_undirected(), places)
    assert all((u in places) != (v in places) for u, v in g.edges)  # arcs join a place and a transition
    for i, p in enumerate(net.places):
        assert g.nodes[p.name] == {
            "bipartite": 0,
            "kind": p.kind,
            "tokens": int(net.M0[i]),
            "subnet": p.subnet,
            "label": p.label,
        }
    for t in net.transitions:
        assert g.nodes[t.name] == {"bipartite": 1, "guard": str(t.guard), "subnet": t.subnet}
    # the arcs are exactly D- (place -> transition) and D+ (transition -> place), weight 1
    _, _, want_arcs, _ = expected_net(rs)
    assert Counter((u, v, d["weight"]) for u, v, d in g.edges(data=True)) == want_arcs
    # the biadjacency matrix is the incidence: rows transitions, columns places
    order = list(net.transition_names) + list(net.place_names)
    A = nx.to_numpy_array(g, nodelist=order, dtype=int)
    n_t = len(net.transitions)
    np.testing.assert_array_equal(A[:n_t, n_t:], net.D_plus)
    np.testing.assert_array_equal(A[n_t:, :n_t].T, net.D_minus)


# ------------------------------------------------------------------ JSON and its schema


@pytest.fixture(scope="module")
def validator():
    jsonschema = pytest.importorskip("jsonschema", reason="jsonschema is not installed: pip install '.[test]'")
    schema = json.loads(SCHEMA.read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def cli_json(spec: Path, *extra: str) -> dict:
    r = CliRunner().invoke(main, ["compile", str(spec), "--format", "json", *extra])
    assert r.exit_code == 0, r.output
    return json.loads(r.output)


@pytest.mark.parametrize("spec_path", SPECS, ids=IDS)
def test_shaped_reward_json_validates_against_the_schema(spec_path: Path, validator) -> None:
    d = cli_json(spec_path, "--reward", "shaped", "--violations", "permanent")
    assert [f"{list(e.absolute_path)}: {e.message}" for e in validator.iter_errors(d)] == []
    assert d["options"]["reward"] == "shaped"
    graded = []
    stack = [d["reward_tree"]]
    while stack:
        node = stack.pop()
        if node["op"] == "graded":
            graded.append(node)
        stack.extend(v for v in node.values() if isinstance(v, dict))
        stack.extend(a for a in node.get("args", ()))
    assert graded  # every spec's propositions are graded
    assert all(n["flat"]["op"] == "sum" for n in graded)  # each replaces its p_a - p_not_a


@pytest.mark.parametrize("violations", VIOLATIONS)
@pytest.mark.parametrize("conjunction", ["literal", "active"])
@pytest.mark.parametrize("spec_path", SPECS, ids=IDS)
def test_cli_json_validates_against_the_schema(spec_path: Path, conjunction: str, violations: str, validator) -> None:
    d = cli_json(spec_path, "--conjunction", conjunction, "--violations", violations)
    errors = [f"{list(e.absolute_path)}: {e.message}" for e in validator.iter_errors(d)]
    assert errors == []
    spec = load_spec(spec_path)
    assert d["options"] == {
        "conjunction": conjunction,
        "violations": violations,
        "clock": spec.option("clock"),
        "reward": spec.option("reward"),
    }
    assert (d["penalty"] > 0) == (violations != "off")
    rs = compile_spec(spec, CompileOptions.from_spec(spec, conjunction=conjunction, violations=violations))
    assert d == json.loads(to_json(rs))
    check_consistent(d)


@pytest.mark.parametrize("name", sorted(EXTRA))
def test_every_subnet_role_and_reward_node_validates(name: str, validator) -> None:
    d = to_dict(compile_spec(parse_spec(EXTRA[name])))
    assert list(validator.iter_errors(d)) == []
    check_consistent(d)


def test_the_extra_specs_cover_every_role_and_op(validator) -> None:
    roles, kinds, ops = set(), set(), set()
    for spec, violations in [*((p, v) for p in SPECS for v in VIOLATIONS), *((e, "off") for e in EXTRA.values())]:
        parsed = load_spec(spec) if isinstance(spec, Path) else parse_spec(spec)
        reward = "shaped" if violations == "permanent" else None  # the graded leaves too
        d = to_dict(compile_spec(parsed, CompileOptions.from_spec(parsed, violations=violations, reward=reward)))
        roles |= {s["role"] for s in d["subnets"]}
        kinds |= {p["kind"] for p in d["places"]}
        stack = [d["reward_tree"]]
        while stack:
            node = stack.pop()
            ops.add(node["op"])
            stack.extend(node.get("args", []))
            stack.extend(node[k] for k in ("gate", "expr", "arg", "flat") if k in node)
    schema = validator.schema
    assert roles == set(schema["properties"]["subnets"]["items"]["properties"]["role"]["enum"])
    assert kinds == set(schema["properties"]["places"]["items"]["properties"]["kind"]["enum"])
    documented = set()
    for branch in schema["$defs"]["rexpr"]["oneOf"]:
        op = branch["properties"]["op"]
        documented |= {op["const"]} if "const" in op else set(op["enum"])
    assert ops == documented


def check_consistent(d: dict) -> None:
    """What a schema cannot say: shapes and cross-references agree."""
    n_t, n_p = len(d["transitions"]), len(d["places"])
    for key in ("D_minus", "D_plus", "D"):
        assert np.shape(d[key]) == (n_t, n_p) or (n_t == 0 and d[key] == [])
    np.testing.assert_array_equal(np.array(d["D"]), np.array(d["D_plus"]) - np.array(d["D_minus"]))
    assert len(d["M0"]) == n_p
    names = [p["name"] for p in d["places"]]
    assert len(set(names)) == n_p
    for s_idx, s in enumerate(d["subnets"]):
        assert sum(d["M0"][names.index(p)] for p in s["places"]) == 1
        assert all(d["places"][names.index(p)]["subnet"] == s_idx for p in s["places"])
    for t_idx, t in enumerate(d["transitions"]):
        for p in t["inputs"]:
            assert d["D_minus"][t_idx][names.index(p)] == 1
        for p in t["outputs"]:
            assert d["D_plus"][t_idx][names.index(p)] == 1


@pytest.mark.parametrize(
    ("break_it", "path"),
    [
        (lambda d: d.pop("M0"), []),
        (lambda d: d["places"][0].update(kind="clock"), ["places", 0, "kind"]),
        (lambda d: d["transitions"][0].update(name="fire"), ["transitions", 0, "name"]),
        (lambda d: d["D_minus"][0].__setitem__(0, 2), ["D_minus", 0, 0]),
        (lambda d: d.update(reward_tree={"op": "pow", "args": []}), ["reward_tree"]),
        (lambda d: d.update(extra=1), []),
    ],
)
def test_the_schema_rejects_broken_documents(break_it, path: list, validator) -> None:
    d = copy.deepcopy(to_dict(compile_spec(load_spec(SPECS[1]))))
    break_it(d)
    errors = list(validator.iter_errors(d))
    assert errors and any(list(e.absolute_path) == path for e in errors)
