"""The suite's split into a tuning half and a check half, drawn once from a seed (``split.json``).

    python -m bench.suite.split            # draw it (seed 31) and write bench/suite/split.json
    python -m bench.suite.split --check    # exit 1 unless split.json holds that draw and every task

The draw is balanced by plant: the tasks of each plant (in name order, plants in name order)
are put in the order of a seeded permutation and dealt alternately to the two halves,
the first to the half that has fewer tasks so far (a coin of the same generator when
they are even). So every plant with two tasks or more has one in each half, and the
halves differ by at most one task. That each half has nested tasks is checked, not
forced. Settings may be tuned on the tuning half only; the check half is what a result
is reported on.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.fileio import json_text

SEED = 31
SPLIT = Path(__file__).resolve().parent / "split.json"
COMMAND = "python -m bench.suite.split"


def draw(plants: Mapping[str, str], seed: int = SEED) -> dict[str, list[str]]:
    """``{"tuning": [...], "check": [...]}`` from the tasks' plants (``{task: plant}``), balanced by plant.

    >>> draw({"a": "p", "b": "p", "c": "q", "d": "q"}, 0)
    {'tuning': ['b', 'c'], 'check': ['a', 'd']}
    """
    rng = np.random.default_rng(seed)
    halves: dict[str, list[str]] = {"tuning": [], "check": []}
    for plant in sorted(set(plants.values())):
        names = sorted(n for n, p in plants.items() if p == plant)
        order = [names[i] for i in rng.permutation(len(names))]
        a, b = len(halves["tuning"]), len(halves["check"])
        first = "tuning" if a < b else "check" if b < a else ("tuning", "check")[int(rng.integers(2))]
        second = "check" if first == "tuning" else "tuning"
        for i, name in enumerate(order):
            halves[first if i % 2 == 0 else second].append(name)
    return {k: sorted(v) for k, v in halves.items()}


def make(seed: int = SEED) -> dict[str, object]:
    """The record ``split.json`` holds: the seed, the command, the tasks drawn over, the two halves and
    how many nested tasks and plants each has."""
    from bench.suite.tasks import load_tasks

    suite = {t.name: t for t in load_tasks()}
    halves = draw({n: t.plant for n, t in suite.items()}, seed)
    summary = {
        half: {
            "tasks": len(names),
            "nested": sum(suite[n].nested for n in names),
            "plants": sorted({suite[n].plant for n in names}),
        }
        for half, names in halves.items()
    }
    return {
        "seed": seed,
        "command": COMMAND,
        "method": "per plant, a numpy default_rng(seed) permutation dealt alternately to the halves (draw())",
        "drawn": sorted(suite),
        **halves,
        "summary": summary,
    }


def problems(record: Mapping[str, object] | None = None) -> list[str]:
    """What is wrong with ``split.json`` (default: the file): its halves restricted to the tasks it was
    drawn over (``drawn``) must be the draw of its seed, and every task must be in exactly one half
    (a task added after the draw is put in a half by hand, never redrawn). Empty when all is well."""
    from bench.suite.tasks import load_tasks

    rec: Mapping[str, Any] = record if record is not None else json.loads(SPLIT.read_text())
    suite = {t.name: t.plant for t in load_tasks()}
    out = []
    tuning, check = list(rec["tuning"]), list(rec["check"])
    both = sorted(set(tuning) & set(check))
    if both:
        out.append(f"in both halves: {both}")
    missing, unknown = sorted(set(suite) - set(tuning + check)), sorted(set(tuning + check) - set(suite))
    if missing or unknown:
        out.append(f"tasks in no half: {missing}; in a half but not in the suite: {unknown}")
    drawn = [n for n in rec["drawn"] if n in suite]
    again = draw({n: suite[n] for n in drawn}, int(rec["seed"]))
    kept = {half: [n for n in names if n in drawn] for half, names in (("tuning", tuning), ("check", check))}
    if again != kept:
        out.append(f"the drawn tasks are not the draw of seed {rec['seed']}: {again}")
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--check", action="store_true", help="do not write; exit 1 unless split.json is the draw")
    args = ap.parse_args(argv)
    if args.check:
        found = problems()
        print(f"{SPLIT.name}: " + ("; ".join(found) if found else "the recorded draw, every task in one half"))
        return 1 if found else 0
    record = make(args.seed)
    SPLIT.write_text(json_text(record, indent=2))
    for half in ("tuning", "check"):
        s = record["summary"][half]  # type: ignore[index]
        print(f"{half}: {s['tasks']} tasks, {s['nested']} nested, plants {', '.join(s['plants'])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
