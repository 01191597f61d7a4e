"""Deprecated: the runtime moved to :mod:`mitlc.runtime` (``from mitlc.runtime import NetRuntime``).

This module re-exports it for one release and warns once when imported.
"""

import warnings

from mitlc.runtime.netruntime import NetRuntime

__all__ = ["NetRuntime"]

warnings.warn(
    "mitlc.learn.runtime moved to mitlc.runtime: use 'from mitlc.runtime import NetRuntime'",
    DeprecationWarning,
    stacklevel=2,
)
