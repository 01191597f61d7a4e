"""What the docs scripts share: the 95 % interval over seeds, and the machine a page was made on."""

from __future__ import annotations

import math
import os
import platform

import numpy as np

__all__ = ["T_975", "interval", "machine"]

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
