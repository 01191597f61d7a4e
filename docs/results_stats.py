"""What the docs scripts share: the 95 % interval over seeds, the machine a page was made on, and
trainings kept on disk so that a long run that stops is resumed by the same command."""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import platform
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

__all__ = ["T_975", "interval", "machine", "code_digest", "run_cached"]

T_975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262}
"""Student's t, two-sided 95 %, by degrees of freedom."""


def interval(values: list[float]) -> tuple[float, float]:
    """Mean over seeds and the half-width of its 95 % t interval (nan for one seed)."""
    m = float(np.mean(values))
    if len(values) < 2:
        return m, math.nan
    return m, T_975[len(values) - 1] * float(np.std(values, ddof=1)) / math.sqrt(len(values))


def machine(*modules: str) -> str:
    """``2 cores, Python 3.11.9, numpy 2.3.1, ...`` for the page's header."""
    import importlib

    parts = [f"{os.cpu_count()} cores", f"Python {platform.python_version()}"]
    for name in ("numpy", *modules):
        try:
            parts.append(f"{name} {importlib.import_module(name).__version__}")
        except ImportError:
            parts.append(f"{name} absent")
    return ", ".join(parts)


ROOT = Path(__file__).resolve().parent.parent


@functools.cache
def code_digest(script: str) -> str:
    """The package's source and the script's, hashed: a kept training is used only by the code that made it."""
    h = hashlib.sha256()
    for path in sorted((ROOT / "mitlc").rglob("*.py")):
        h.update(path.read_bytes())
    h.update(Path(script).read_bytes())
    return h.hexdigest()


def run_cached(
    train: Callable[[tuple], dict],
    jobs: Sequence[tuple],
    workers: int,
    cache: Path | None = None,
    name: Callable[[tuple], str] | None = None,
) -> tuple[list[dict], int]:
    """Every job's result in order, and how many came from ``cache`` (``name(job)``: its file there).

    The others are trained in ``workers`` processes; each is printed as it finishes and kept.
    """
    from mitlc.fileio import atomic_write

    done: dict[int, dict] = {}
    if cache is not None:
        assert name is not None
        cache.mkdir(parents=True, exist_ok=True)
        for i, job in enumerate(jobs):
            f = cache / name(job)
            if f.is_file():
                done[i] = json.loads(f.read_text(encoding="utf-8"))
    kept = len(done)
    todo = [i for i in range(len(jobs)) if i not in done]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for i, r in zip(todo, pool.map(train, [jobs[i] for i in todo]), strict=True):
            print(f"{r['job']}: success {r['success']:.2f} ({r['wall_s']:.0f} s)", flush=True)
            if cache is not None:
                assert name is not None
                atomic_write(cache / name(jobs[i]), json.dumps(r) + "\n")
            done[i] = r
    return [done[i] for i in range(len(jobs))], kept
