"""Screenshots of a training's and a sweep's report for docs/report.md, made, not drawn by hand.

    python docs/make_report_screenshots.py

trains a small training and a small sweep in a scratch folder with ``mitlc train`` and ``mitlc
sweep`` (which write their ``report.html``), opens each page in headless Chromium (Debian's
``chromium``) and writes ``docs/figures/report_training.png`` and ``docs/figures/report_sweep.png``.
The training's page is shown at a step of a violated run (``#run=R&step=K``), as a user who chose
that run and moved the slider would see it. Needs Graphviz's ``dot`` and ``chromium``.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this checkout's mitlc, whichever is installed

FIGURES = ROOT / "docs" / "figures"
TRAIN = ["train", "--spec", "pendulum/n1_reach_in_time", "--runs", "6", "--trials", "40", "-q"]
SWEEP = ["sweep", "pendulum/p2_avoid", "--grid", "sigma=1,3,6", "--grid", "weight.psi=1,3,10"]
SWEEP += ["--seeds", "2", "--runs", "4", "--trials", "60", "--workers", "1", "-q"]


def mitlc(*args: str, cwd: Path) -> None:
    code = f"import sys; sys.path.insert(0, {str(ROOT)!r}); from mitlc.cli import run; run()"
    subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, check=True, stdout=subprocess.DEVNULL)


def screenshot(page: Path, fragment: str, out: Path, size: str, profile: Path) -> None:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("headless Chromium is needed: apt-get install chromium")
    subprocess.run(
        [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",  # a container's small /dev/shm
            "--hide-scrollbars",
            f"--user-data-dir={profile}",
            f"--window-size={size}",
            f"--screenshot={out}",
            page.as_uri() + fragment,
        ],
        check=True,
        capture_output=True,
    )
    print(f"wrote {out.relative_to(ROOT)}")


def main() -> None:
    if shutil.which("dot") is None:
        raise SystemExit("Graphviz's dot is needed to draw the net: apt-get install graphviz")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        mitlc(*TRAIN, "--out", "n1", cwd=work)
        mitlc(*SWEEP, "--out", "sweep", cwd=work)
        metrics = json.loads((work / "n1" / "metrics.json").read_text())
        violated = [r for r, ok in enumerate(metrics["satisfied"]) if not ok]
        run = violated[0] if violated else 0
        step = 30
        FIGURES.mkdir(parents=True, exist_ok=True)
        profile = work / "chromium"
        screenshot(
            work / "n1" / "report.html",
            f"#run={run}&step={step}",
            FIGURES / "report_training.png",
            "1280,1500",
            profile,
        )
        screenshot(work / "sweep" / "report.html", "", FIGURES / "report_sweep.png", "1100,820", profile)


if __name__ == "__main__":
    main()
