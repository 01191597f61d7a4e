"""Compile a spec from Python, print its reward and write its net as DOT and SVG.

    python examples/compile_and_render.py                       # problem 2 into ./out
    python examples/compile_and_render.py specs/pendulum/p5_timed_visit.mitl --out /tmp/p5

It writes ``<out>/<spec>.dot`` (Graphviz source, always), ``<out>/<spec>.svg``
(needs Graphviz's ``dot`` program) and ``<out>/<spec>.json`` (the net as data,
see docs/net.schema.json).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import mitlc
from mitlc.petri.export import to_json
from mitlc.petri.render import render_bytes, to_digraph

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec", nargs="?", default=str(ROOT / "specs" / "pendulum" / "p2_avoid.mitl"))
    parser.add_argument("--out", default="out", help="directory to write into (created if missing)")
    args = parser.parse_args(argv)

    try:
        spec = mitlc.load_spec(args.spec)
        rs = mitlc.compile_spec(spec)
    except mitlc.MitlError as err:  # a bad spec: one clear line, the source line and a caret
        print(err.render(), file=sys.stderr)
        return 2

    net = rs.net
    print(f"formula:  {spec.formula}")
    print(f"sub-nets: {', '.join(s.name for s in net.subnets)}")
    print(f"places:   {', '.join(net.place_names)}")
    print(f"M0:       {net.M0.tolist()}")
    for t in net.transitions:
        print(f"  {t.name}: {t.inputs[0]} -> {t.outputs[0]} when {t.guard}")
    print(f"reward:   {rs.reward}")

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = Path(args.spec).stem
    written = []
    (out / f"{stem}.dot").write_text(to_digraph(rs).source, encoding="utf-8")
    (out / f"{stem}.json").write_text(to_json(rs), encoding="utf-8")
    written += [f"{stem}.dot", f"{stem}.json"]
    try:
        (out / f"{stem}.svg").write_bytes(render_bytes(rs, "svg"))
        written.append(f"{stem}.svg")
    except mitlc.InputError as err:  # Graphviz's dot is not installed
        print(f"no SVG: {err.message}", file=sys.stderr)
    print(f"wrote {', '.join(written)} to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
