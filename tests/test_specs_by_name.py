"""Shipped specs by name: ``mitlc specs`` lists them and every command takes a name as a path."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from mitlc.cli.main import main
from mitlc.spec.library import find, shipped_specs
from mitlc.spec.parse import load_spec

ROOT = Path(__file__).resolve().parent.parent
FILES = sorted(p.relative_to(ROOT / "specs").with_suffix("").as_posix() for p in (ROOT / "specs").rglob("*.mitl"))


def test_every_shipped_file_has_a_name_and_the_same_text() -> None:
    assert list(shipped_specs()) == FILES
    for name in FILES:
        assert find(name).read_text() == (ROOT / "specs" / f"{name}.mitl").read_text()
    for alias in ("pendulum/p2_avoid.mitl", "specs/pendulum/p2_avoid.mitl", "mitlc:pendulum/p2_avoid.mitl"):
        assert find(alias).name == "pendulum/p2_avoid"
    assert find("pendulum/nope") is None


def test_commands_take_a_name_from_any_folder(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # no specs/ here
    runner = CliRunner()
    by_name = runner.invoke(main, ["compile", "pendulum/p2_avoid", "--format", "json"])
    assert by_name.exit_code == 0, by_name.output
    by_path = runner.invoke(main, ["compile", str(ROOT / "specs/pendulum/p2_avoid.mitl"), "--format", "json"])
    strip = lambda out: out.split("\n", 2)[2]  # noqa: E731 - the first line names the spec
    assert strip(by_name.output) == strip(by_path.output)
    assert '"spec": "mitlc:pendulum/p2_avoid.mitl"' in by_name.output
    listed = runner.invoke(main, ["specs"])
    assert listed.exit_code == 0 and [line.split()[0] for line in listed.output.splitlines()] == FILES
    shown = runner.invoke(main, ["specs", "pendulum/p5_timed_visit"])
    assert shown.output == (ROOT / "specs/pendulum/p5_timed_visit.mitl").read_text()
    auto = runner.invoke(main, ["automaton", "mass_damper/overshoot", "--format", "json"])
    assert auto.exit_code == 0, auto.output


def test_a_file_of_that_name_wins_and_unknown_names_say_where_to_look(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "pendulum").mkdir()
    (tmp_path / "pendulum" / "p2_avoid").write_text("prop a = x < 1\nformula G a\n")
    assert str(load_spec("pendulum/p2_avoid").formula) == "G a"
    r = CliRunner().invoke(main, ["compile", "pendulum/p2_avoidx"])
    assert r.exit_code == 2
    assert "pendulum/p2_avoidx: error: cannot read spec" in r.output and "mitlc specs lists them" in r.output
    r = CliRunner().invoke(main, ["specs", "pendulum/p2_avoidx"])
    assert r.exit_code == 2 and "no shipped spec 'pendulum/p2_avoidx'" in r.output


def test_an_installed_wheel_finds_its_own_copy(tmp_path, monkeypatch) -> None:
    """In site-packages there is no checkout: the specs are the package data next to mitlc/."""
    import importlib.util
    import shutil
    import sys

    site = tmp_path / "site"
    (site / "mitlc" / "spec").mkdir(parents=True)
    (site / "mitlc" / "specs" / "cart").mkdir(parents=True)
    shutil.copy(ROOT / "mitlc" / "spec" / "library.py", site / "mitlc" / "spec" / "library.py")
    (site / "mitlc" / "specs" / "cart" / "reach.mitl").write_text("# reach it\nprop a = x < 1\nformula F a\n")
    spec = importlib.util.spec_from_file_location("wheel_library", site / "mitlc" / "spec" / "library.py")
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "wheel_library", module)  # dataclasses look their module up
    spec.loader.exec_module(module)
    assert list(module.shipped_specs()) == ["cart/reach"]
    assert module.find("cart/reach.mitl").summary() == "reach it"
