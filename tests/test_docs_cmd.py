"""``mitlc docs``: the pages where mitlc is installed, and the --help texts that point to them."""

from __future__ import annotations

import re
from pathlib import Path

import click
from click.testing import CliRunner

from mitlc.cli.docs import docs_folder, pages
from mitlc.cli.main import main

ROOT = Path(__file__).resolve().parent.parent


def test_lists_every_page_with_its_title() -> None:
    r = CliRunner().invoke(main, ["docs"])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    names = [line.split()[0] for line in lines]
    on_disk = sorted(p.relative_to(ROOT / "docs").with_suffix("").as_posix() for p in (ROOT / "docs").rglob("*.md"))
    assert names == on_disk
    assert re.fullmatch(r"semantics +Semantics: from an MITL formula to a reward net", lines[names.index("semantics")])


def test_prints_a_page_and_its_path() -> None:
    r = CliRunner().invoke(main, ["docs", "commands/train.md"])
    assert r.exit_code == 0
    assert r.output == (ROOT / "docs" / "commands" / "train.md").read_text(encoding="utf-8")
    r = CliRunner().invoke(main, ["docs", "--path", "semantics"])
    assert r.output == f"{ROOT / 'docs' / 'semantics.md'}\n"


def test_an_unknown_page_is_one_line_and_a_suggestion() -> None:
    r = CliRunner().invoke(main, ["docs", "semantix"])
    assert r.exit_code == 2
    assert r.output.splitlines()[0] == "mitlc docs: error: no page 'semantix': did you mean 'semantics'?"


def test_the_wheel_carries_every_page() -> None:
    """pyproject's data-files install exactly the pages `mitlc docs` lists from the checkout."""
    import tomllib  # Python 3.11+; CI's Python

    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["data-files"]
    shipped = {p.relative_to(ROOT / "docs").as_posix() for globs in data.values() for g in globs for p in ROOT.glob(g)}
    folder = docs_folder()
    assert folder == ROOT / "docs"
    assert shipped == {p.relative_to(folder).as_posix() for p in pages(folder).values()}


def test_no_help_text_points_into_the_source_tree() -> None:
    """An installed mitlc has no docs/ folder: --help says `mitlc docs PAGE` instead."""
    runner = CliRunner()
    for name in main.list_commands(click.Context(main)):  # type: ignore[attr-defined]
        r = runner.invoke(main, [name, "--help"])
        assert r.exit_code == 0, name
        assert "docs/" not in r.output and ".md" not in r.output, (name, r.output)
