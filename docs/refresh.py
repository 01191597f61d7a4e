"""Rerun the commands the docs show and paste their real output: the pages cannot drift.

A page shows a command and what it prints in a ``console`` block::

    ```console
    $ mitlc check specs/pendulum/p5_timed_visit.mitl visit.csv
    visit.csv: satisfied
    ```

and a file the commands read in a block whose info string names it (GitHub shows it as
an ordinary ``csv`` block)::

    ```csv file=visit.csv
    t,q,qdot
    ```

The commands of a page run in order, in one scratch folder that holds the files the
page showed before them and links ``specs/`` and ``examples/``, with stdout and stderr
together as a terminal shows them once the command is done (progress lines and the
kernel's one-time compile notice left out). Run from anywhere:

    python docs/refresh.py                 # every page in PAGES: rewrite its outputs
    python docs/refresh.py README.md       # one page
    python docs/refresh.py --check         # exit 1 and show the difference where a page drifted

tests/test_docs_pages.py runs ``--check``'s comparison for every page. Exact but for
what depends on the machine and says so on the page: the seconds a training took
(``in 9.8 s``), which are compared as ``in <seconds> s``.
"""

from __future__ import annotations

import argparse
import difflib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# Every page with a console block; tests/test_docs_pages.py checks that no other page has one.
PAGES = (
    "README.md",
    "docs/commands/compile.md",
    "docs/commands/train.md",
    "docs/plants.md",
    "docs/monitor.md",
    "docs/sweep.md",
    "docs/verify.md",
    "docs/report.md",
)

# What a page may show that depends on the machine: the seconds a training took.
SECONDS = re.compile(r"\bin \d+(?:\.\d+)? s\b")
# What a terminal shows only while a command runs, and not on the page: the progress (a bar on a
# terminal, a line per 5 % in a log: mitlc.cli.progress) and the kernel's one-time compile notice.
TRANSIENT = re.compile(r"^(?:\S.*: \w+ \d+/\d+ \(\d+%\)(?:, .*)?|compiling the training kernel \(.*\))$")
FILE_INFO = re.compile(r"^```\S*\s+file=(\S+)\s*$")


@dataclass
class Command:
    line: str  # without the "$ "
    shown: str = ""  # the output the page shows, lines ending in "\n"


@dataclass
class Block:
    """A console block (``commands``) or a file block (``file`` and its ``text``)."""

    start: int  # index of the opening fence in the page's lines
    end: int  # index of the closing fence
    commands: list[Command] = field(default_factory=list)
    file: str | None = None
    text: str = ""


def blocks(markdown: str) -> list[Block]:
    """The console and file blocks of a page, in order."""
    found: list[Block] = []
    lines = markdown.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        named = FILE_INFO.match(line)
        if line.startswith("```console") or named:
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            body = lines[i + 1 : j]
            block = Block(i, j)
            if named:
                block.file, block.text = named.group(1), "".join(f"{b}\n" for b in body)
            else:
                for b in body:
                    if b.startswith("$ "):
                        block.commands.append(Command(b[2:]))
                    elif block.commands:
                        block.commands[-1].shown += b + "\n"
            found.append(block)
            i = j
        elif line.startswith("```"):  # any other block: skip to its end
            i += 1
            while i < len(lines) and not lines[i].startswith("```"):
                i += 1
        i += 1
    return found


def needs_dot(command: str) -> bool:
    return "--format svg" in command or "--format png" in command


def run_page(page: Path, skip: tuple[str, ...] = (), folder: Path | None = None) -> list[tuple[Command, str]]:
    """Run a page's commands in order; per command, what it printed now.

    Commands for which ``skip`` holds a substring are not run (their output is taken as shown).
    They run in ``folder`` (which must be empty) when given, else in a temporary one."""
    if folder is None:
        with tempfile.TemporaryDirectory(prefix="mitlc-docs-") as tmp:
            return run_page(page, skip, Path(tmp))
    results: list[tuple[Command, str]] = []
    env = {
        **os.environ,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
        "COLUMNS": "120",
    }
    for name in ("specs", "examples"):
        (folder / name).symlink_to(ROOT / name)
    status = 0  # the previous command's exit status, for a page that shows `echo $?`
    for block in blocks(page.read_text(encoding="utf-8")):
        if block.file is not None:
            (folder / block.file).write_text(block.text, encoding="utf-8")
            continue
        for cmd in block.commands:
            if any(s in cmd.line for s in skip):
                results.append((cmd, cmd.shown))
                continue
            r = subprocess.run(
                ["bash", "-c", f"(exit {status}); {cmd.line}"],
                cwd=folder,
                env=env,
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                text=True,
                timeout=900,
            )
            got = "".join(f"{line}\n" for line in r.stdout.splitlines() if not TRANSIENT.match(line))
            results.append((cmd, got))
            status = r.returncode
    return results


def refreshed(page: Path, results: list[tuple[Command, str]]) -> str:
    """The page's text with each command's output replaced by what it printed now."""
    lines = page.read_text(encoding="utf-8").splitlines()
    new = iter(got for _, got in results)
    out: list[str] = []
    i = 0
    for block in blocks("\n".join(lines)):
        out.extend(lines[i : block.start + 1])
        if block.file is not None:
            out.extend(lines[block.start + 1 : block.end])
        else:
            for cmd in block.commands:
                out.append(f"$ {cmd.line}")
                out.extend(next(new).splitlines())
        i = block.end
    out.extend(lines[i:])
    return "\n".join(out) + "\n"


def normalised(text: str) -> str:
    """What must match exactly: everything but a training's seconds."""
    return SECONDS.sub("in <seconds> s", text)


def drift(results: list[tuple[Command, str]]) -> list[str]:
    """For each command whose output differs from the page's (beyond the seconds), a diff."""
    found = []
    for cmd, got in results:
        if normalised(got) != normalised(cmd.shown):
            diff = difflib.unified_diff(cmd.shown.splitlines(), got.splitlines(), "page", "now", lineterm="")
            found.append(f"$ {cmd.line}\n" + "\n".join(diff))
    return found


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pages", nargs="*", help=f"pages, relative to the repository (default: {', '.join(PAGES)})")
    ap.add_argument("--check", action="store_true", help="do not write; exit 1 where a page drifted")
    args = ap.parse_args()
    pages = [ROOT / p for p in (args.pages or PAGES)]
    if shutil.which("dot") is None and any(
        needs_dot(c.line) for p in pages for b in blocks(p.read_text()) for c in b.commands
    ):
        print("the pages' picture commands need Graphviz's dot, which is not installed here", file=sys.stderr)
        return 2
    status = 0
    for page in pages:
        results = run_page(page)
        if args.check:
            for d in drift(results):
                print(f"{page.relative_to(ROOT)}: drifted:\n{d}\n")
                status = 1
        else:
            page.write_text(refreshed(page, results), encoding="utf-8")
            print(f"refreshed {page.relative_to(ROOT)}")
    return status


if __name__ == "__main__":
    sys.exit(main())
