"""Draw the package's pipeline, read off its imports: docs/figures/architecture.svg and .png.

    python docs/make_architecture.py       # from the repository root, about a second
    python docs/make_architecture.py --out DIR    # write architecture.svg / .png to DIR instead

Every module under ``mitlc/`` is read by the import reader of tests/test_layers.py (the
layer rule's own); every import of a ``mitlc`` module counts, the ones inside functions
too, and so does
``importlib.import_module("mitlc....")`` with a literal name (drawn dashed: the gym
wrapper's optional monitor).  A module belongs to the stage of the first folder under
``mitlc/`` (``errors.py`` and ``fileio.py`` are stages of one file);
``mitlc/__init__.py`` and ``__main__.py``, the public facade, are left out.  Each edge
runs from the imported stage to the importing one, the way the data flows; an edge
against the order of :data:`STAGES` is drawn red (tests/test_layers.py fails on it).
The base modules get no edges, only the number of stages that import them.
"""

from __future__ import annotations

import sys
from collections import defaultdict
from html import escape
from pathlib import Path

import graphviz

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.fileio import atomic_write

sys.path.insert(0, str(ROOT / "tests"))
from test_layers import FACADE, imported, modules, stage_of_file, stage_of_module  # the layer test's own reader

COMMAND = "python docs/make_architecture.py"
OUT = ROOT / "docs" / "figures" / "architecture"

STAGES: dict[str, tuple[str, str]] = {
    "plants": ("nothing", "Plant"),
    "spec": ("text", "Spec"),
    "petri": ("Spec", "RewardSystem"),
    "hybrid": ("Spec", "HybridAutomaton"),
    "monitor": ("Spec + traces", "MonitorResult"),
    "runtime": ("RewardSystem + state names", "NetRuntime"),
    "learn": ("RewardSystem | HybridAutomaton", "Sacpn, HybridLearner"),
    "sweep": ("Spec + grid", "ResultStore"),
    "gym": ("RewardSystem + gym.Env", "MitlRewardWrapper"),
    "verify": ("Policy + Spec + ranges", "bound, counterexamples"),
    "cli": ("argv", "files, exit code"),
}
"""The pipeline's stages in data-flow order: stage -> (what goes in, what comes out)."""
BASE = {"errors": "MitlError", "fileio": "atomic_write", "limits": "MAX_STEPS"}
"""The modules any stage may import: module -> what it offers."""

Deps = dict[tuple[str, str], list[tuple[str, bool]]]
"""(imported stage, importing stage) -> [("file:line", by importlib)]."""


def dependencies() -> Deps:
    deps: Deps = defaultdict(list)
    for path in modules():
        own = stage_of_file(path)
        if own in FACADE:
            continue
        for line, dotted, lazy in imported(path):
            other = stage_of_module(dotted)
            if other != own and (other in STAGES or other in BASE):
                deps[(other, own)].append((f"{path.relative_to(ROOT)}:{line}", lazy))
    return dict(deps)


def columns(deps: Deps) -> dict[str, int]:
    """Stage -> its column: one right of the furthest stage it imports (``plants``: 0)."""
    col: dict[str, int] = {}
    for name in STAGES:  # in pipeline order: the stages it imports have their columns already
        col[name] = 1 + max((col.get(src, -1) for src, dst in deps if dst == name), default=-1)
    return col


def label(name: str, detail: str) -> str:
    return f'<<b>{escape(name)}</b><br/><font point-size="10">{escape(detail)}</font>>'


def diagram(deps: Deps) -> graphviz.Digraph:
    note = "an arrow: the right stage imports the left one (data flows along it); dashed: by importlib only"
    g = graphviz.Digraph("mitlc", graph_attr={"rankdir": "LR", "ranksep": "0.6", "label": note, "fontsize": "10"})
    g.attr(fontname="Helvetica")
    g.attr("node", shape="box", style="rounded,filled", fillcolor="#eef3fb", fontname="Helvetica")
    g.attr("edge", color="#4a6fa5", arrowsize="0.7")
    col = columns(deps)
    for c in sorted(set(col.values())):
        with g.subgraph() as same:
            same.attr(rank="same")
            for name in (n for n in STAGES if col[n] == c):
                same.node(name, label(name, "{} -> {}".format(*STAGES[name])), tooltip=f"mitlc/{name}")
    with g.subgraph(name="cluster_base") as base:
        base.attr(label="base: any stage may import", fontsize="10", color="#bbbbbb")
        base.attr("node", fillcolor="#f4f4f4", color="#999999", fontcolor="#555555")
        for name, offers in BASE.items():
            users = sum(1 for src, dst in deps if src == name and dst in STAGES)
            base.node(name, label(name, f"{offers}; imported by {users} stages"))
    order = list(STAGES)
    for (src, dst), sites in deps.items():
        if src in STAGES and dst in STAGES:
            backwards = order.index(src) > order.index(dst)
            g.edge(
                src,
                dst,
                color="red" if backwards else "#4a6fa5",
                style="dashed" if all(lazy for _, lazy in sites) else "solid",
                tooltip=f"{dst} imports {src}: " + ", ".join(site for site, _ in sites),
            )
    return g


def main(argv: list[str] | None = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT.parent, help="folder for architecture.svg and .png")
    args = ap.parse_args(argv)
    g = diagram(dependencies())
    for fmt in ("svg", "png"):
        path = args.out / OUT.with_suffix(f".{fmt}").name
        atomic_write(path, g.pipe(format=fmt))
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
