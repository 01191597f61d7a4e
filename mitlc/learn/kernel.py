"""Deprecated: SACPN's fused trial kernel moved to :mod:`mitlc.learn.sacpn.kernel`, and the code
generation of the atoms to :mod:`mitlc.runtime.atoms`.

This module re-exports their names for one release and warns once when imported.
"""

import warnings

from mitlc.learn.sacpn.kernel import identity, jit, numba_available, rbf_kernel, trial_kernel, unsupported
from mitlc.runtime.atoms import atom_source, compile_atoms, scalar_atoms

__all__ = [
    "atom_source",
    "compile_atoms",
    "identity",
    "jit",
    "numba_available",
    "rbf_kernel",
    "scalar_atoms",
    "trial_kernel",
    "unsupported",
]

warnings.warn(
    "mitlc.learn.kernel moved to mitlc.learn.sacpn.kernel (the trial kernel) and mitlc.runtime.atoms (the atoms)",
    DeprecationWarning,
    stacklevel=2,
)
