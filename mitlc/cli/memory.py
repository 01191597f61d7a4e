"""A training process keeps the memory numpy frees for its next arrays.

glibc's ``malloc`` gives an array of more than its threshold (128 KB, raised as such arrays are
freed, up to 32 MB) pages of its own from the system, and returns freed memory at the heap's top once
more than twice that is free: a policy search or a monitor judging hundreds of rollouts makes and
drops arrays of a megabyte or more many times a generation, and each one's pages are faulted in
afresh (the cart-pole's sway, 8 runs x 100 generations of the search: 1.24 million page faults).
:func:`keep_freed_memory` sets the threshold to its largest (32 MB) and keeps up to 256 MB freed at
the heap's top: 25 thousand faults there, the same peak memory. Processes forked by the command
(the race's, the search's) inherit it. Elsewhere than glibc it does nothing.
"""

from __future__ import annotations

import sys

__all__ = ["keep_freed_memory"]

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's malloc.h
_MMAP_THRESHOLD = 32 * 2**20  # the most glibc takes on 64-bit machines
_TRIM_THRESHOLD = 256 * 2**20


def keep_freed_memory() -> bool:
    """Tune glibc's ``malloc`` for this process (see the module); whether it was set."""
    if not sys.platform.startswith("linux"):
        return False
    import ctypes
    import platform

    if platform.libc_ver()[0] != "glibc":
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD)) and bool(
            libc.mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD)
        )
    except (OSError, AttributeError):  # no such library or function: malloc as it is
        return False
