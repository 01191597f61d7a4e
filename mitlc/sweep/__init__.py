"""Many trainings: a spec trained over a grid of settings, weights and options.

In: a :class:`mitlc.spec.Spec`, grid axes (``NAME=V1,V2``), seeds. Out: one record per
task in a :class:`ResultStore` (``results.json``, ``results.csv``), summaries and a
heat map. Tasks run on a :class:`LocalBackend` (process pool) or a
:class:`RayBackend` (``pip install 'mitlc[ray]'``).

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.plants`,
:mod:`mitlc.spec`, :mod:`mitlc.petri`, :mod:`mitlc.hybrid`, :mod:`mitlc.monitor`,
:mod:`mitlc.learn`.
"""

from mitlc.sweep.engine import *  # noqa: F403  (replaced by the split below)
