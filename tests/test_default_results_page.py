"""docs/results.md's section at the defaults is what docs/make_default_results.py renders from its
data, made with nothing but the spec and a seed given: every spec, every seed, mitlc train's runs
and trials."""

from __future__ import annotations

import json

from scripts import load_script  # tests/scripts.py: tests/ is on the path, as for strategies and golden


def _script():  # type: ignore[no-untyped-def]
    return load_script("docs/make_default_results.py", "default_results_script")


def test_the_section_is_rendered_from_its_data_at_the_defaults() -> None:
    from mitlc.cli.train import TRIALS, train
    from mitlc.sweep.race import search_generations

    script = _script()
    data = json.loads(script.DATA.read_text(encoding="utf-8"))
    page = script.PAGE.read_text(encoding="utf-8")
    block = page[page.index(script.BEGIN) : page.index(script.END) + len(script.END) + 1]
    assert block == script.render(data), "python docs/make_default_results.py --render writes it again"
    readme = script.README.read_text(encoding="utf-8")
    assert script.readme_line(data) in readme, "README.md's block: python docs/make_default_results.py --render"
    runs = next(p.default for p in train.params if p.name == "runs")
    assert data["seeds"] == list(script.SEEDS) and data["runs"] == runs
    assert set(data["specs"]) == {key for key, _, _ in script.SPECS}
    for key, recs in data["specs"].items():
        assert sorted(r["seed"] for r in recs) == list(script.SEEDS), key
        for r in recs:  # mitlc train's default trials, or the generations of a policy search that won the race
            assert r["runs"] == runs and r["trials"] == (
                search_generations(TRIALS) if r["learner"] == "search" else TRIALS
            )
        assert all(0.0 <= r["success"] <= 1.0 for r in recs), key


def test_render_says_which_specs_miss_the_target() -> None:
    script = _script()

    def recs(*success: float) -> list[dict]:
        return [
            {"seed": s, "success": v, "trials": 500, "learner": "sacpn", "winner": "search", "wall_s": 10.0}
            for s, v in enumerate(success)
        ]

    data = {
        "command": "c",
        "minutes": 1.0,
        "machine": "m",
        "seeds": [0, 1],
        "runs": 30,
        "target": 0.95,
        "specs": {key: recs(1.0, 1.0) for key, _, _ in script.SPECS},
    }
    assert "Every spec reaches 0.95 at the defaults." in script.render(data)
    data["specs"]["P4"] = recs(1.0, 0.8)
    text = script.render(data)
    # mean 0.9, half-width t(1) s / sqrt(2) = 12.706 x 0.1414 / 1.414 = 1.27
    assert (
        "| P4 `p4_alternate.mitl`: alternate between two regions | 1.00 / 0.80 | **0.90 ± 1.27** | search x2 | 10 |"
        in text
    )
    assert "on 30 runs for 500 trials (docs/training.md" in text
    assert "Below 0.95 at the defaults: P4 0.90." in text
