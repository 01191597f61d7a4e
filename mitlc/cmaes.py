"""Hansen's ``cma`` package (CMA-ES), imported without the modules mitlc never asks of it.

``import cma`` also imports ``matplotlib.pyplot`` (for ``cma.plot``) and, where SciPy is installed,
``scipy.stats`` (for one rank correlation in its surrogate fitness models): 0.7-1.3 s of a process's
start on this project's machines, paid by every ``mitlc train`` that races the policy search and by
every process it forks before the first import. mitlc runs ``cma.CMAEvolutionStrategy``'s ask and
tell only, which use neither, so :func:`load` imports ``cma`` with those two modules held back (``cma``
has a fallback for each: no plotting, its own Kendall tau) and then lets them be imported as ever.
A process that has imported either before keeps it and ``cma`` uses it: the same search either way.
"""

from __future__ import annotations

import sys
import warnings
from types import ModuleType

__all__ = ["HELD_BACK", "load"]

HELD_BACK = ("matplotlib", "matplotlib.pyplot", "scipy", "scipy.stats")
"""The modules ``cma`` imports at its own import and mitlc's use of it never runs (with their packages:
an import of ``matplotlib`` alone costs 0.2 s)."""


def load() -> ModuleType:
    """``cma``, imported as described above; ImportError where it is not installed."""
    if "cma" in sys.modules:
        return sys.modules["cma"]
    held = [name for name in HELD_BACK if name not in sys.modules]
    for name in held:
        sys.modules[name] = None  # type: ignore[assignment]  # an import of it raises ImportError
    try:
        with warnings.catch_warnings():  # "Could not import matplotlib.pyplot, therefore cma.plot() ..."
            warnings.simplefilter("ignore")
            import cma
    finally:
        for name in held:
            if sys.modules.get(name, 0) is None:
                del sys.modules[name]
    return cma
