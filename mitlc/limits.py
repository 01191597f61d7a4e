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
    "MAX_COLUMNS",
    "MAX_META_CHARS",
    "MAX_CHECKPOINT_ARRAY_BYTES",
    "MIN_RBF_WIDTH",
    "MAX_RBF_WIDTH",
    "MAX_MAGNITUDE",
    "MIN_SPAN",
    "check_steps",
    "check_samples",
]

MAX_SPEC_BYTES = 1 << 20
"""A spec file is read up to 1 MiB (the shipped ones are under 2 KiB)."""

MAX_STEPS = 1_000_000
"""Samples in one trial (``horizon / dt``) or one trace's time step count (a trace of
``MAX_STEPS + 1`` samples, rows of a CSV or entries of an ``.npz`` array, at most)."""

MAX_COLUMNS = 10_000
"""Columns in a CSV trace's header (the state variables and any others, which are ignored)."""

MIN_DT = 1e-9
"""The smallest sample time, in seconds (a trace's or a learner's)."""

MAX_TIME = 1e9
"""The largest finite time, in seconds, a horizon or a trial may have (about 32 years)."""

MAX_FEATURES = 100_000
"""RBF features per place (the product of the ``rbf`` counts)."""

MAX_LEARNER_BYTES = 4 << 30
"""Memory the learner's per-run arrays may take together (4 GiB)."""


def check_samples(samples: int, what: str = "the trace") -> None:
    """A ``ValueError`` when ``samples`` (of a trace) are more than :data:`MAX_STEPS` time steps."""
    if samples > MAX_STEPS + 1:
        raise ValueError(
            f"{what} has {samples:,} samples, more than the {MAX_STEPS + 1:,} supported ({MAX_STEPS:,} time steps)"
        )


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

MAX_META_CHARS = 1 << 24
"""Characters of a checkpoint's ``meta`` record (its JSON): 16 Mi, room for a spec at its
limit (:data:`MAX_SPEC_BYTES`) and the random generators' states of some 50,000 runs."""

MAX_CHECKPOINT_ARRAY_BYTES = MAX_LEARNER_BYTES // 4
"""Bytes, unpacked, of one array of a checkpoint (``xi``, ``theta``, ``returns``): 1 GiB, the
most a learner's actor may take (its four arrays share :data:`MAX_LEARNER_BYTES`)."""

MIN_RBF_WIDTH = 0.02
"""The narrowest RBF width (a multiple of the centre spacing): the nearest centre's exponent,
``-1 / (8 w^2)``, stays above -313, so the features never all underflow to 0 (0 / 0)."""

MAX_RBF_WIDTH = 1000.0
"""The widest RBF width (a multiple of the centre spacing): flat features already; far wider
overflows ``(width x spacing)^2``."""

MAX_MAGNITUDE = 1e12
"""The largest magnitude of a learner setting in the plant's units (an exploration ``sigma``, a
feature grid's bounds): far above any plant's range, far below where products overflow."""

MIN_SPAN = 1e-9
"""The narrowest range of a feature grid (``hi - lo`` of a ``feature_bounds`` entry, HyRL's
``qdot_grid``), in the plant's units: narrower, the centres' spacing squared underflows."""
