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


def test_cart_section_ranks_fixed_controllers() -> None:
    """The cart's section: both compiled rewards pay the braking controller, which the monitor accepts,
    more than standing still, and driving into the stop least; pushing left earns what standing still
    earns under net (every step outside the goal pays -1 until F[0,2]'s window closes, 40 steps of -1, then
    the failed part pays the goal's -1 less one for the trial's last 20 steps)."""
    import mitlc.plants.user as U
    from mitlc.plants import PLANTS

    sys.path.insert(0, str(ROOT / "docs"))
    before, sources = dict(PLANTS), list(U.SOURCES)
    try:
        import make_benchmarks

        lines = make_benchmarks._cart_section("examples/cart/cart_small_goal.mitl")
    finally:  # the cart plant it loads is this test's only (test_user_plants.py asks for it unknown)
        sys.path.remove(str(ROOT / "docs"))
        PLANTS.clear()
        PLANTS.update(before)
        U.SOURCES[:] = sources
    rows = {}
    for ln in lines:
        cells = [c.strip() for c in ln.strip("|").split("|")]
        if len(cells) == 6 and cells[0].split(":")[0] in (
            "brake at the goal",
            "stand still",
            "full force left",
            "full force right, into the stop",
        ):
            rows[cells[0].split(":")[0]] = [float(c) for c in cells[1:]]
    assert len(rows) == 4
    brake, still, left, right = (
        rows[k] for k in ("brake at the goal", "stand still", "full force left", "full force right, into the stop")
    )
    assert brake[4] == 1.0 and still[4] == left[4] == right[4] == 0.0
    for col in range(4):  # net and shaped, discounted and total
        assert brake[col] > still[col] >= left[col] > right[col]
    assert still[1] == left[1] == -40.0 - 2 * 20  # net, total: 2 s of -1 per 0.05 s step, then 1 s of -2
