"""mitlc: compile MITL control specifications into reward Petri nets for RL.

>>> import mitlc
>>> rs = mitlc.compile_spec(mitlc.parse_spec("prop k = abs(q) < 0.3\\nformula F G k"))
>>> print(rs.reward)
(1 + ~p_k) * (p_k - p_not_k)
"""

from mitlc.errors import CompileError, InputError, MitlError, SpecError, SpecSyntaxError, TrainingError
from mitlc.petri.compile import CompileOptions, RewardSystem, compile_spec
from mitlc.spec.parse import load_spec, parse_formula, parse_spec

__version__ = "0.1.0"

__all__ = [
    "CompileError",
    "CompileOptions",
    "InputError",
    "MitlError",
    "RewardSystem",
    "SpecError",
    "SpecSyntaxError",
    "TrainingError",
    "compile_spec",
    "load_spec",
    "parse_formula",
    "parse_spec",
]
