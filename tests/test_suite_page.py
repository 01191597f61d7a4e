"""docs/suite.md is what bench/suite.py renders from its run's data, made at the current defaults."""

from __future__ import annotations

import json
from pathlib import Path

from scripts import load_script  # tests/scripts.py: tests/ is on the path, as for strategies and golden

ROOT = Path(__file__).resolve().parent.parent


def _script():  # type: ignore[no-untyped-def]
    return load_script("bench/suite.py", "suite_script")


def test_page_is_rendered_from_its_data_at_the_defaults() -> None:
    script = _script()
    data = json.loads((ROOT / "docs" / "suite.json").read_text(encoding="utf-8"))
    page = (ROOT / "docs" / "suite.md").read_text(encoding="utf-8")
    assert page == script.render(data), "python bench/suite.py --render writes it again"
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert script.readme_block(data) in readme, "README.md's suite block: python bench/suite.py --render"
    # made at the product's defaults: nothing changed, mitlc train's runs and trials, every task and seed
    assert data["sets"] == [] and data["options"] == {}
    assert data["runs"] == script.default_runs() and data["trials"] == script.default_trials()
    assert data["seeds"] == list(script.SEEDS)
    names = {t.name for t in script.load_tasks()}
    assert set(data["tasks"]) == names
    assert data["halves"] == script.halves()
    for name, task in data["tasks"].items():
        assert sorted(r["seed"] for r in task["records"]) == list(script.SEEDS), name
        ok, n = task["witness"]
        assert ok == n > 0, f"{name}: the witness must satisfy the task from every start"


def test_trials_to_reads_the_seeds_mean_curve() -> None:
    script = _script()
    recs = [{"curve": [[50, 0.5], [100, 0.9], [150, 1.0]]}, {"curve": [[50, 0.7], [100, 0.6], [150, 0.9]]}]
    assert script._trials_to(recs) == "150"  # the mean reaches 0.8 at 150 (0.75 at 100)
    assert script._trials_to(recs, 0.6) == "50"
    assert script._trials_to([{"curve": [[50, 0.1]]}]) == "-"
    s = script.summary(
        {"tasks": {"a": {"records": [{"success": 1.0}, {"success": 0.8}]}, "b": {"records": [{"success": 0.2}]}}},
        ["a", "b"],
    )
    assert (s["tasks"], s["at_least_0.9"], s["below_0.5"]) == (2, 1, ["b"])
    assert abs(s["mean"] - 0.55) < 1e-12
