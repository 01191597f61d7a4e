"""``mitlc docs [PAGE]``: the documentation pages, readable where mitlc is installed.

A pip install puts the pages (docs/*.md, docs/commands/*.md) under
``<prefix>/share/mitlc/docs`` (pyproject's data-files); a source checkout reads its own
``docs/``. The commands' ``--help`` texts point here (``mitlc docs semantics``) rather than at
paths of the source tree that an installed copy does not have.
"""

from __future__ import annotations

import difflib
import sysconfig
from pathlib import Path

import click

from mitlc.cli.common import handle_errors
from mitlc.errors import InputError

__all__ = ["docs", "docs_folder", "pages"]


def docs_folder() -> Path | None:
    """The folder of the pages: the checkout's ``docs/`` first, else the installed copy."""
    checkout = Path(__file__).resolve().parents[2] / "docs"
    installed = Path(sysconfig.get_path("data")) / "share" / "mitlc" / "docs"
    for folder in (checkout, installed):
        if (folder / "semantics.md").is_file():
            return folder
    return None


def pages(folder: Path) -> dict[str, Path]:
    """Page name (``semantics``, ``commands/train``) -> its file."""
    found = {p.relative_to(folder).with_suffix("").as_posix(): p for p in folder.glob("*.md")}
    found.update({p.relative_to(folder).with_suffix("").as_posix(): p for p in folder.glob("commands/*.md")})
    return dict(sorted(found.items()))


def _title(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return ""


@click.command("docs")
@click.argument("page", required=False)
@click.option("--path", "show_path", is_flag=True, help="Print the page's file path instead of its text.")
@handle_errors
def docs(page: str | None, show_path: bool) -> None:
    """List the documentation pages, or print the one called PAGE (e.g. semantics, commands/train).

    The pages are Markdown; --path prints where a page is, to open it in a viewer."""
    folder = docs_folder()
    if folder is None:
        raise InputError("the documentation pages are not installed with this copy of mitlc", file="mitlc docs")
    known = pages(folder)
    if page is None:
        width = max(len(n) for n in known)
        for name, path in known.items():
            click.echo(f"{name:<{width}}  {_title(path)}")
        return
    name = page.removesuffix(".md").removeprefix("docs/")
    if name not in known:
        close = difflib.get_close_matches(name, list(known), n=1)
        raise InputError(
            f"no page '{page}'" + (f": did you mean '{close[0]}'?" if close else ""),
            file="mitlc docs",
            hint="mitlc docs lists them",
        )
    click.echo(str(known[name]) if show_path else known[name].read_text(encoding="utf-8"), nl=show_path)
