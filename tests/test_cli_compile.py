"""`mitlc compile` through click's CliRunner."""

from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import graphviz
import pytest
from click.testing import CliRunner

from mitlc.cli import main

ROOT = Path(__file__).resolve().parent.parent
P2 = str(ROOT / "specs" / "pendulum" / "p2_avoid.mitl")


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def test_text_summary() -> None:
    r = run("compile", P2)
    assert r.exit_code == 0, r.output
    assert "transitions (6):" in r.output
    assert "t1  p_kappa -> p_psi  when psi" in r.output
    assert "M0 = [0 0 1]" in r.output


def test_json_keys() -> None:
    r = run("compile", P2, "--format", "json")
    d = json.loads(r.output)
    assert {"places", "transitions", "D_minus", "D_plus", "D", "M0", "reward"} <= set(d)
    assert d["places"][0] == {"name": "p_kappa", "kind": "state", "subnet": 0, "label": "kappa"}
    assert set(d["transitions"][0]) >= {"name", "guard", "inputs", "outputs"}
    assert len(d["D"]) == 6 and len(d["D"][0]) == 3


def test_json_matrices_dense_or_arcs_only() -> None:
    """P2's net: t1 takes p_kappa (place 0) and puts p_psi (place 1); arcs only leaves the matrices out."""
    from mitlc.petri.export import DENSE_ENTRIES

    dense = json.loads(run("compile", P2, "--format", "json").output)
    assert dense["arcs"]["pre"][0] == [0, 0, 1] and dense["arcs"]["post"][0] == [0, 1, 1]
    assert len(dense["arcs"]["pre"]) == len(dense["arcs"]["post"]) == 6
    arcs = json.loads(run("compile", P2, "--format", "json", "--matrices", "arcs").output)
    assert not {"D_minus", "D_plus", "D"} & set(arcs) and arcs["arcs"] == dense["arcs"]
    assert json.loads(run("compile", P2, "--format", "json", "--matrices", "dense").output) == dense
    r = run("compile", P2, "--matrices", "dense")
    assert r.exit_code == 2 and r.output.strip() == "--matrices: error: --matrices applies to --format json, not text"
    assert f"{DENSE_ENTRIES:,} entries" in run("compile", "--help").output


def test_dot_has_clusters() -> None:
    r = run("compile", P2, "--format", "dot")
    assert r.exit_code == 0 and "subgraph cluster_0" in r.output


def test_pnml_is_ptnet(tmp_path: Path) -> None:
    out = tmp_path / "net.pnml"
    r = run("compile", P2, "--format", "pnml", "-o", str(out))
    assert r.exit_code == 0, r.output
    root = ET.parse(out).getroot()
    ns = {"p": "http://www.pnml.org/version-2009/grammar/pnml"}
    net = root.find("p:net", ns)
    assert net.get("type") == "http://www.pnml.org/version-2009/grammar/ptnet"
    assert len(net.findall(".//p:place", ns)) == 3
    assert len(net.findall(".//p:transition", ns)) == 6
    assert len(net.findall(".//p:arc", ns)) == 12
    assert {a.find("p:inscription/p:text", ns).text for a in net.findall(".//p:arc", ns)} == {"1"}


@pytest.mark.skipif(shutil.which("dot") is None, reason="no Graphviz dot (.ci/run installs it)")
def test_svg(tmp_path: Path) -> None:
    out = tmp_path / "net.svg"
    r = run("compile", P2, "--format", "svg", "-o", str(out))
    assert r.exit_code == 0, r.output
    assert out.read_text().lstrip().startswith(("<?xml", "<svg"))


def test_png_needs_output() -> None:
    r = run("compile", P2, "--format", "png")
    assert r.exit_code == 2 and "needs -o FILE" in r.output


def test_missing_dot_is_a_clear_message(tmp_path: Path, monkeypatch) -> None:
    def boom(*args, **kwargs):
        raise graphviz.ExecutableNotFound(["dot"])

    monkeypatch.setattr(graphviz.Digraph, "pipe", boom)
    out = tmp_path / "net.svg"
    r = run("compile", P2, "--format", "svg", "-o", str(out))
    assert r.exit_code == 2
    assert "'dot' program is not installed" in r.output and "apt-get install graphviz" in r.output
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_bad_spec_exit_2_no_traceback(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mitl"
    bad.write_text("prop k = q < 1\nformula F[2,1] k\n")
    out = tmp_path / "out.json"
    r = run("compile", str(bad), "--format", "json", "-o", str(out))
    assert r.exit_code == 2
    assert (
        r.output.splitlines()[0]
        == f"{bad}:2:11: error: inverted interval [2,1]: the lower end must not exceed the upper"
    )
    assert "Traceback" not in r.output and not out.exists()


def test_warning_for_unused_prop(tmp_path: Path) -> None:
    spec = tmp_path / "w.mitl"
    spec.write_text("prop a = x < 1\nprop b = x > 2\nformula G a\n")
    r = run("compile", str(spec))
    assert r.exit_code == 0
    assert f"{spec}:2:6: warning: proposition 'b' is never used" in r.output


def test_conjunction_option() -> None:
    r = run("compile", str(ROOT / "specs" / "pendulum" / "p4_alternate.mitl"), "--conjunction", "active")
    assert "min_active(" in r.output
