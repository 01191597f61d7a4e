"""Mode-wise rewards of a hybrid automaton: the thesis's building blocks (3-11)/(3-12) as data."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.hybrid.guards import Guard, Lin, evaluate, fmt_const, guard_to_dict

# ---------------------------------------------------------------- rewards


@dataclass(frozen=True, slots=True)
class Const:
    """A constant reward per step (the discrete reward (3-11) with S = X)."""

    value: float

    def __str__(self) -> str:
        return fmt_const(self.value)


@dataclass(frozen=True, slots=True)
class AbsError:
    """``-weight * |q - target|``, the reward (3-12) on the position."""

    weight: float
    target: Lin

    def __str__(self) -> str:
        target = str(self.target)
        parts = len(self.target.terms) + (self.target.const != 0)
        if parts == 0:
            err = "q"
        elif parts > 1:
            err = f"q - ({target})"
        elif target.startswith("-"):
            err = f"q + {target[1:]}"
        else:
            err = f"q - {target}"
        return f"-{fmt_const(self.weight)}*|{err}|"


@dataclass(frozen=True, slots=True)
class IfElse:
    """``then`` where ``guard`` holds after the step, else ``otherwise`` (the discrete reward (3-11))."""

    guard: Guard
    then: float
    otherwise: float

    def __str__(self) -> str:
        return f"({fmt_const(self.then)} if {self.guard} else {fmt_const(self.otherwise)})"


@dataclass(frozen=True, slots=True)
class StayBonus:
    """``value`` when the automaton was in this mode before and after the step
    (Table 3-1: ``+3 if delta = delta' = S``)."""

    value: float

    def __str__(self) -> str:
        return f"({fmt_const(self.value)} if stayed)"


RewardTerm = Const | AbsError | IfElse | StayBonus


@dataclass(frozen=True, slots=True)
class Reward:
    """A mode's reward: the sum of its terms, evaluated on the state after the step."""

    terms: tuple[RewardTerm, ...]

    def value(self, env: Mapping[str, Any], stayed: np.ndarray) -> np.ndarray:
        out = np.zeros(np.shape(env["q"]))
        for term in self.terms:
            if isinstance(term, Const):
                out += term.value
            elif isinstance(term, AbsError):
                out -= term.weight * np.abs(env["q"] - term.target.value(env))
            elif isinstance(term, IfElse):
                out += np.where(evaluate(term.guard, env), term.then, term.otherwise)
            else:
                out += np.where(stayed, term.value, 0.0)
        return out

    def __str__(self) -> str:
        if not self.terms:
            return "0"
        out = str(self.terms[0])
        for term in self.terms[1:]:
            text = str(term)
            out += f" - {text[1:]}" if text.startswith("-") else f" + {text}"
        return out

    def to_dict(self) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        for t in self.terms:
            if isinstance(t, Const):
                out.append({"const": t.value})
            elif isinstance(t, AbsError):
                out.append({"abs_error": {"weight": t.weight, "target": t.target.to_dict()}})
            elif isinstance(t, IfElse):
                out.append({"if": guard_to_dict(t.guard), "then": t.then, "else": t.otherwise})
            else:
                out.append({"stay_bonus": t.value})
        return out


@dataclass(frozen=True)
class RewardConstants:
    """The constants of the mode-wise rewards (Tables 3-1 / B-2 and 3-3 / B-4)."""

    idle_penalty: float = 3.0
    """rho_1: ``-3`` per step in I unless moving towards the set-point."""

    error_weight: float = 3.0
    """rho_2, rho_3: ``-3 |q_des - q|`` in the evaluating and stabilising modes."""

    stay_bonus: float = 3.0
    """rho_3: ``+3`` when ``delta = delta' = S``."""

    penalty: float = 9.0
    """rho_4: ``-9`` per step in P."""
