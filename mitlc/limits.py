"""The sizes mitlc refuses, in one place (docs/reliability.md lists them).

Each limit is far above what a real task needs and below what would hang the
machine or run it out of memory: past one, mitlc stops before the work with one
line naming the value and the limit, instead of running for hours or dying.
"""

from __future__ import annotations

__all__ = [
    "MAX_SPEC_BYTES",
    "MAX_STEPS",
    "MIN_DT",
    "MAX_TIME",
    "MAX_FEATURES",
    "MAX_LEARNER_BYTES",
    "MAX_DENSE_ENTRIES",
    "check_steps",
]

MAX_SPEC_BYTES = 1 << 20
"""A spec file is read up to 1 MiB (the shipped ones are under 2 KiB)."""

MAX_STEPS = 1_000_000
"""Samples in one trial (``horizon / dt``) or one trace's time step count."""

MIN_DT = 1e-9
"""The smallest sample time, in seconds (a trace's or a learner's)."""

MAX_TIME = 1e9
"""The largest finite time, in seconds, a horizon or a trial may have (about 32 years)."""

MAX_FEATURES = 100_000
"""RBF features per place (the product of the ``rbf`` counts)."""

MAX_LEARNER_BYTES = 4 << 30
"""Memory the learner's per-run arrays may take together (4 GiB)."""


def check_steps(duration: float, dt: float, what: str) -> int:
    """``round(duration / dt)``, the number of samples, or a ``ValueError`` saying which limit it breaks."""
    if not dt >= MIN_DT:
        raise ValueError(f"{what}: the time step {dt:g} s is below the smallest supported, {MIN_DT:g} s")
    if not duration <= MAX_TIME:
        raise ValueError(f"{what}: {duration:g} s is longer than the longest supported, {MAX_TIME:g} s")
    steps = round(duration / dt)
    if steps > MAX_STEPS:
        raise ValueError(
            f"{what}: {duration:g} s at {dt:g} s per step is {steps:,} steps, more than the {MAX_STEPS:,} supported"
        )
    return max(1, int(steps))


MAX_DENSE_ENTRIES = 1 << 25
"""Entries (transitions x places) up to which a net's dense ``D-``, ``D+`` and ``D`` are built
on request (256 MiB each as int64); a net keeps them sparse and refuses the dense view past it."""
