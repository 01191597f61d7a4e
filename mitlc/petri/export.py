"""Exports of a compiled reward system: text, JSON, PNML and networkx.

All functions are pure: they return strings or objects and write nothing.

>>> from mitlc.spec.parse import parse_spec
>>> from mitlc.petri.compile import compile_spec
>>> rs = compile_spec(parse_spec("prop a = x < 1\\nformula G a"))
>>> import json; d = json.loads(to_json(rs))
>>> [p["name"] for p in d["places"]], d["D"], d["arcs"]["pre"]
(['p_a', 'p_not_a'], [[-1, 1], [1, -1]], [[0, 0, 1], [1, 1, 1]])
>>> g = to_networkx(rs); sorted(g.nodes)
['p_a', 'p_not_a', 't1', 't2']
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from mitlc.fileio import json_text
from mitlc.petri import reward as R
from mitlc.petri.compile import RewardSystem
from mitlc.spec import ast as A

if TYPE_CHECKING:
    import networkx as nx

__all__ = [
    "MATRICES",
    "DENSE_ENTRIES",
    "dense_wanted",
    "to_dict",
    "to_json",
    "to_text",
    "to_pnml",
    "to_networkx",
    "reward_tree",
    "PNML_NS",
    "PTNET_TYPE",
]

TEXT_TABLE_PLACES = 64
"""The text summary prints ``D`` as a table up to this many places (columns) ..."""
TEXT_TABLE_ENTRIES = 50_000
"""... and this many entries (transitions x places); past either, it says the size instead (the arcs are listed)."""

DENSE_ENTRIES = 50_000
"""JSON carries the dense matrices ``D_minus``, ``D_plus`` and ``D`` by default up to this many entries
(transitions x places) each; past it only the arcs, which stay linear in the net's size."""

MATRICES = ("auto", "dense", "arcs")
"""How JSON writes the incidence: ``arcs`` only, ``dense`` matrices too, or ``auto`` (dense up to
:data:`DENSE_ENTRIES`)."""

PNML_NS = "http://www.pnml.org/version-2009/grammar/pnml"
PTNET_TYPE = "http://www.pnml.org/version-2009/grammar/ptnet"


def reward_tree(e: R.RExpr) -> dict[str, Any]:
    """The reward expression as nested dicts (``op`` and its operands)."""
    if isinstance(e, R.Const):
        return {"op": "const", "value": e.value}
    if isinstance(e, R.Tokens):
        return {"op": "tokens", "places": list(e.names), "when": "k" if e.prev else "k+1"}
    if isinstance(e, R.Gated):
        return {"op": "gated", "gate": reward_tree(e.gate), "expr": reward_tree(e.expr)}
    if isinstance(e, R.Neg):
        return {"op": "neg", "arg": reward_tree(e.arg)}
    if isinstance(e, R.Graded):
        return {"op": "graded", "atom": e.atom, "negated": e.negated, "mix": e.mix, "flat": reward_tree(e.flat)}
    if isinstance(e, R.Min):
        return {"op": "min_active" if e.active else "min", "args": [reward_tree(c) for c in e.children]}
    name = {R.Sum: "sum", R.Prod: "prod", R.Max: "max"}[type(e)]
    return {"op": name, "args": [reward_tree(c) for c in e.children]}


def to_dict(rs: RewardSystem, matrices: str = "auto") -> dict[str, Any]:
    """Everything about the compiled net as plain JSON-able data (docs/net.schema.json).

    ``arcs`` always holds ``D-`` and ``D+`` as ``[transition, place, weight]`` triples (indices
    into ``transitions`` and ``places``); the dense ``D_minus``, ``D_plus`` and ``D`` are there too
    when :func:`dense_wanted` says so (``matrices``: one of :data:`MATRICES`).
    """
    d = _dict(rs, matrices)
    d["arcs"] = {"pre": _triples(rs.net.pre), "post": _triples(rs.net.post)}
    for name in _MATRICES:
        if name in d:
            d[name] = getattr(rs.net, name).tolist()
    return d


def dense_wanted(rs: RewardSystem, matrices: str = "auto") -> bool:
    """Whether JSON carries the dense matrices: ``dense``, or ``auto`` on a net of at most
    :data:`DENSE_ENTRIES` entries (transitions x places).

    >>> from mitlc.spec.parse import parse_spec
    >>> from mitlc.petri.compile import compile_spec
    >>> rs = compile_spec(parse_spec("prop a = x < 1\\nformula G a"))
    >>> [dense_wanted(rs, m) for m in MATRICES]
    [True, True, False]
    """
    if matrices not in MATRICES:
        raise ValueError(f"matrices must be one of {', '.join(MATRICES)}, not {matrices!r}")
    if matrices != "auto":
        return matrices == "dense"
    T, P = rs.net.pre.shape
    return T * P <= DENSE_ENTRIES


