"""mitlc: compile MITL control specifications into reward Petri nets for RL.

>>> import mitlc
>>> rs = mitlc.compile_spec(mitlc.parse_spec("prop k = abs(q) < 0.3\\nformula F G k"))
>>> print(rs.reward)
(1 + ~p_k) * (p_k - p_not_k)
"""

from typing import TYPE_CHECKING, Any

from mitlc.errors import CompileError, InputError, MitlError, SpecError, SpecSyntaxError, TrainingError

if TYPE_CHECKING:
    from mitlc.petri.compile import CompileOptions, RewardSystem, compile_spec
    from mitlc.spec.parse import load_spec, parse_formula, parse_spec

__version__ = "0.1.0"

_LAZY = {
    "CompileOptions": "mitlc.petri.compile",
    "RewardSystem": "mitlc.petri.compile",
    "compile_spec": "mitlc.petri.compile",
    "load_spec": "mitlc.spec.parse",
    "parse_formula": "mitlc.spec.parse",
    "parse_spec": "mitlc.spec.parse",
}


def __getattr__(name: str) -> Any:
    """The facade's compiler and parser, imported on first use: ``import mitlc`` (and so the
    command line's start-up, where a Ctrl-C must stay a clean exit 130) stays light."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'mitlc' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


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
