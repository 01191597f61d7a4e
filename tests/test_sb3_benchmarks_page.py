"""docs/make_sb3_benchmarks.py --quick: SB3 SAC through the wrapper, with and without counterfactual
markings, and on the cart as MitlPlantEnv, runs and reports what it measured (a smoke run: 1 seed,
200 steps, 2 test episodes)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 and PyTorch: pip install 'mitlc[sb3]'")

ROOT = Path(__file__).resolve().parent.parent


def test_quick_sb3_benchmark(tmp_path) -> None:
    r = subprocess.run(
        [sys.executable, str(ROOT / "docs" / "make_sb3_benchmarks.py"), "--quick", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    block = (tmp_path / "sb3.md").read_text(encoding="utf-8")
    data = json.loads((tmp_path / "benchmarks_sb3.json").read_text(encoding="utf-8"))
    assert block.startswith("<!-- sb3:begin -->") and block.rstrip().endswith("<!-- sb3:end -->")
    assert len(data["rows"]) == 6 and data["steps"] == 200
    by = {(row["spec"].split("/")[-1], row["design"], row["crm"]): row["results"][0] for row in data["rows"]}
    # problem 4's recurrence: one counterfactual marking per step with CRM, none without
    assert by[("p4_alternate.mitl", "net", True)]["counterfactual_per_step"] == 1.0
    assert by[("p4_alternate.mitl", "net", False)]["counterfactual_per_step"] == 0.0
    for res in by.values():
        assert 0.0 <= res["success"] <= 1.0 and 0.0 <= res["effort"] <= 2.0
    assert by[("cart_small_goal.mitl", "shaped", False)]["counterfactual_per_step"] == 0.0
    assert all(res["steps"] == 200 for res in by.values())
    assert block.count("| P4 | `net` |") == 2 and block.count("| cart | ") == 2
