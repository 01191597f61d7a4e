"""tests/mutation.py's bookkeeping: equivalent mutants keyed so that code moving keeps them,
and docs/reliability.md's table the script's own rendering of docs/mutation.json."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import mutation as M  # tests/mutation.py: tests/ is on the path, as for strategies and golden
import pytest

ROOT = Path(__file__).resolve().parent.parent


def _keys(module: str, source: str) -> list[str]:
    tree = ast.parse(source)
    return M.keys(module, tree, M.points(tree))


def test_every_equivalent_key_names_a_mutation_point_of_todays_code() -> None:
    current = {m: set(_keys(m, (ROOT / path).read_text(encoding="utf-8"))) for m, (path, _) in M.TARGETS.items()}
    stale = [k for k in M.EQUIVALENT if k not in current[k.split(":", 1)[0]]]
    assert stale == []


def test_keys_do_not_move_with_lines() -> None:
    source = (ROOT / M.TARGETS["timed"][0]).read_text(encoding="utf-8")
    before = _keys("timed", source)
    # lines and a new function above every point: the points' keys stay, the new ones are the function's
    moved = "\n\n\ndef _added(a, b):\n    return a < b + 1\n\n" + source.replace("\n\n\n", "\n\n\n\n")
    after = _keys("timed", moved)
    assert sorted(k for k in after if ":_added:" not in k) == sorted(before)
    assert sorted(k for k in after if ":_added:" in k) == [
        "timed:_added:bin:Add->Sub:b + 1",
        "timed:_added:cmp0:Lt->LtE:a < b + 1",
        "timed:_added:const:1->2:b + 1",
        "timed:_added:return:None:a < b + 1",
    ]


def test_a_repeated_expression_in_one_function_is_numbered() -> None:
    source = "def f(x):\n    if x > 0:\n        return 1\n    if x > 0:\n        return 2\n"
    keys = _keys("m", source)
    assert "m:f:cmp0:Gt->GtE:x > 0" in keys and "m:f:cmp0:Gt->GtE:x > 0#2" in keys
    assert keys.count("m:f:if:negated:x > 0") == 1 and "m:f:if:negated:x > 0#2" in keys
    assert len(set(keys)) == len(keys)


def test_the_page_table_is_the_scripts_rendering_of_the_record() -> None:
    record = json.loads(M.RECORD.read_text(encoding="utf-8"))
    page = M.PAGE.read_text(encoding="utf-8")
    a, b = page.index(M.TABLE_BEGIN) + len(M.TABLE_BEGIN), page.index(M.TABLE_END)
    assert page[a:b].strip() == M.table(record).strip()


@pytest.mark.parametrize("module", ["timed", "fused", "online", "grades"])
def test_the_recorded_semantic_modules_meet_the_bar(module: str) -> None:
    """Issue 35's bar on its modules: at least 60 mutants sampled, at least 90 % of the
    non-equivalent ones killed; the record's counts add up and its equivalents are listed."""
    r = json.loads(M.RECORD.read_text(encoding="utf-8"))[module]
    assert r["file"] == M.TARGETS[module][0]
    assert r["sampled"] >= 60
    assert r["killed"] + r["survived"] + r["equivalent"] == r["sampled"]
    assert len(r["survivors"]) == r["survived"]
    assert M.rate(r) == r["killed"] / (r["killed"] + r["survived"]) >= 0.9
