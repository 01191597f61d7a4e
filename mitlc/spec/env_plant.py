"""The plant of ``plant gym:ID(...)`` in a spec: a Gymnasium environment whose observation the
spec's ``state`` lines map to named state variables (:mod:`mitlc.plants.gym_env`), each line
checked against the environment's observation space.
"""

from __future__ import annotations

import math
from typing import Any

from lark import Token

from mitlc.errors import MitlError, SpecError
from mitlc.plants.base import Plant, StateVar
from mitlc.plants.gym_env import GYM_PREFIX, ObsVar, check_env_id, env_info, gym_plant
from mitlc.spec import ast as A
from mitlc.spec import predicates as P
from mitlc.spec.checks import RESERVED, constant
from mitlc.spec.transform import token_pos

__all__ = ["gym_env_plant"]


def _columns(index: dict[str, int]) -> Any:
    """How compile_numpy reads ``obs[i]`` off a flattened observation batch ``(B, m)``."""

    def var(name: str) -> Any:
        i = index[name]
        return lambda flat: flat[:, i]

    return var


def gym_env_plant(tok: Token, params: list, state_lines: list) -> tuple[Plant, dict[str, float]]:
    """The plant of ``plant gym:ID(...)`` and its ``state`` lines (:mod:`mitlc.plants.gym_env`)."""
    env_id = str(tok)[len(GYM_PREFIX) :]
    try:
        check_env_id(env_id)  # first: 'gym:module:Env' would make Gymnasium import module
    except MitlError as exc:
        raise SpecError(exc.message, line=tok.line, column=tok.column, hint=exc.hint) from None
    values: dict[str, float] = {}
    for ptok, value in params:
        pname = str(ptok)
        if pname in values:
            raise SpecError(f"parameter '{pname}' given twice", line=ptok.line, column=ptok.column)
        number = constant(value, f"parameter '{pname}'", ptok)
        if not math.isfinite(number):
            raise SpecError(f"parameter '{pname}' must be finite", line=ptok.line, column=ptok.column)
        values[pname] = number
    dt_given = values.pop("dt", None)
    try:
        info = env_info(env_id, values)
    except MitlError as exc:
        raise SpecError(exc.message, line=tok.line, column=tok.column, hint=exc.hint) from None
    if dt_given is not None:
        if not dt_given > 0:
            raise SpecError(
                f"parameter 'dt' must be positive, got {A.fmt_number(dt_given)}", line=tok.line, column=tok.column
            )
        dt = dt_given
    elif info.dt is not None:
        dt = info.dt
        if not (math.isfinite(dt) and dt > 0):
            raise SpecError(
                f"{info.dt_where} is {dt}, not a positive time: give {tok}(dt = ...)", line=tok.line, column=tok.column
            )
    else:
        raise SpecError(
            f"'{env_id}' keeps no time step (no dt, tau or metadata['dt']): give the seconds per step, "
            f"plant {tok}(dt = ...)",
            line=tok.line,
            column=tok.column,
        )
    if not state_lines:
        raise SpecError(
            f"plant '{tok}' needs its state variables mapped to the observation "
            f"({len(info.obs_low)} entries): add a line such as 'state x = obs[0]'",
            line=tok.line,
            column=tok.column,
        )
    size = len(info.obs_low)
    observe: list[ObsVar] = []
    for st in state_lines:
        for ntok, expr, lo_p, hi_p in st[1]:
            name = str(ntok)
            if name in RESERVED or name in P.CONSTANTS:
                raise SpecError(
                    f"'{name}' is a reserved word and cannot name a state variable", line=ntok.line, column=ntok.column
                )
            if any(o.var.name == name for o in observe):
                raise SpecError(f"state variable '{name}' mapped twice", line=ntok.line, column=ntok.column)
            if P.is_boolean(expr):
                raise SpecError(
                    f"state variable '{name}' must be a number read off the observation, not a condition",
                    line=ntok.line,
                    column=ntok.column,
                )
            index: dict[str, int] = {}
            for v in P.variables(expr):
                pos = v.pos or token_pos(ntok)
                if not v.name.startswith("obs["):
                    raise SpecError(
                        f"a 'state' line reads the observation: write obs[i] (entry i of the flattened "
                        f"observation), not '{v.name}'",
                        line=pos.line,
                        column=pos.column,
                    )
                i = int(v.name[4:-1])
                if i >= size:
                    raise SpecError(
                        f"{v.name} is outside the observation of '{env_id}' "
                        f"({size} entries: obs[0] to obs[{size - 1}])",
                        line=pos.line,
                        column=pos.column,
                    )
                index[v.name] = i
            if not index:
                raise SpecError(
                    f"state variable '{name}' reads nothing of the observation", line=ntok.line, column=ntok.column
                )
            angle = isinstance(expr, P.Call) and expr.fn == "atan2"
            if lo_p is not None:
                lo = constant(lo_p, f"lower bound of '{name}'", ntok)
                hi = constant(hi_p, f"upper bound of '{name}'", ntok)
            elif angle:
                lo, hi = -math.pi, math.pi
            elif isinstance(expr, P.Var):
                lo, hi = float(info.obs_low[index[expr.name]]), float(info.obs_high[index[expr.name]])
                if not (math.isfinite(lo) and math.isfinite(hi)):
                    raise SpecError(
                        f"{expr.name} of '{env_id}' is unbounded ([{A.fmt_number(lo)}, {A.fmt_number(hi)}]): "
                        f"give its range, state {name} = {expr.name} in [lo, hi]",
                        line=ntok.line,
                        column=ntok.column,
                    )
            else:
                raise SpecError(
                    f"give the range of '{name}': state {name} = {expr} in [lo, hi]",
                    line=ntok.line,
                    column=ntok.column,
                )
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise SpecError(
                    f"the range of '{name}' must be finite with lower < upper, "
                    f"got [{A.fmt_number(lo)}, {A.fmt_number(hi)}]",
                    line=ntok.line,
                    column=ntok.column,
                )
            read = P.compile_numpy(expr, _columns(index))
            observe.append(ObsVar(StateVar(name, lo, hi, periodic=angle), read, str(expr), expr))
    plant = gym_plant(env_id, values, observe, dt, info)
    return plant, {**values, "dt": dt}
