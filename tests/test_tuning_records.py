"""docs/training.md's table of how the defaults were chosen reads the suite runs kept in bench/suite/tuning/."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RECORDS = ROOT / "bench" / "suite" / "tuning"


def test_each_rows_tuning_mean_is_its_records() -> None:
    page = (ROOT / "docs" / "training.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| [^|]+ \| `([\w.-]+\.json)` \| ([\d.]*) ?\|", page, flags=re.M)
    assert len(rows) == len(list(RECORDS.glob("*.json"))) >= 6
    for name, shown in rows:
        data = json.loads((RECORDS / name).read_text(encoding="utf-8"))
        assert data["command"].startswith("python bench/suite.py"), name
        tuning = [n for n in data["halves"]["tuning"] if n in data["tasks"]]
        per_task = [np.mean([r["success"] for r in data["tasks"][n]["records"] if r["seed"] == 0]) for n in tuning]
        if len(tuning) == len(data["halves"]["tuning"]):
            assert shown == f"{np.mean(per_task):.2f}", name
        else:  # a few tasks only: no half's mean to show
            assert shown == "", name
