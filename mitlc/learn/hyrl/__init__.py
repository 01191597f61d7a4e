"""HyRL, actor-critic learning on a hybrid automaton (thesis chapter 3), on a :class:`~mitlc.hybrid.HybridAutomaton`.

:mod:`~mitlc.learn.hyrl.hyrl` is the learner (:class:`HybridLearner`, :func:`train_hybrid`,
:func:`load_learner`); :mod:`~mitlc.learn.hyrl.evaluation` judges its greedy policies with the
criteria checker (:func:`evaluate`) and composes policies learned per requirement
(:func:`compose`, :func:`brake_bound`, :func:`train_handover`).
"""

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
from mitlc.learn.hyrl.hyrl import HybridLearner, HybridRollout, HyrlSettings, load_learner, q_warp_for, train_hybrid

__all__ = [
    "HANDOVER_SIGMA",
    "STABLE_FRACTION",
    "ComposedController",
    "Evaluation",
    "HybridLearner",
    "HybridRollout",
    "HyrlSettings",
    "brake_bound",
    "compose",
    "evaluate",
    "load_learner",
    "q_warp_for",
    "stabilised",
    "train_handover",
    "train_hybrid",
]
