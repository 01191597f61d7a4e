"""The command outputs the docs show are what the commands print now (docs/refresh.py).

Each page of ``docs/refresh.PAGES`` runs again, command by command, in a scratch folder;
a page whose outputs drifted fails with the difference and the command that rewrites it.
Exact, but for the seconds a training took (``in 9.8 s``), which depend on the machine.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from scripts import load_script  # tests/scripts.py: tests/ is on the path, as for strategies and golden

ROOT = Path(__file__).resolve().parent.parent
HAS_DOT = shutil.which("dot") is not None


refresh = load_script("docs/refresh.py", "docs_refresh")


def test_every_page_with_commands_is_checked() -> None:
    """A ``$ command`` line appears only in console blocks, and only on the pages checked here."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    with_commands = set()
    for page in pages:
        text = page.read_text(encoding="utf-8")
        in_console = {i for b in refresh.blocks(text) if b.file is None for i in range(b.start, b.end)}
        fence = False
        for i, line in enumerate(text.splitlines()):
            if line.startswith("```"):
                fence = not fence
            elif fence and line.startswith("$ "):
                assert i in in_console, f"{page.relative_to(ROOT)}:{i + 1}: a command outside a console block"
                with_commands.add(page.relative_to(ROOT).as_posix())
    assert with_commands == set(refresh.PAGES)


def test_seconds_are_all_that_may_differ() -> None:
    a = "8 runs x 300 trials in 3.6 s; final mean return 9.9; success rate 0.62\n"
    assert refresh.normalised(a) == refresh.normalised(a.replace("3.6 s", "12 s"))
    assert refresh.normalised(a) != refresh.normalised(a.replace("9.9", "2.6"))
    assert refresh.normalised("t = 2 s") == "t = 2 s"  # a time inside a verdict is exact


def test_progress_is_left_out() -> None:
    """What mitlc.cli.progress writes to a log, and the compile notice, are not page output."""
    import io

    from mitlc.cli.progress import Progress

    log = io.StringIO()
    with Progress(40, desc="p2_short", stream=log) as bar:
        for _ in range(40):
            bar.update("mean return -1.0")
    lines = log.getvalue().splitlines()
    assert len(lines) == 20 and all(refresh.TRANSIENT.match(line) for line in lines)
    assert refresh.TRANSIENT.match("compiling the training kernel (up to ~10 s, cached in ~/.cache/mitlc/kernels)")
    assert not refresh.TRANSIENT.match("8 runs x 300 trials in 3.6 s; final mean return 9.9; results in p1")
    assert not refresh.TRANSIENT.match("p2.mitl:3:13: error: undefined proposition 'upp'")


def test_blocks_read_files_and_commands() -> None:
    page = "x\n```csv file=a.csv\nt,q\n0,1\n```\n```console\n$ cat a.csv\nt,q\n0,1\n$ true\n```\n```\n$ not run\n```\n"
    found = refresh.blocks(page)
    assert [(b.file, b.text) for b in found if b.file] == [("a.csv", "t,q\n0,1\n")]
    [console] = [b for b in found if b.file is None]
    assert [(c.line, c.shown) for c in console.commands] == [("cat a.csv", "t,q\n0,1\n"), ("true", "")]


@pytest.mark.parametrize("page", refresh.PAGES)
def test_page_shows_what_its_commands_print(page: str, tmp_path: Path) -> None:
    skip = () if HAS_DOT else ("--format svg", "--format png")
    results = refresh.run_page(ROOT / page, skip=skip, folder=tmp_path)
    assert results, f"{page} shows no command"
    drifted = refresh.drift(results)
    assert not drifted, f"{page} drifted; python docs/refresh.py {page} rewrites it:\n" + "\n".join(drifted)
    if page == "docs/commands/compile.md" and HAS_DOT:
        assert (tmp_path / "p1_swing_up.svg").read_text().lstrip().startswith(("<?xml", "<svg"))
        assert (tmp_path / "p2_avoid.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
