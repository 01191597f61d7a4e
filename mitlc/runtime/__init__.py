"""Reward system to markings and rewards: the executable reward net, between the compiler and its users.

In: a :class:`mitlc.petri.RewardSystem` and the names of a plant's state variables (the columns
of the state arrays it will be given). Out: per step of ``R`` runs at once, markings (or their
integer codes), the step's rewards and violation charges, and the timed obligations' verdicts
so far. :class:`NetRuntime` (:mod:`~mitlc.runtime.netruntime`) is what the learners, the
Gymnasium wrapper and ``mitlc check --net`` step; its pieces:

* :mod:`~mitlc.runtime.atoms`: propositions as code (numpy closures over a batch, generated
  source for a compiled kernel, plain Python for one sample);
* :mod:`~mitlc.runtime.rule`: the firing rule on batches of markings (:class:`~mitlc.runtime.rule.Rule`);
* :mod:`~mitlc.runtime.tables`: the rule and the reward tabulated over marking, atom and clock codes;
* :mod:`~mitlc.runtime.tablefile`: those tables kept on disk between processes, as data;
* :mod:`~mitlc.runtime.obligations`: the timed obligations' per-run state, stepped per sample;
* :mod:`~mitlc.runtime.obligation_kernel`: the same for one run as flat arrays and plain Python over
  scalars (what SACPN's compiled trial kernel steps).

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`, :mod:`mitlc.cachefiles`
and :mod:`mitlc.npzfile` (the tables' disk cache), :mod:`mitlc.spec`, :mod:`mitlc.petri`.
"""

from mitlc.runtime.atoms import atom_source, compile_atoms, scalar_atoms
from mitlc.runtime.netruntime import NetRuntime

__all__ = ["NetRuntime", "atom_source", "compile_atoms", "scalar_atoms"]
