"""Spec text to a checked :class:`Spec`: grammar, AST, parser and normal-form passes.

In: spec text (``.mitl`` files, formula strings). Out: :class:`Spec` (propositions as
predicates over a plant's state, a weighted MITL formula, init set, horizon, options,
``require`` criteria), its AST (:mod:`mitlc.spec.ast`), predicates
(:mod:`mitlc.spec.predicates`) and the pure passes over formulas
(:mod:`mitlc.spec.passes`).

May import: :mod:`mitlc.errors`, :mod:`mitlc.fileio`, :mod:`mitlc.limits`, :mod:`mitlc.plants`,
:mod:`mitlc.cachefiles` (the parser's tables).
"""

from mitlc.spec.model import CRITERIA, OPTIONS, InitRange, PropDef, Requirement, Spec
from mitlc.spec.parse import load_spec, parse_formula, parse_predicate, parse_spec

__all__ = [
    "CRITERIA",
    "OPTIONS",
    "InitRange",
    "PropDef",
    "Requirement",
    "Spec",
    "load_spec",
    "parse_formula",
    "parse_predicate",
    "parse_spec",
]
