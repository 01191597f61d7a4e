"""SACPN, the standard actor-critic with a Petri net (thesis Algorithm 1), on a :class:`~mitlc.petri.RewardSystem`.

:mod:`~mitlc.learn.sacpn.sacpn` is the learner (:class:`Sacpn`, its :class:`SacpnSettings`,
the :class:`Rollout` of a trained policy); :mod:`~mitlc.learn.sacpn.kernel` is its fused
trial kernel, one loop over runs and steps compiled by numba (``mitlc[fast]``), kept to the
bit with the numpy trial.
"""

from mitlc.learn.sacpn.sacpn import MAX_SIGMA_FRAC, Rollout, Sacpn, SacpnSettings, read_meta

__all__ = ["MAX_SIGMA_FRAC", "Rollout", "Sacpn", "SacpnSettings", "read_meta"]
