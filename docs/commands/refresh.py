"""Rerun every ``$ command`` of the ``console`` blocks of a docs page and paste its real output.

Run from the repository root:  python docs/commands/refresh.py docs/commands/compile.md

Commands run in a scratch directory that links ``specs/``, as
tests/test_examples.py does when it checks the page.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def refresh(page: Path) -> str:
    out: list[str] = []
    in_block = False
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "specs").symlink_to(ROOT / "specs")
        env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
        for line in page.read_text(encoding="utf-8").splitlines():
            if line.startswith("```console"):
                in_block = True
                out.append(line)
            elif line.startswith("```") and in_block:
                in_block = False
                out.append(line)
            elif in_block and line.startswith("$ "):
                r = subprocess.run(
                    ["bash", "-c", line[2:]],
                    cwd=tmp,
                    env=env,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT,
                    text=True,
                    timeout=600,
                )
                out.append(line)
                out.extend(r.stdout.rstrip("\n").splitlines() if r.stdout else [])
            elif not in_block:
                out.append(line)
    return "\n".join(out) + "\n"


def _needs_dot(page: Path) -> bool:
    lines = page.read_text(encoding="utf-8").splitlines()
    return any(line.startswith("$ ") and ("--format svg" in line or "--format png" in line) for line in lines)


if __name__ == "__main__":
    for name in sys.argv[1:]:
        path = Path(name)
        if _needs_dot(path) and shutil.which("dot") is None:  # it would paste dot's "not installed" error
            print(f"{path}: its picture commands need Graphviz's dot, which is not installed here; not refreshed")
            sys.exit(2)
        path.write_text(refresh(path), encoding="utf-8")
        print(f"refreshed {path}")
