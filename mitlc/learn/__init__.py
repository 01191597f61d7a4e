"""Reward system and plant to policy: the runtime and the learners.

In: a :class:`mitlc.petri.RewardSystem` or a :class:`mitlc.hybrid.HybridAutomaton`,
and a :class:`mitlc.plants.Plant`. Out: trained policies with their learning curves
and rollouts. :class:`NetRuntime` steps the net and its reward alongside a batch of
plant states (:mod:`mitlc.learn.runtime`); :class:`Sacpn` is Algorithm 1
(:mod:`mitlc.learn.sacpn`); :class:`HybridLearner` is HyRL, one actor-critic per
mode (:mod:`mitlc.learn.hyrl`, judged and composed by :mod:`mitlc.learn.hyrl_eval`); both use the RBF features of
:mod:`mitlc.learn.features` and settings read by :mod:`mitlc.learn.settings`;
:mod:`mitlc.learn.plots` draws what they produce.

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`, :mod:`mitlc.cachefiles`,
:mod:`mitlc.npzfile`, :mod:`mitlc.plants`, :mod:`mitlc.spec`, :mod:`mitlc.petri`, :mod:`mitlc.hybrid` (never
the monitor: the learners are judged by it, from a later stage).
"""

from mitlc.learn.features import Axis, RbfFeatures
from mitlc.learn.hyrl import HybridLearner, HybridRollout, HyrlSettings, load_learner
from mitlc.learn.hyrl_eval import ComposedController, Evaluation, compose, evaluate
from mitlc.learn.runtime import NetRuntime
from mitlc.learn.sacpn import Rollout, Sacpn, SacpnSettings

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
