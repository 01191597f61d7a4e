"""Deprecated: moved to :mod:`mitlc.learn.hyrl.evaluation` (``from mitlc.learn.hyrl import evaluate, compose``).

This module re-exports its names for one release and warns once when imported.
"""

import warnings

from mitlc.learn.hyrl.evaluation import (
    HANDOVER_SIGMA,
    STABLE_FRACTION,
    ComposedController,
    Evaluation,
    brake_bound,
    compose,
    evaluate,
    stabilised,
    train_handover,
)

__all__ = [
    "HANDOVER_SIGMA",
    "STABLE_FRACTION",
    "ComposedController",
    "Evaluation",
    "brake_bound",
    "compose",
    "evaluate",
    "stabilised",
    "train_handover",
]

warnings.warn(
    "mitlc.learn.hyrl_eval moved to mitlc.learn.hyrl.evaluation: use 'from mitlc.learn.hyrl import evaluate, compose'",
    DeprecationWarning,
    stacklevel=2,
)
