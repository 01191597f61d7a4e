"""Render a compiled net with Graphviz.

:func:`to_digraph` returns a :class:`graphviz.Digraph` and writes nothing:
places are circles showing their initial tokens, transitions are black bars
labelled with their guards, and each sub-net is a cluster (state sub-nets
blue, timing sub-nets orange, violation sub-nets red).  :func:`render_bytes` runs the ``dot`` binary.

>>> from mitlc.spec.parse import parse_spec
>>> from mitlc.petri.compile import compile_spec
>>> g = to_digraph(compile_spec(parse_spec("prop a = x < 1\\nformula F G a")))
>>> "cluster_0" in g.source and "shape=circle" in g.source
True
"""

from __future__ import annotations

import graphviz

from mitlc.errors import InputError
from mitlc.petri.compile import RewardSystem

__all__ = ["to_digraph", "render_bytes"]

_COLORS = {
    "state": ("#e8f0fe", "#1a56db"),
    "timing": ("#fff4e5", "#c2410c"),
    "violation": ("#fde8e8", "#b91c1c"),
}


def _place_label(name: str, tokens: int) -> str:
    dots = "●" * tokens if tokens <= 3 else str(tokens)
    return f"{dots}" if dots else " "


def _title(rs: RewardSystem) -> str:
    """The formula, and under it what each inline predicate's name stands for."""
    lines = [str(rs.spec.formula)]
    lines += [f"{p.name}: {p.pred}" for p in rs.spec.props if p.inline]
    return "\n".join(lines)


def to_digraph(rs: RewardSystem, title: str | None = None) -> graphviz.Digraph:
    net = rs.net
    g = graphviz.Digraph(
        "net",
        graph_attr={
            "rankdir": "LR",
            "fontname": "Helvetica",
            "label": title if title is not None else _title(rs),
            "labelloc": "t",
            "fontsize": "16",
            "nodesep": "0.35",
            "ranksep": "0.45",
        },
    )
    g.attr("node", fontname="Helvetica")
    g.attr("edge", arrowsize="0.6")
    for s_idx, sub in enumerate(net.subnets):
        fill, line = _COLORS.get(sub.kind, ("#f3f4f6", "#374151"))
        with g.subgraph(name=f"cluster_{s_idx}") as c:
            c.attr(
                label=f"{sub.kind}: {sub.name}",
                style="rounded,filled",
                fillcolor=fill,
                color=line,
                fontcolor=line,
                fontsize="11",
            )
            for i in sub.places:
                p = net.places[i]
                c.node(
                    f"P{i}",
                    label=_place_label(p.name, int(net.M0[i])),
                    xlabel=p.name,
                    shape="circle",
                    width="0.45",
                    fixedsize="true",
                    style="filled",
                    fillcolor="white",
                    color=line,
                    fontsize="14",
                )
            for t_idx in sub.transitions:
                t = net.transitions[t_idx]
                c.node(
                    f"T{t_idx}",
                    label="",
                    xlabel=f"{t.name}: {t.guard}",
                    shape="box",
                    width="0.08",
                    height="0.4",
                    style="filled",
                    fillcolor="black",
                    fontsize="9",
                )
    index = {p.name: i for i, p in enumerate(net.places)}
    for t_idx, t in enumerate(net.transitions):
        for name in t.inputs:
            g.edge(f"P{index[name]}", f"T{t_idx}")
        for name in t.outputs:
            g.edge(f"T{t_idx}", f"P{index[name]}")
    return g


def render_bytes(rs: RewardSystem, fmt: str) -> bytes:
    """The net drawn as ``svg`` or ``png`` bytes (needs the Graphviz ``dot`` binary)."""
    try:
        return to_digraph(rs).pipe(format=fmt)
    except graphviz.ExecutableNotFound:
        raise InputError(
            "the Graphviz 'dot' program is not installed, so the net cannot be drawn",
            file=f"--format {fmt}",
            hint="install it (Debian/Ubuntu: sudo apt-get install graphviz; macOS: brew install graphviz), "
            "or use --format dot and render elsewhere",
        ) from None
