"""Progress on stderr for ``mitlc train`` (SACPN and HyRL) and ``mitlc sweep``.

* On a terminal: a tqdm bar. Until the first step (trial, task) is done it shows no
  rate and no ETA: the first trial of a new spec includes compiling the kernel, and a
  rate measured on it predicted hours (``0/500 ... ETA 1:31:52``). From the first step
  on the bar's rate and ETA are those of the steps after it.
* Anywhere else (``2> log``, a pipe, CI): no carriage-return frames but one plain line
  each time another 5 % of the steps is done, so 20 lines for 20 steps or more and one
  per step for fewer::

      p2_avoid: trial 25/500 (5%), mean return -123.4, elapsed 00:12, ETA 03:48

* ``quiet``: nothing (the command's final line is its own).

:func:`compile_notice` prints the one line :mod:`mitlc.learn.jitcache` gives when a
kernel is about to be compiled rather than loaded from the disk cache.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterator
from typing import Any, TextIO

__all__ = ["Progress", "compile_notice", "LINES"]

LINES = 20
"""Plain lines per run of steps away from a terminal: one per 5 %."""


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # no isatty, or a closed stream
        return False


def _write(line: str) -> None:
    """``line`` on stderr, above a tqdm bar if one is shown there."""
    from tqdm import tqdm

    tqdm.write(line, file=sys.stderr)
    sys.stderr.flush()


@contextlib.contextmanager
def compile_notice(quiet: bool = False) -> Iterator[None]:
    """While inside: a kernel about to be compiled is announced on stderr (not when ``quiet``)."""
    from mitlc.learn import jitcache

    before = jitcache.set_notice(None if quiet else _write)
    try:
        yield
    finally:
        jitcache.set_notice(before)


_BAR: type | None = None


def _bar_class() -> type:
    """tqdm with :attr:`before` seconds added to the elapsed time it shows but not to the
    time its rate (and so its ETA) is measured over."""
    global _BAR
    if _BAR is None:
        from tqdm import tqdm

        class Bar(tqdm):
            def __init__(self, *args: Any, before: float = 0.0, **kwargs: Any) -> None:
                self.before = before
                super().__init__(*args, **kwargs)

            @property
            def format_dict(self) -> dict:
                d = super().format_dict
                if d.get("rate") is None and d["elapsed"]:  # tqdm's own fallback, over this bar's time
                    d["rate"] = (d["n"] - d["initial"]) / d["elapsed"]
                d["elapsed"] += self.before
                return d

        _BAR = Bar
    return _BAR


class Progress:
    """``total`` steps, ``initial`` of them done before (a resumed training), shown as
    the module says; :meth:`update` after each step, :meth:`close` at the end."""

    def __init__(
        self,
        total: int,
        initial: int = 0,
        *,
        desc: str,
        unit: str = "trial",
        quiet: bool = False,
        stream: TextIO | None = None,
    ) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.total, self.n = int(total), int(initial)
        self.desc, self.unit, self.quiet = desc, unit, quiet
        self.tty = not quiet and _isatty(self.stream)
        self.start = time.perf_counter()
        self._first: tuple[int, float] | None = None  # (steps done, time) when the first step ended
        self._shown = self._mark(self.n)
        self._bar: Any = self._new_bar(first=True) if self.tty else None

    def _mark(self, n: int) -> int:
        """How many 5 % marks ``n`` steps have reached."""
        return n * LINES // self.total if self.total > 0 else 0

    def _new_bar(self, first: bool, before: float = 0.0) -> Any:
        plain = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} [{elapsed}{postfix}]"
        bar = _bar_class()(
            total=self.total,
            initial=self.n,
            unit=self.unit,
            dynamic_ncols=True,
            desc=self.desc,
            file=self.stream,
            leave=not first,
            bar_format=plain if first else None,
            before=before,
        )
        return bar

    def update(self, postfix: str = "") -> None:
        """One more step done; ``postfix`` (e.g. ``mean return -12.3``) goes with it."""
        self.n += 1
        now = time.perf_counter()
        first = self._first is None
        if first:
            self._first = (self.n, now)
        if self.quiet:
            return
        if self._bar is not None:
            if first:  # from now on with rate and ETA, measured from here
                before = self._bar.format_dict["elapsed"]
                self._bar.close()
                self._bar = self._new_bar(first=False, before=before)  # in the elapsed time, not in the rate
                self._bar.set_postfix_str(postfix)
            else:
                self._bar.set_postfix_str(postfix, refresh=False)
                self._bar.update(1)
            return
        mark = self._mark(self.n)
        if mark <= self._shown:
            return
        self._shown = mark
        self.stream.write(self.line(postfix, now) + "\n")
        self.stream.flush()

    def extend(self, more: int) -> None:
        """``more`` steps to do after the ``total`` planned (a search's restarts, planned once the first
        search is judged): the count, the percentage and the ETA go on over the new total."""
        self.total += int(more)
        self._shown = self._mark(self.n)
        if self._bar is not None:
            self._bar.total = self.total
            self._bar.refresh()

    def line(self, postfix: str, now: float) -> str:
        """The plain line of the step just done."""
        from tqdm import tqdm

        parts = [f"{self.desc}: {self.unit} {self.n}/{self.total} ({100 * self.n // self.total}%)"]
        if postfix:
            parts.append(postfix)
        parts.append(f"elapsed {tqdm.format_interval(now - self.start)}")
        assert self._first is not None
        n0, t0 = self._first
        if self.n > n0 and now > t0:  # the rate of the steps after the first
            parts.append(f"ETA {tqdm.format_interval((self.total - self.n) * (now - t0) / (self.n - n0))}")
        return ", ".join(parts)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