def _triples(inc: Any) -> list[list[int]]:
    rows = np.repeat(np.arange(inc.shape[0]), np.diff(inc.indptr))
    return np.stack([rows, inc.indices, inc.data], axis=1).astype(int).tolist()


_MATRICES = ("D_minus", "D_plus", "D")


def _dict(rs: RewardSystem, matrices: str) -> dict[str, Any]:
    """:func:`to_dict` with the arcs and each dense matrix (if wanted) a placeholder: :func:`to_json`
    writes them itself."""
    net = rs.net
    dense = dense_wanted(rs, matrices)
    return {
        "spec": rs.spec.path,
        "formula": str(rs.spec.formula),
        "normal_form": str(rs.normal_form),
        "options": {
            "conjunction": rs.options.conjunction,
            "violations": rs.options.violations,
            "clock": rs.options.clock,
            "reward": rs.options.reward,
        },
        "penalty": rs.penalty,
        "places": [{"name": p.name, "kind": p.kind, "subnet": p.subnet, "label": p.label} for p in net.places],
        "transitions": [
            {
                "name": t.name,
                "guard": str(t.guard),
                "inputs": list(t.inputs),
                "outputs": list(t.outputs),
                "subnet": t.subnet,
                "age": next((_interval_text(g.age) for g in t.guard.terms if g.age is not None), None),
                "event": next((g.event for g in t.guard.terms if g.event is not None), None),
            }
            for t in net.transitions
        ],
        "subnets": [
            {
                "name": s.name,
                "kind": s.kind,
                "role": s.role,
                "places": [net.places[i].name for i in s.places],
                "transitions": [net.transitions[i].name for i in s.transitions],
                "counters": [net.places[i].name for i in s.counters],
                "formula": s.formula,
            }
            for s in net.subnets
        ],
        "arcs": _placeholder("arcs"),
        **({name: _placeholder(name) for name in _MATRICES} if dense else {}),
        "M0": net.M0.tolist(),
        "reward": str(rs.reward),
        "reward_tree": reward_tree(rs.reward),
        "obligations": [
            {
                "formula": str(tn.tree.formula),
                "nodes": [
                    {
                        "op": n.op,
                        "children": list(n.children),
                        "formula": str(n.formula),
                        "interval": _interval_text(n.interval) if n.temporal else None,
                        "subnet": dict(tn.subnets).get(i),
                    }
                    for i, n in enumerate(tn.tree.nodes)
                ],
            }
            for tn in rs.timed
        ],
    }


def _interval_text(i: A.Interval) -> str:
    lo = "[" if i.lo_closed else "("
    hi = ")" if math.isinf(i.hi) or not i.hi_closed else "]"
    return f"{lo}{A.fmt_number(i.lo)},{'inf' if math.isinf(i.hi) else A.fmt_number(i.hi)}{hi}"


def to_json(rs: RewardSystem, matrices: str = "auto") -> str:
    """The net as strict JSON (docs/net.schema.json); a non-finite number would be null.

    The data is :func:`to_dict`'s, indented by two, but the arcs (one triple per line) and the
    dense matrices (one entry per line, as ``json.dumps(indent=2)`` writes them) are written by
    :func:`_arcs_json` and :func:`_matrix_json`, not walked number by number by the JSON encoder.

    >>> from mitlc.spec.parse import parse_spec
    >>> from mitlc.petri.compile import compile_spec
    >>> rs = compile_spec(parse_spec("prop a = x < 1\\nformula F[0,1] a & G a"))
    >>> all(json.loads(to_json(rs, m)) == to_dict(rs, m) for m in MATRICES)
    True
    >>> to_json(rs).replace(_matrix_json(rs.net.D, "  "), "") == to_json(rs)
    False
    """
    data = _dict(rs, matrices)
    text = json_text(data, indent=2, ensure_ascii=False)
    pieces = {"arcs": _arcs_json(rs.net.pre, rs.net.post, "  ")}
    pieces.update({name: _matrix_json(getattr(rs.net, name), "  ") for name in _MATRICES if name in data})
    for name, piece in pieces.items():
        token = json.dumps(_placeholder(name))
        assert text.count(token) == 1
        text = text.replace(token, piece)
    return text


def _arcs_json(pre: Any, post: Any, indent: str) -> str:
    """``{"pre": ..., "post": ...}`` with one ``[transition, place, weight]`` triple per line.

    >>> from mitlc.petri.net import Incidence
    >>> a = Incidence.from_dense(np.array([[1, 0], [0, 1]]))
    >>> json.loads(_arcs_json(a, Incidence.from_dense(np.zeros((2, 2), int)), ""))
    {'pre': [[0, 0, 1], [1, 1, 1]], 'post': []}
    """
    inner, cell = indent + "  ", indent + "    "

    def listed(inc: Any) -> str:
        triples = _triples(inc)
        if not triples:
            return "[]"
        return "[\n" + ",\n".join(f"{cell}[{t}, {p}, {w}]" for t, p, w in triples) + "\n" + inner + "]"

    return "{\n" + f'{inner}"pre": {listed(pre)},\n{inner}"post": {listed(post)}\n' + indent + "}"


