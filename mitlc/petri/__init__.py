"""Spec to reward system: the Petri-net compiler (thesis chapter 4).

In: :class:`mitlc.spec.Spec`. Out: :class:`RewardSystem`, one composed :class:`Net`
(places, transitions with guards, ``D-``, ``D+``, ``D``, ``M0``) and a reward
expression over token counts now and one step ago (Table 4-2,
:mod:`mitlc.petri.reward`); exports to JSON, text, PNML and networkx
(:mod:`mitlc.petri.export`) and Graphviz drawings (:mod:`mitlc.petri.render`).

The builder of :mod:`~mitlc.petri.compile` takes its sub-nets from one module per kind:
:mod:`~mitlc.petri.regions` (state), :mod:`~mitlc.petri.timeline` (the trial clock),
:mod:`~mitlc.petri.violations` (violation watches and the penalty's bounds), as
:class:`~mitlc.petri.parts.Part` drafts; :mod:`~mitlc.petri.reading` holds the
formula-level helpers, :mod:`~mitlc.petri.options` the :class:`CompileOptions` both the
builder and the violation watches read.

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`, :mod:`mitlc.plants`,
:mod:`mitlc.spec`.
"""

from mitlc.petri.compile import CompileOptions, RewardSystem, compile_spec
from mitlc.petri.net import Net

__all__ = ["CompileOptions", "Net", "RewardSystem", "compile_spec"]
