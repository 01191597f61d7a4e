"""Reward system and plant to policy: the learners.

In: a :class:`mitlc.petri.RewardSystem` (stepped by :class:`mitlc.runtime.NetRuntime`) or a
:class:`mitlc.hybrid.HybridAutomaton`, and a :class:`mitlc.plants.Plant`. Out: trained policies
with their learning curves and rollouts. One folder per learner: :mod:`mitlc.learn.sacpn`
(:class:`Sacpn`, Algorithm 1, and its fused kernel) and :mod:`mitlc.learn.hyrl`
(:class:`HybridLearner`, HyRL, one actor-critic per mode, judged and composed by
:mod:`mitlc.learn.hyrl.evaluation`). What both use lies here: the RBF features
(:mod:`~mitlc.learn.features`), settings (:mod:`~mitlc.learn.settings`), checkpoints
(:mod:`~mitlc.learn.checkpoint`), saved policies (:mod:`~mitlc.learn.policy`), the disk cache of
compiled kernels (:mod:`~mitlc.learn.jitcache`) and figures (:mod:`~mitlc.learn.plots`).

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`, :mod:`mitlc.cachefiles`,
:mod:`mitlc.cmaes`, :mod:`mitlc.npzfile`, :mod:`mitlc.plants`, :mod:`mitlc.spec`, :mod:`mitlc.petri`,
:mod:`mitlc.hybrid`, :mod:`mitlc.runtime` (never the monitor: the learners are judged by it, from a later stage).
"""

from mitlc.learn.features import Axis, RbfFeatures
from mitlc.learn.hyrl import (
    ComposedController,
    Evaluation,
    HybridLearner,
    HybridRollout,
    HyrlSettings,
    compose,
    evaluate,
    load_learner,
)
from mitlc.learn.sacpn import Rollout, Sacpn, SacpnSettings
from mitlc.runtime import NetRuntime  # re-exported: mitlc.learn.NetRuntime predates mitlc.runtime

__all__ = [
    "Axis",
    "ComposedController",
    "Evaluation",
    "HybridLearner",
    "HybridRollout",
    "HyrlSettings",
    "NetRuntime",
    "RbfFeatures",
    "Rollout",
    "Sacpn",
    "SacpnSettings",
    "compose",
    "evaluate",
    "load_learner",
]