def _placeholder(name: str) -> str:
    return f"\0mitlc-matrix-{name}\0"  # no spec text can hold a NUL (json writes it \u0000)


def _matrix_json(a: np.ndarray, indent: str) -> str:
    """``a`` (2-D integers) as ``json.dumps(a.tolist(), indent=2)`` writes it at ``indent``.

    >>> a = np.array([[0, -1], [1, 0]])
    >>> _matrix_json(a, "  ") == json.dumps({"D": a.tolist()}, indent=2)[len('{\\n  "D": '):-2]
    True
    >>> _matrix_json(np.zeros((0, 3), int), ""), _matrix_json(np.zeros((2, 0), int), "")
    ('[]', '[\\n  [],\\n  []\\n]')
    """
    rows, cols = a.shape
    if rows == 0:
        return "[]"
    inner, cell = indent + "  ", indent + "    "
    if cols == 0:
        return "[\n" + ",\n".join([inner + "[]"] * rows) + "\n" + indent + "]"
    lo, hi = int(a.min()), int(a.max())
    if hi - lo <= 1024:  # arc weights: a few small integers, looked up by offset (no sort)
        values, where = np.arange(lo, hi + 1), a - lo
    else:  # pragma: no cover - no compiled net has such weights
        values, where = np.unique(a, return_inverse=True)
    cells = np.array([cell + str(int(v)) for v in values], dtype=object)[where.reshape(rows, cols)]
    lines = [inner + "[\n" + ",\n".join(row) + "\n" + inner + "]" for row in cells.tolist()]
    return "[\n" + ",\n".join(lines) + "\n" + indent + "]"


def to_text(rs: RewardSystem) -> str:
    """A readable summary: places, transitions with guards, D, M0 and the reward."""
    net = rs.net
    out = []
    if rs.spec.path:
        out.append(f"spec:        {rs.spec.path}")
    out.append(f"formula:     {rs.spec.formula}")
    out.append(f"normal form: {rs.normal_form}")
    if rs.spec.props:
        out.append("")
        out.append(f"propositions ({len(rs.spec.props)}):")
        nw = max(len(d.name) for d in rs.spec.props)
        for d in rs.spec.props:
            out.append(f"  {d.name:{nw}}  {d.pred}{'  (inline)' if d.inline else ''}")
    out.append("")
    out.append(f"sub-nets ({len(net.subnets)}):")
    for i, s in enumerate(net.subnets):
        places = ", ".join(net.places[j].name for j in s.places)
        what = f"  [{s.formula}]" if s.formula else ""
        out.append(f"  {i}  {s.kind:9}  {s.role:10}  {places}{what}")
    out.append("")
    out.append(f"places ({len(net.places)}):")
    pw = max((len(p.name) for p in net.places), default=1)
    for i, p in enumerate(net.places):
        out.append(f"  {p.name.ljust(pw)}  {p.kind:9}  sub-net {p.subnet}  M0={int(net.M0[i])}")
    out.append("")
    out.append(f"transitions ({len(net.transitions)}):")
    tw = max((len(t.name) for t in net.transitions), default=1)
    for t in net.transitions:
        arc = f"{', '.join(t.inputs)} -> {', '.join(t.outputs)}"
        out.append(f"  {t.name.ljust(tw)}  {arc}  when {t.guard}")
    out.append("")
    out.append("D = D+ - D-  (rows: transitions, columns: places)")
    T, P = len(net.transitions), len(net.places)
    if T and (P > TEXT_TABLE_PLACES or T * P > TEXT_TABLE_ENTRIES):  # a table nobody reads, quadratic in size
        out.append(
            f"  {T:,} x {P:,}, too big for a table: each transition's row is its arcs above "
            f"({net.pre.nnz + net.post.nnz:,} arcs; --format json --matrices dense has the matrices)"
        )
    elif net.transitions:
        widths = [len(p.name) for p in net.places]
        out.append("  " + " " * tw + "  " + "  ".join(p.name for p in net.places))
        row = np.zeros(len(net.places), dtype=np.int64)
        for k, tr in enumerate(net.transitions):  # each row from the sparse D- and D+, not a dense D
            row[:] = 0
            for sign, inc in ((1, net.post), (-1, net.pre)):
                cols, vals = inc.row(k)
                row[cols] += sign * vals
            cells = "  ".join(f"{int(v):>{w}d}" for v, w in zip(row.tolist(), widths, strict=True))
            out.append(f"  {tr.name.ljust(tw)}  {cells}")
    else:
        out.append("  (no transitions)")
    out.append("")
    out.append(f"M0 = [{' '.join(str(int(v)) for v in net.M0)}]")
    out.append("")
    out.append("reward r(M_k, M_k+1):")
    out.append(f"  {rs.reward}")
    out.append("  (p = tokens in place p at step k+1, ~p = at step k)")
    if rs.grader is not None:
        what = "s_a = (p_a - p_not_a + g_a) / 2, " if rs.options.reward == "shaped" else ""
        out.append(f"  (reward {rs.options.reward}: {what}g_a = robustness of a over the state bounds, in [-1, 1])")
    if rs.paid_by_monitor:
        out.append(f"  (reward {rs.options.reward}: the learner is paid by the monitor instead; this is the net's own)")
    return "\n".join(out) + "\n"


