"""Ctrl-C that is never lost.

Python turns SIGINT into a KeyboardInterrupt at the next bytecode, wherever that is; when
it is inside a weakref callback or a ``__del__`` (the import system runs such callbacks
while it loads modules) the exception is printed as "Exception ignored" and dropped, and a
training the user meant to stop runs on. :func:`install` replaces Python's handler by one
that also remembers the signal (and keeps such a dropped interrupt's traceback off the
screen), and the trainers' per-trial callbacks call :func:`check`, which raises the
interrupt again if it was swallowed. Only the standard library here: it
is installed before anything else of the command line loads.

:func:`exit_interrupted` ends the program with status 130. CPython 3.11 marks a
KeyboardInterrupt that leaves an ``exec()`` as unhandled and then exits by SIGINT (status
-2) even after the program handled it, and ``dataclasses`` builds methods with ``exec``
while modules load; so in the ``mitlc`` process itself (:data:`PROGRAM`) after a real
SIGINT it runs the exit functions, flushes, and leaves by ``os._exit(130)``.
"""

from __future__ import annotations

import atexit
import os
import signal
import sys
from types import FrameType
from typing import NoReturn

__all__ = ["install", "check", "pending", "exit_interrupted", "PROGRAM"]

_seen = False
PROGRAM = False
"""Set by the entry points (``mitlc``, ``python -m mitlc``): this process is mitlc's own."""


def _handler(signum: int, frame: FrameType | None) -> None:
    global _seen
    _seen = True
    raise KeyboardInterrupt


def _unraisable(unraisable: sys.UnraisableHookArgs) -> None:
    # a remembered Ctrl-C that Python could not raise (a weakref callback, a __del__, a ctypes
    # callback such as numba's object cache): no "Exception ignored" traceback, check() raises it
    if _seen and isinstance(unraisable.exc_value, KeyboardInterrupt):
        return
    _python_unraisable(unraisable)


_python_unraisable = sys.unraisablehook


def install() -> None:
    """Remember every SIGINT (where Python's own handler is in place: not when it is ignored)."""
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _handler)
        sys.unraisablehook = _unraisable


def pending() -> bool:
    """Whether a SIGINT came since :func:`install`."""
    return _seen


def check() -> None:
    """Raise KeyboardInterrupt if a SIGINT came (its first raise may have been swallowed)."""
    if _seen:
        raise KeyboardInterrupt


def exit_interrupted(force: bool = False) -> NoReturn:
    """Exit with status 130 (see the module text); ``force``: as the program even before
    :data:`PROGRAM` is set (a Ctrl-C while the command line itself loads)."""
    if _seen and (PROGRAM or force):
        atexit._run_exitfuncs()
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):  # pragma: no cover - a closed stream
                pass
        os._exit(130)
    sys.exit(130)
