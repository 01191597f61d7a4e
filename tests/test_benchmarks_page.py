"""docs/make_benchmarks.py --quick: the script that writes docs/benchmarks.md runs, and its page says
what its data file holds (a smoke run: two tasks, 2 seeds x 3 runs, 20 trials)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DESIGNS = ("net", "shaped", "graded", "sparse", "robustness", "robustness-window")


def test_quick_benchmark_writes_page_figure_and_data(tmp_path) -> None:
    r = subprocess.run(
        [sys.executable, str(ROOT / "docs" / "make_benchmarks.py"), "--quick", "--out", str(tmp_path)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "benchmarks.md").read_text(encoding="utf-8")
    data = json.loads((tmp_path / "benchmarks.json").read_text(encoding="utf-8"))
    assert (tmp_path / "benchmarks.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "python docs/make_benchmarks.py --quick" in page and data["seeds"] == 2 and data["runs"] == 3
    assert set(data["tasks"]) == {"P1", "cart"}
    for key, task in data["tasks"].items():
        assert set(task["designs"]) == set(DESIGNS)
        for design, d in task["designs"].items():
            assert len(d["success"]) == 2 and all(0.0 <= s <= 1.0 for s in d["success"])
            assert all(len(c) == len(d["at"][0]) for c in d["curve"]) and d["at"][0][-1] == task["trials"]
            # the page's cell is the data's mean over the seeds
            row = next(ln for ln in page.splitlines() if ln.startswith(f"| {key}:") and f"| `{design}` |" in ln)
            shown = float(re.search(r"\*\*([0-9.]+)", row).group(1))
            assert shown == round(float(np.mean(d["success"])), 2)
    assert page.count("| `net` |") == 2 and "## What the numbers say" in page