def to_pnml(rs: RewardSystem) -> str:
    """A standard place/transition net in PNML (2009 grammar, type ptnet).

    Guards and place kinds travel in ``toolspecific`` elements, which other
    tools ignore.
    """
    import xml.etree.ElementTree as ET  # here: the tables' key (mitlc check --net) imports this module too

    ET.register_namespace("", PNML_NS)
    q = lambda tag: f"{{{PNML_NS}}}{tag}"  # noqa: E731
    root = ET.Element(q("pnml"))
    net_el = ET.SubElement(root, q("net"), id="net1", type=PTNET_TYPE)
    name = ET.SubElement(net_el, q("name"))
    ET.SubElement(name, q("text")).text = str(rs.spec.formula)
    page = ET.SubElement(net_el, q("page"), id="page1")
    net = rs.net
    ids = {}
    for i, p in enumerate(net.places):
        pid = f"p{i}"
        ids[p.name] = pid
        el = ET.SubElement(page, q("place"), id=pid)
        n = ET.SubElement(el, q("name"))
        ET.SubElement(n, q("text")).text = p.name
        m = ET.SubElement(el, q("initialMarking"))
        ET.SubElement(m, q("text")).text = str(int(net.M0[i]))
        tool = ET.SubElement(el, q("toolspecific"), tool="mitlc", version="1")
        ET.SubElement(tool, q("kind")).text = p.kind
    arc_id = 0
    for t in net.transitions:
        el = ET.SubElement(page, q("transition"), id=t.name)
        n = ET.SubElement(el, q("name"))
        ET.SubElement(n, q("text")).text = t.name
        tool = ET.SubElement(el, q("toolspecific"), tool="mitlc", version="1")
        ET.SubElement(tool, q("guard")).text = str(t.guard)
        for src, dst in [(ids[p], t.name) for p in t.inputs] + [(t.name, ids[p]) for p in t.outputs]:
            arc_id += 1
            a = ET.SubElement(page, q("arc"), id=f"a{arc_id}", source=src, target=dst)
            ins = ET.SubElement(a, q("inscription"))
            ET.SubElement(ins, q("text")).text = "1"
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def to_networkx(rs: RewardSystem) -> nx.DiGraph:
    """The net as a bipartite :class:`networkx.DiGraph`.

    Nodes are named after the places and transitions.  Place nodes have
    ``bipartite=0``, ``kind`` ("state" or "timing"), ``tokens`` (M0),
    ``subnet`` (index into ``net.subnets``) and ``label``; transition nodes
    ``bipartite=1``, ``guard`` (text) and ``subnet``; every arc has
    ``weight=1`` and joins a place and a transition (``D-``: place ->
    transition, ``D+``: transition -> place).  The graph's ``formula`` is the
    spec's formula.

    >>> from mitlc.spec.parse import parse_spec
    >>> from mitlc.petri.compile import compile_spec
    >>> g = to_networkx(compile_spec(parse_spec("prop a = x < 1\\nformula G a")))
    >>> g.nodes["p_a"]
    {'bipartite': 0, 'kind': 'state', 'tokens': 0, 'subnet': 0, 'label': 'a'}
    >>> g.nodes["t1"], list(g.edges("t1", data=True))
    ({'bipartite': 1, 'guard': '!a', 'subnet': 0}, [('t1', 'p_not_a', {'weight': 1})])
    """
    import networkx as nx  # only here: the rest of the exports (and mitlc check --net's table key) need none

    net = rs.net
    g = nx.DiGraph(formula=str(rs.spec.formula))
    for i, p in enumerate(net.places):
        g.add_node(p.name, bipartite=0, kind=p.kind, tokens=int(net.M0[i]), subnet=p.subnet, label=p.label)
    for t in net.transitions:
        g.add_node(t.name, bipartite=1, guard=str(t.guard), subnet=t.subnet)
        for name in t.inputs:
            g.add_edge(name, t.name, weight=1)
        for name in t.outputs:
            g.add_edge(t.name, name, weight=1)
    return g
