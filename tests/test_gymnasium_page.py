"""docs/gymnasium.md is what docs/make_gym_results.py renders from its run's data."""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_page_is_rendered_from_its_data() -> None:
    sys.path.insert(0, str(ROOT / "docs"))
    try:
        import make_gym_results
    finally:
        sys.path.remove(str(ROOT / "docs"))
    data = json.loads((ROOT / "docs" / "figures" / "gym.json").read_text())
    page = (ROOT / "docs" / "gymnasium.md").read_text(encoding="utf-8")
    assert page == make_gym_results.render(data), "python docs/make_gym_results.py --render writes it again"
    # each spec's shipped comment names the settings the page measured with
    for spec, trials, sets, _ in make_gym_results.TASKS:
        text = (ROOT / "specs" / f"{spec}.mitl").read_text()
        assert "docs/gymnasium.md" in text
        assert all(f"--set {s}" in " ".join(text.replace("#", " ").split()) for s in sets), spec
        assert data["specs"][spec][", ".join(sets)]["trials"] == trials
