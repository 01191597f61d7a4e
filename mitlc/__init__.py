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


def load_policy(directory):  # noqa: ANN001, ANN201 - typed in mitlc.learn.policy
    """The trained policy in ``directory`` (``mitlc train --out``): SACPN or HyRL, with
    ``reset(x0)``, ``act(x, state)``, ``step(state, x_next)`` and ``spec``
    (:mod:`mitlc.learn.policy`; imported when called, so ``import mitlc`` stays light)."""
    from mitlc.learn.policy import load_policy as _load

    return _load(directory)


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
    "load_policy",
    "load_spec",
    "parse_formula",
    "parse_spec",
]
