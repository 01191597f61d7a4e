"""Spec and trajectory to verdict: the MITL monitor.

In: a :class:`mitlc.spec.Spec` (or a formula) and sampled traces, as arrays, mappings
of columns, or files (CSV, ``.npz``: :mod:`mitlc.monitor.trace`). Out:
:class:`MonitorResult`, the Boolean verdict and the robustness of each trace under
the standard finite-trace MITL semantics (docs/monitor.md), and where a trace failed.

:mod:`~mitlc.monitor.offline` evaluates a formula node by node over whole traces with
the array kernels of :mod:`~mitlc.monitor.kernels`; :mod:`~mitlc.monitor.online` judges
traces as they grow, and :mod:`~mitlc.monitor.scalar` one growing trace on Python numbers
(the Gymnasium wrapper's verdict after every step); :mod:`~mitlc.monitor.trace` reads
recorded traces from files.

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`, :mod:`mitlc.npzfile`
(trace .npz files), :mod:`mitlc.plants`, :mod:`mitlc.spec`.
"""

from mitlc.monitor.offline import (
    TIME_TOL,
    MonitorResult,
    judged_formula,
    monitor,
    needed_variables,
    offsets,
    signals,
    state_columns,
)
from mitlc.monitor.trace import Trace, read_trace

__all__ = [
    "TIME_TOL",
    "MonitorResult",
    "Trace",
    "judged_formula",
    "monitor",
    "needed_variables",
    "offsets",
    "read_trace",
    "signals",
    "state_columns",
]
