"""mitlc.cmaes: cma imported without matplotlib's pyplot and scipy.stats, the same CMA-ES all the same."""

from __future__ import annotations

import json
import subprocess
import sys

SEARCH = """
import json, sys
{before}
from mitlc.cmaes import load
cma = load()
held = {{m: m in sys.modules for m in ("matplotlib", "matplotlib.pyplot", "scipy", "scipy.stats")}}
import matplotlib.pyplot, scipy.stats  # held back while cma imported, importable after
es = cma.CMAEvolutionStrategy([0.5, -0.3, 0.2], 0.4, {{"seed": 5, "popsize": 8, "verbose": -9}})
for _ in range(12):
    xs = es.ask()
    es.tell(xs, [float(sum((x - 0.1) ** 2)) for x in xs])
print(json.dumps({{"held": held, "mean": [float(v) for v in es.mean], "sigma": float(es.sigma)}}))
"""


def run(before: str) -> dict:
    out = subprocess.run([sys.executable, "-c", SEARCH.format(before=before)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stderr == ""  # cma's "Could not import matplotlib.pyplot" warning is not shown
    return json.loads(out.stdout)


def test_cma_is_imported_without_pyplot_or_scipy_stats_and_searches_as_with_them() -> None:
    light = run("")
    assert light["held"] == {"matplotlib": False, "matplotlib.pyplot": False, "scipy": False, "scipy.stats": False}
    full = run("import matplotlib.pyplot, scipy.stats")
    assert full["held"] == dict.fromkeys(light["held"], True)
    assert light["mean"] == full["mean"] and light["sigma"] == full["sigma"]  # the same CMA-ES to the bit
    assert light["sigma"] != 0.4  # and it did search


def test_a_process_that_imported_cma_keeps_it() -> None:
    from mitlc.cmaes import load

    assert load() is load() is sys.modules["cma"]
