"""Where mitlc keeps files it can rebuild (compiled kernels, the spec parser's tables).

``$MITLC_CACHE_DIR`` if set (empty: no disk cache), else ``$XDG_CACHE_HOME/mitlc`` or
``~/.cache/mitlc``. Everything there is mitlc's own and safe to delete. This module
imports nothing heavy: ``mitlc check`` asks it where the parser's tables are.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["cache_root"]


def cache_root() -> Path | None:
    """mitlc's cache folder, or None when the disk cache is off (``MITLC_CACHE_DIR=``)."""
    env = os.environ.get("MITLC_CACHE_DIR")
    if env is not None:
        return Path(env) if env else None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "mitlc"
