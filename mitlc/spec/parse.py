"""Parse spec text into a checked :class:`~mitlc.spec.model.Spec`.

The one grammar is ``grammar/mitl.lark`` (shipped inside the wheel as
``mitlc/grammar/mitl.lark``).  One :class:`lark.Transformer`
(:class:`mitlc.spec.transform.Build`) builds the AST while the LALR parser
(:mod:`mitlc.spec.lark_tables`) runs, so deeply nested input cannot exhaust the Python
stack.  Every problem becomes a :class:`~mitlc.errors.SpecSyntaxError`
(:mod:`mitlc.spec.syntax_errors`) or :class:`~mitlc.errors.SpecError` with file, line
and column.  This module checks the statements of a spec; the checks that formulas and
predicates share are in :mod:`mitlc.spec.checks`, a Gymnasium plant's ``state`` lines in
:mod:`mitlc.spec.env_plant`.

>>> print(parse_formula("[] (a -> <>[0:2.5] b) && !c"))
G (a -> F[0,2.5] b) & !c
>>> parse_formula("F[2,1] a")
Traceback (most recent call last):
  ...
mitlc.errors.SpecError: <spec>:1:3: error: inverted interval [2,1]: the lower end must not exceed the upper
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import lark
from lark import Token

from mitlc.errors import MitlError, SpecError
from mitlc.limits import MAX_SPEC_BYTES, MAX_TIME
from mitlc.plants.base import PLANTS
from mitlc.plants.gym_env import GYM_PREFIX
from mitlc.spec import ast as A
from mitlc.spec import predicates as P
from mitlc.spec.checks import MAX_DEPTH, MAX_TREE, RESERVED, check_depth, check_weights, constant, too_deep
from mitlc.spec.env_plant import gym_env_plant
from mitlc.spec.lark_tables import parser_for
from mitlc.spec.model import CRITERIA, OPTIONS, InitRange, PropDef, Requirement, Spec
from mitlc.spec.syntax_errors import syntax_error, text_lines
from mitlc.spec.transform import as_pred, token_pos

__all__ = ["parse_spec", "load_spec", "parse_formula", "parse_predicate", "MAX_DEPTH", "MAX_TREE", "RESERVED"]


def _run(start: str, text: str, path: str | None) -> Any:
    try:
        return parser_for(start).parse(text)
    except lark.exceptions.UnexpectedInput as exc:
        raise syntax_error(exc, text).located(path) from None
    except lark.exceptions.VisitError as exc:  # pragma: no cover - lark wraps some callbacks
        inner = exc.orig_exc
        if isinstance(inner, MitlError):
            raise inner.located(path, text) from None
        raise
    except MitlError as exc:
        raise exc.located(path, text) from None


def _line_ends(text: str) -> str:
    """``text`` with each lone carriage return (old Mac line ends) made a line feed: the lexer ends a line
    (and a comment) at ``\n`` only, so a spec of CR-only lines would read as one line. ``\r\n`` is left as
    it is: it parses the same (``\r`` is white space), and the text's hash, which a training or a sweep
    records, stays the same."""
    return _LONE_CR.sub("\n", text) if "\r" in text else text


_LONE_CR = re.compile(r"\r(?!\n)")


def parse_formula(text: str) -> A.Formula:
    """Parse one formula (no spec statements)."""
    text = _line_ends(text)
    f = _run("formula", text, None)
    try:
        check_depth(f)
        check_weights(f, text)
    except MitlError as exc:
        raise exc.located(None, text) from None
    return f


def parse_predicate(text: str) -> P.Pred:
    """Parse one predicate over state variables."""
    return as_pred(_run("pred", _line_ends(text), None))


def parse_spec(text: str, path: str | None = None) -> Spec:
    """Parse and check a whole spec; raise a located :class:`MitlError` if it is wrong.

    A lone carriage return ends a line as ``\n`` does (:func:`_line_ends`; ``source`` is the text so read)."""
    text = _line_ends(text)
    try:
        return _parse_spec(text, path)
    except MitlError as exc:
        raise exc.located(path, text) from None


def _parse_spec(text: str, path: str | None) -> Spec:
    statements = _run("start", text, path)
    warnings: list[str] = []
    props: dict[str, PropDef] = {}
    formula = check = None
    plant_name: str | None = None
    plant_params: dict[str, float] = {}
    init: dict[str, InitRange] = {}
    horizon: float | None = None
    options: dict[str, str] = {}
    setpoint: float | None = None
    requirements: dict[str, Requirement] = {}
    seen: dict[str, Token] = {}

    def once(key: str, tok: Token) -> None:
        if key in seen:
            first = seen[key]
            raise SpecError(f"'{key}' given twice (first at line {first.line})", line=tok.line, column=tok.column)
        seen[key] = tok

    # Plant first: the state variables it declares are needed to check predicates.
    env_plant = None
    state_lines = [st for st in statements if st[0] == "state"]
    for st in statements:
        if st[0] == "plant" and str(st[1]).startswith(GYM_PREFIX):
            _, tok, params = st
            once("plant", tok)
            plant_name = str(tok)
            env_plant, plant_params = gym_env_plant(tok, params, state_lines)
        elif st[0] == "plant":
            _, tok, params = st
            once("plant", tok)
            name = str(tok)
            if name not in PLANTS:
                from mitlc.plants.user import discover

                discover()  # installed packages' mitlc.plants entry points
            if name not in PLANTS:
                raise SpecError(
                    f"unknown plant '{name}' (known: {', '.join(sorted(PLANTS))})",
                    line=tok.line,
                    column=tok.column,
                    hint="a plant of your own: --plant-file FILE.py (or module:attribute), or an installed "
                    "package's 'mitlc.plants' entry point; mitlc plants lists the known ones (mitlc docs plants)",
                )
            plant_name = name
            for ptok, value in params:
                pname = str(ptok)
                if pname in plant_params:
                    raise SpecError(f"parameter '{pname}' given twice", line=ptok.line, column=ptok.column)
                if pname not in PLANTS[name].defaults:
                    raise SpecError(
                        f"plant '{name}' has no parameter '{pname}' "
                        f"(known: {', '.join(sorted(PLANTS[name].defaults))})",
                        line=ptok.line,
                        column=ptok.column,
                    )
                v = constant(value, f"parameter '{pname}'", ptok)
                if not (math.isfinite(v) and v > 0):
                    raise SpecError(
                        f"parameter '{pname}' must be positive and finite, got {A.fmt_number(v)}",
                        line=ptok.line,
                        column=ptok.column,
                    )
                plant_params[pname] = v
    if state_lines and env_plant is None:
        tok = state_lines[0][1][0][0]
        raise SpecError(
            "a 'state' line maps a Gymnasium environment's observation (plant gym:ID); "
            + (f"plant '{plant_name}' declares its own state variables" if plant_name else "the spec names no plant"),
            line=tok.line,
            column=tok.column,
        )
    plant = env_plant if env_plant is not None else PLANTS.get(plant_name) if plant_name else None
    state_names = set(plant.state_names) if plant else None

    def check_vars(pred: P.Pred) -> None:
        for v in P.variables(pred):
            pos = v.pos or A.Pos(1, 1)
            if v.name.startswith("obs["):
                raise SpecError(
                    f"'{v.name}' reads the observation only in a 'state' line; name it there "
                    "(state NAME = obs[i]) and use the name",
                    line=pos.line,
                    column=pos.column,
                )
            if v.name in props and (state_names is None or v.name not in state_names):
                raise SpecError(
                    f"'{v.name}' is a proposition, not a number: a comparison compares state variables",
                    line=pos.line,
                    column=pos.column,
                    hint=f"to use {v.name} in a formula write it on its own (G {v.name}); a predicate is "
                    "written as a comparison, e.g. abs(q) < 0.3",
                )
            if state_names is not None and v.name not in state_names:
                raise SpecError(
                    f"unknown state variable '{v.name}' (plant '{plant_name}' has: {', '.join(plant.state_names)})",  # type: ignore[union-attr]
                    line=pos.line,
                    column=pos.column,
                    hint=(f"map it to the observation: state {v.name} = obs[i]" if env_plant is not None else None),
                )

    for st in statements:
        kind = st[0]
        if kind == "prop":
            _, tok, pred = st
            name = str(tok)
            if name in RESERVED:
                raise SpecError(
                    f"'{name}' is a reserved word and cannot name a proposition",
                    line=tok.line,
                    column=tok.column,
                )
            if name in props:
                first = props[name].pos
                raise SpecError(
                    f"proposition '{name}' defined twice (first at line {first.line if first else '?'})",
                    line=tok.line,
                    column=tok.column,
                )
            if not P.is_boolean(pred):
                raise SpecError(
                    f"proposition '{name}' must be a condition such as 'abs(q) < 0.3', not a number",
                    line=tok.line,
                    column=tok.column,
                )
            problem = too_deep(pred, f"predicate of '{name}':")
            if problem is not None:
                raise SpecError(
                    problem,
                    line=tok.line,
                    column=tok.column,
                )
            check_vars(pred)
            props[name] = PropDef(name, pred, pos=token_pos(tok))
        elif kind in ("formula", "check"):
            f = st[1]
            check_depth(f)
            if kind == "formula":
                if formula is not None:
                    pos = getattr(f, "pos", None) or A.Pos(1, 1)
                    raise SpecError("more than one 'formula'", line=pos.line, column=pos.column)
                formula = f
            else:
                if check is not None:
                    pos = getattr(f, "pos", None) or A.Pos(1, 1)
                    raise SpecError("more than one 'check'", line=pos.line, column=pos.column)
                check = f
        elif kind == "init":
            for tok, lo_p, hi_p in st[1]:
                var = str(tok)
                if state_names is not None and var not in state_names:
                    raise SpecError(
                        f"unknown state variable '{var}' in init (plant '{plant_name}' has: "
                        f"{', '.join(sorted(state_names))})",
                        line=tok.line,
                        column=tok.column,
                    )
                if var in init:
                    raise SpecError(f"initial range of '{var}' given twice", line=tok.line, column=tok.column)
                lo = constant(lo_p, f"initial bound of '{var}'", tok)
                hi = constant(hi_p, f"initial bound of '{var}'", tok)
                if not (math.isfinite(lo) and math.isfinite(hi) and math.isfinite(hi - lo)):
                    raise SpecError(
                        f"initial range of '{var}' must be finite (and its width too), got "
                        f"[{A.fmt_number(lo)}, {A.fmt_number(hi)}]",
                        line=tok.line,
                        column=tok.column,
                    )
                if lo > hi:
                    raise SpecError(
                        f"inverted initial range of '{var}': [{A.fmt_number(lo)}, {A.fmt_number(hi)}]",
                        line=tok.line,
                        column=tok.column,
                    )
                init[var] = InitRange(var, lo, hi)
        elif kind == "horizon":
            _, value, tok = st
            h = constant(value, "horizon", tok)
            if not (math.isfinite(h) and h > 0):
                raise SpecError(
                    f"horizon must be positive and finite, got {A.fmt_number(h)}", line=tok.line, column=tok.column
                )
            if h > MAX_TIME:
                raise SpecError(
                    f"horizon {A.fmt_number(h)} s is longer than the longest supported, {A.fmt_number(MAX_TIME)} s",
                    line=tok.line,
                    column=tok.column,
                )
            once("horizon", tok)
            horizon = h
        elif kind == "setpoint":
            _, value, tok = st
            once("setpoint", tok)
            setpoint = constant(value, "setpoint", tok)
            if not math.isfinite(setpoint):
                raise SpecError("setpoint must be finite", line=tok.line, column=tok.column)
        elif kind == "require":
            _, tok, lo_p, hi_p, band_p = st
            name = str(tok)
            if name not in CRITERIA:
                raise SpecError(
                    f"unknown criterion '{name}' (known: {', '.join(CRITERIA)})", line=tok.line, column=tok.column
                )
            if name in requirements:
                raise SpecError(f"criterion '{name}' required twice", line=tok.line, column=tok.column)
            hi = constant(hi_p, f"bound of {name}", tok)
            lo = 0.0 if lo_p is None else constant(lo_p, f"bound of {name}", tok)
            if not (math.isfinite(lo) and math.isfinite(hi)) or lo < 0 or lo > hi:
                raise SpecError(
                    f"bounds of {name} must be finite with 0 <= lower <= upper, got "
                    f"[{A.fmt_number(lo)}, {A.fmt_number(hi)}]",
                    line=tok.line,
                    column=tok.column,
                )
            band = None
            if band_p is not None:
                if name != "settling_time":
                    raise SpecError(f"only settling_time takes a band, not {name}", line=tok.line, column=tok.column)
                band = constant(band_p, "band", tok)
                if not 0 < band < 1:
                    raise SpecError(
                        f"band must be a fraction in (0, 1), got {A.fmt_number(band)}", line=tok.line, column=tok.column
                    )
            requirements[name] = Requirement(name, lo, hi, band, pos=token_pos(tok))
        elif kind == "option":
            _, tok, value = st
            key = str(tok)
            if key not in OPTIONS:
                raise SpecError(
                    f"unknown option '{key}' (known: {', '.join(sorted(OPTIONS))})",
                    line=tok.line,
                    column=tok.column,
                )
            val = str(value) if isinstance(value, Token) else str(value)
            if val not in OPTIONS[key]:
                raise SpecError(
                    f"option '{key}' must be one of {', '.join(OPTIONS[key])}, got '{val}'",
                    line=tok.line,
                    column=tok.column,
                )
            once(f"option {key}", tok)
            options[key] = val

    if formula is None and not requirements:
        lines = text_lines(text)
        raise SpecError("the spec has no 'formula' (nor any 'require')", line=len(lines), column=1)

    for f in (formula, check):
        if f is None:
            continue
        check_weights(f, text)
        _add_inline_props(f, props, lambda pred, _: check_vars(pred), "a prop line", "rename that proposition")
        for node in A.walk(f):
            if isinstance(node, A.Atom) and node.name not in props:
                pos = node.pos or A.Pos(1, 1)
                hint = f"defined: {', '.join(props)}" if props else "define it with 'prop NAME = condition'"
                raise SpecError(f"undefined proposition '{node.name}'", line=pos.line, column=pos.column, hint=hint)
    used = set(A.atoms(formula)) if formula is not None else set()
    used |= set(A.atoms(check)) if check is not None else set()
    for name, p in props.items():
        if name not in used:
            pos = p.pos or A.Pos(1, 1)
            warnings.append(f"{path or '<spec>'}:{pos.line}:{pos.column}: warning: proposition '{name}' is never used")

    return Spec(
        formula=formula,
        props=tuple(props.values()),
        check=check,
        plant_name=plant_name,
        plant_params=tuple(plant_params.items()),
        init=tuple(init.values()),
        horizon=horizon,
        options=tuple(options.items()),
        setpoint=0.0 if setpoint is None else setpoint,
        requirements=tuple(requirements.values()),
        path=path,
        source=text,
        warnings=tuple(warnings),
        env_plant=env_plant,
    )


def _add_inline_props(
    f: A.Formula,
    props: dict[str, PropDef],
    check_vars: Callable[[P.Pred, A.Pos], None],
    defined_by: str,
    instead: str,
) -> None:
    """Add the inline predicates of ``f`` to ``props``, as propositions named after their text (a spec's
    formulas, and :func:`with_inline_props`'s). A name that ``props`` holds for another predicate (which
    ``defined_by`` defines; ``instead`` says what to do), a predicate nested too deep, or a variable
    that ``check_vars`` (given the predicate and where it stands) refuses is a :class:`SpecError`."""
    for node in A.walk(f):
        if not (isinstance(node, A.Atom) and isinstance(node.pred, P.Pred)):
            continue
        pos = node.pos or A.Pos(1, 1)
        known = props.get(node.name)
        if known is not None:
            if str(known.pred) != str(node.pred):
                raise SpecError(
                    f"the inline predicate '{node.pred}' is named '{node.name}', which {defined_by} defines "
                    f"as '{known.pred}': {instead}",
                    line=pos.line,
                    column=pos.column,
                )
            continue
        problem = too_deep(node.pred, "inline predicate:")
        if problem is not None:
            raise SpecError(problem, line=pos.line, column=pos.column)
        check_vars(node.pred, pos)
        props[node.name] = PropDef(node.name, node.pred, pos=pos, inline=True)


def load_spec(path: str | Path) -> Spec:
    """Read and check a ``.mitl`` file, or a shipped spec by name (``pendulum/p2_avoid``).

    A file of that name wins; without one, the shipped specs
    (:mod:`mitlc.spec.library`, ``mitlc specs`` lists them) are looked up.
    """
    from mitlc.spec import library

    p = Path(path)
    if not p.exists() and (shipped := library.find(str(path))) is not None:
        return parse_spec(shipped.read_text(), shipped.origin)
    try:
        if p.exists() and not p.is_file():  # a directory, a device (/dev/zero), a FIFO: not a spec
            kind = "a directory" if p.is_dir() else "not a regular file"
            raise SpecError(f"cannot read spec: {kind}", file=str(path))
        with p.open("rb") as fh:
            raw = fh.read(MAX_SPEC_BYTES + 1)
    except OSError as exc:
        hint = None
        if not p.exists():
            hint = "no file of that name, and no shipped spec either (mitlc specs lists them, e.g. pendulum/p2_avoid)"
        raise SpecError(f"cannot read spec: {exc.strerror or exc}", file=str(path), hint=hint) from None
    if len(raw) > MAX_SPEC_BYTES:
        raise SpecError(f"spec is larger than {MAX_SPEC_BYTES >> 10} KiB, the most a spec may be", file=str(path))
    try:
        text = raw.decode("utf-8-sig")  # a byte-order mark at the start is allowed
    except UnicodeDecodeError as exc:
        raise SpecError(f"spec is not UTF-8 text (byte {exc.start})", file=str(path)) from None
    return parse_spec(text, str(path))


def with_inline_props(spec: Spec, f: A.Formula) -> Spec:
    """``spec`` with the inline predicates of ``f``, a formula given apart from the spec (``mitlc check
    --formula 'abs(q) < 0.3 U[0,1] (qdot > 1)'``), added as propositions, named and checked as a
    spec's own are: a name that a prop line defines otherwise, a predicate nested too deep, an
    unknown state variable or a proposition used as a number is a :class:`SpecError` at the predicate.

    >>> spec = parse_spec("plant pendulum\\nprop up = abs(q) < 0.3\\nformula F up")
    >>> [p.name for p in with_inline_props(spec, parse_formula("up U[0,1] (qdot > 1)")).props]
    ['up', 'qdot_gt_1']
    """
    import dataclasses  # here, not at the top: this function is an addition kept apart

    props = {p.name: p for p in spec.props}
    plant = spec.plant
    state = set(plant.state_names) if plant is not None else None

    def check_vars(pred: P.Pred, pos: A.Pos) -> None:
        for v in P.variables(pred):
            where = v.pos or pos
            if v.name in props and (state is None or v.name not in state):
                raise SpecError(
                    f"'{v.name}' is a proposition, not a number: a comparison compares state variables",
                    line=where.line,
                    column=where.column,
                )
            if plant is not None and state is not None and v.name not in state:
                raise SpecError(
                    f"unknown state variable '{v.name}' (plant '{plant.name}' has: {', '.join(plant.state_names)})",
                    line=where.line,
                    column=where.column,
                )

    _add_inline_props(f, props, check_vars, "the spec", "write that proposition's name, or another predicate")
    if len(props) == len(spec.props):
        return spec
    return dataclasses.replace(spec, props=tuple(props.values()))
