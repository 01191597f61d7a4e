"""Falsification-guided training: ``mitlc train --resume DIR --starts counterexamples.npz``.

The trials of a resumed SACPN training start, run by run, from one of the given states (the
``x0`` of ``mitlc verify``'s counterexamples.npz) with probability :data:`SHARE`, otherwise from
the spec's ``init`` box as before; the evaluation starts that ``mitlc train`` judges its success
rate on stay the box's. The extra draws come from each run's own generator, so a guided training
is as reproducible as any other (the same checkpoint and file give the same numbers).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import InputError

__all__ = ["SHARE", "read_starts", "guide_starts"]

SHARE = 0.5
"""The probability that a run's trial starts from one of the given states rather than the init box."""


def read_starts(path: str | Path, state_names: tuple[str, ...]) -> np.ndarray:
    """The states ``(K, n)`` of ``path`` (an ``.npz`` with ``x0``, and ``state_names`` in the plant's
    order when it has them); one line naming ``--starts`` for anything else."""
    label = f"--starts {path}"
    try:
        with np.load(path, allow_pickle=False) as f:
            if "x0" not in f.files:
                raise InputError("no array 'x0' (mitlc verify --out DIR writes DIR/counterexamples.npz)", file=label)
            x0 = np.asarray(f["x0"], dtype=float)
            names = tuple(str(n) for n in f["state_names"]) if "state_names" in f.files else None
    except InputError:
        raise
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read it as .npz: {exc}", file=label) from None
    if names is not None and names != tuple(state_names):
        raise InputError(f"its states are ({', '.join(names)}); the plant's are ({', '.join(state_names)})", file=label)
    if x0.ndim != 2 or x0.shape[1] != len(state_names):
        raise InputError(f"x0 has shape {x0.shape}; expected (K, {len(state_names)})", file=label)
    if x0.shape[0] == 0:
        raise InputError("no states in it (a verification that found no counterexample)", file=label)
    if not np.all(np.isfinite(x0)):
        raise InputError("a state that is not a finite number", file=label)
    return x0


def guide_starts(agent: Any, starts: np.ndarray, share: float = SHARE) -> None:
    """Make ``agent`` (a :class:`~mitlc.learn.sacpn.Sacpn`) start each run's trial from a state of
    ``starts`` with probability ``share``; its evaluation starts are left alone."""
    box = agent.sample_init
    trial_rngs = agent.rngs

    def sample_init(rngs: list[np.random.Generator]) -> np.ndarray:
        x = box(rngs)
        if rngs is trial_rngs:  # a trial's starts (the evaluation streams are other generators)
            for r, g in enumerate(rngs):
                if g.random() < share:
                    x[r] = starts[int(g.integers(starts.shape[0]))]
        return x

    agent.sample_init = sample_init
