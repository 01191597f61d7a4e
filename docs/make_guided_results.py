"""Falsification-guided training on a policy trained on part of its init box (docs/verify.md).

    python docs/make_guided_results.py        # about 2.5 minutes on 2 cores

Writes the section between the ``guided`` markers of docs/verify.md and its data
docs/figures/verify_guided.json. For each of three seeds:

1. train problem 5 from half its box (``q in [-pi/2, 0]``; 8 runs x 1000 trials);
2. ``mitlc verify`` it on the spec's whole box (``[-pi/2, pi/2]``) with ``--keep 100``: the
   satisfied fraction *before*, and counterexamples.npz;
3. resume a copy for 3000 more trials with ``--starts counterexamples.npz`` (*guided*) and
   another copy for the same trials without (*unguided*: what more training alone buys);
4. verify both on the whole box with fresh samples (``--seed 1``, not the ones that found
   the counterexamples): the satisfied fraction and its 95 % lower bound *after*.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
import platform  # noqa: E402
import re  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mitlc.fileio import atomic_write, json_text, write_block  # noqa: E402

COMMAND = "python docs/make_guided_results.py"
PAGE = ROOT / "docs" / "verify.md"
DATA = ROOT / "docs" / "figures" / "verify_guided.json"
BEGIN, END = "<!-- guided:begin -->", "<!-- guided:end -->"
SEEDS = (0, 1, 2)
FULL = "pendulum/p5_timed_visit"
TRIALS, MORE = 1000, 3000
SAMPLED = re.compile(r"sampled: (\d+)/(\d+) rollouts")


def mitlc(*args: str, cwd: Path) -> str:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    res = subprocess.run([sys.executable, "-m", "mitlc", *args], cwd=cwd, env=env, capture_output=True, text=True)
    if res.returncode not in (0, 1):
        raise SystemExit(f"mitlc {' '.join(args)} failed:\n{res.stdout}{res.stderr}")
    return res.stdout


def verified(folder: str, cwd: Path, *extra: str) -> dict:
    """``mitlc verify`` on the whole box, sampling only: satisfied, samples, lower bound."""
    mitlc("verify", "--policy", folder, "--spec", FULL, "--budget", "0", "--out", f"{folder}-v", *extra, cwd=cwd)
    s = json.loads((cwd / f"{folder}-v" / "report.json").read_text())["sampling"]
    return {"satisfied": s["satisfied"], "samples": s["samples"], "lower_bound": round(s["lower_bound"], 4)}


def main() -> None:
    started = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        text = (ROOT / "specs/pendulum/p5_timed_visit.mitl").read_text()
        (work / "p5_half.mitl").write_text(text.replace("init q in [-pi/2, pi/2]", "init q in [-pi/2, 0]"))
        for seed in SEEDS:
            base = f"s{seed}"
            mitlc("train", "--spec", "p5_half.mitl", "--runs", "8", "--trials", str(TRIALS), "--seed", str(seed),
                  "--out", base, "-q", "--no-plots", cwd=work)  # fmt: skip
            shutil.copytree(work / base, work / f"{base}-guided")
            shutil.copytree(work / base, work / f"{base}-unguided")
            mitlc("verify", "--policy", base, "--spec", FULL, "--keep", "100", "--out", f"{base}-cex", cwd=work)
            with np.load(work / f"{base}-cex" / "counterexamples.npz") as f:
                starts = int(f["x0"].shape[0])
            before = verified(base, work, "--seed", "1")
            mitlc("train", "--resume", f"{base}-guided", "--trials", str(TRIALS + MORE), "--starts",
                  f"{base}-cex/counterexamples.npz", "-q", "--no-plots", cwd=work)  # fmt: skip
            mitlc("train", "--resume", f"{base}-unguided", "--trials", str(TRIALS + MORE), "-q", "--no-plots",
                  cwd=work)  # fmt: skip
            row = {
                "seed": seed,
                "starts": starts,
                "before": before,
                "guided": verified(f"{base}-guided", work, "--seed", "1"),
                "unguided": verified(f"{base}-unguided", work, "--seed", "1"),
            }
            rows.append(row)
            print(json.dumps(row), flush=True)
    results = {
        "command": COMMAND,
        "rows": rows,
        "seconds": round(time.perf_counter() - started, 1),
        "python": platform.python_version(),
        "numpy": np.__version__,
    }
    atomic_write(DATA, json_text(results, indent=1))
    write_block(PAGE, BEGIN, END, block(results))
    print(f"wrote {DATA.relative_to(ROOT)} and the block of {PAGE.relative_to(ROOT)} in {results['seconds']} s")


def block(r: dict) -> str:
    def cell(v: dict) -> str:
        return f"{v['satisfied']}/{v['samples']} (bound {v['lower_bound']:.4f})"

    lines = [
        BEGIN,
        f"| seed | starts given | before ({TRIALS} trials) | guided (+{MORE}, --starts) | unguided (+{MORE}) |",
        "| --- | --- | --- | --- | --- |",
        *(
            f"| {x['seed']} | {x['starts']} | {cell(x['before'])} | {cell(x['guided'])} | {cell(x['unguided'])} |"
            for x in r["rows"]
        ),
        "",
        f"`{COMMAND}` ({r['seconds']:.0f} s, Python {r['python']}, numpy {r['numpy']}; the data: "
        "[figures/verify_guided.json](figures/verify_guided.json)).",
        END,
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
