"""Propositions as code: the atom code of a batch of states, or of one state.

A net's guards see the plant's state only through its propositions' truth, packed into one
integer per run, the *atom code* (bit ``i`` = proposition ``i``). This module makes that
function three ways from the predicates' syntax trees (data, never text):

* :func:`compile_predicate` and :func:`pack_atoms`: numpy closures over a batch ``(R, n)``
  (what :meth:`~mitlc.runtime.NetRuntime.atom_code` runs);
* :func:`atom_source` and :func:`compile_atoms`: Python source over one state ``x (n,)``,
  compiled by a ``jit`` the caller chooses (SACPN's fused kernel, :mod:`mitlc.learn.sacpn.kernel`);
* :func:`scalar_atoms`: the same source over Python floats, for one sample at a time (the
  Gymnasium wrapper, through :meth:`~mitlc.runtime.NetRuntime.sample_stepper`).

All three give the same truths: each node is the same numpy function, constants folded the
same way (``tests/test_kernel.py``, ``tests/test_runtime.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from mitlc.spec import predicates as P

__all__ = [
    "atom_source",
    "compile_atoms",
    "compile_observe",
    "compile_predicate",
    "observe_source",
    "pack_atoms",
    "scalar_atoms",
]


def compile_predicate(p: P.Pred, columns: Mapping[str, int]) -> Callable[[np.ndarray], np.ndarray | float]:
    """A predicate as one closure over a state batch ``x`` ``(R, n)`` (columns by variable name)."""

    def column(name: str) -> Callable[[Any], np.ndarray]:
        i = columns[name]
        return lambda x: x[:, i]

    return P.compile_numpy(p, column)


def pack_atoms(preds: Sequence[Callable[[np.ndarray], np.ndarray | float]], x: np.ndarray) -> np.ndarray:
    """The truths of ``preds`` (closures of :func:`compile_predicate`, at least one) on ``x`` ``(R, n)``
    packed into one integer per run, bit ``i`` = predicate ``i``."""
    code = np.asarray(preds[0](x), dtype=bool)
    if len(preds) <= 7:  # bools viewed as 0/1 bytes: no conversion pass
        code = code.view(np.int8)
        for i, pred in enumerate(preds[1:], 1):
            code = code + (np.asarray(pred(x), dtype=bool).view(np.int8) << i)
        return code
    code = code.astype(np.int64)
    for i, pred in enumerate(preds[1:], 1):
        code += np.asarray(pred(x), dtype=np.int64) << i
    return code


_FUNCS = {
    "abs": "np.abs",
    "sqrt": "np.sqrt",
    "sin": "np.sin",
    "cos": "np.cos",
    "tan": "np.tan",
    "exp": "np.exp",
    "min": "np.minimum",
    "max": "np.maximum",
    "atan2": "np.arctan2",
}
_OPS = {"+": "np.add", "-": "np.subtract", "*": "np.multiply", "/": "np.divide"}


def _literal(v: float) -> str:
    if math.isnan(v):
        return "np.nan"
    if math.isinf(v):
        return "np.inf" if v > 0 else "(-np.inf)"
    return repr(float(v))


def _expr(p: P.Pred, columns: dict[str, int], scalar: bool = False) -> str:
    """Python source of one predicate node over one state ``x (n,)``, built from the tree
    (numbers written by ``repr``, variables as ``x[i]``): what :func:`~mitlc.spec.predicates.compile_numpy`
    computes, constant subtrees folded the same way, each node the same numpy function. ``scalar``:
    over Python floats, with Python's operators where they are numpy's to the bit (:func:`scalar_atoms`)."""

    def sub(q: P.Pred) -> str:
        return _expr(q, columns, scalar)

    value = p.value if isinstance(p, P.Num) else P.const_value(p)
    if value is not None:
        return _literal(value)
    if isinstance(p, P.Var):
        return f"x[{int(columns[p.name])}]"
    if isinstance(p, P.Neg):
        return f"(-{sub(p.arg)})" if scalar else f"np.negative({sub(p.arg)})"
    if isinstance(p, P.BinOp):
        if scalar:
            return _SCALAR_OPS[p.op].format(sub(p.left), sub(p.right))
        return f"{_OPS[p.op]}({sub(p.left)}, {sub(p.right)})"
    if isinstance(p, P.Call):
        args = ", ".join(sub(a) for a in p.args)
        if not scalar:
            return f"{_FUNCS[p.fn]}({args})"
        if p.fn in _SCALAR_FUNCS:
            return f"{_SCALAR_FUNCS[p.fn]}({args})"
        return f"float({_FUNCS[p.fn]}({args}))"
    if isinstance(p, P.Compare):
        vals = [sub(o) for o in p.operands]
        links = [f"({a} {op} {b})" for op, a, b in zip(p.ops, vals, vals[1:], strict=False)]
        return "(" + " and ".join(links) + ")"
    if isinstance(p, P.PAnd):
        return f"({sub(p.left)} and {sub(p.right)})"
    if isinstance(p, P.POr):
        return f"({sub(p.left)} or {sub(p.right)})"
    if isinstance(p, P.PNot):
        return f"(not {sub(p.arg)})"
    raise TypeError(f"not a predicate node: {p!r}")


def atom_source(preds: Sequence[P.Pred], columns: dict[str, int], scalar: bool = False) -> str:
    """Source of ``atoms(x)``: the atom code of one state (bit ``i`` = predicate ``i``),
    as :meth:`~mitlc.runtime.NetRuntime.atom_code` packs it (``scalar``: over Python
    floats, for :func:`scalar_atoms`).

    >>> kappa = P.Compare((P.Call("abs", (P.Var("q"),)), P.Num(0.3)), ("<",))
    >>> print(atom_source([kappa], {"q": 0, "qdot": 1}))
    def atoms(x):
        c = 0
        if ((np.abs(x[0]) < 0.3)):
            c += 1
        return c
    """
    lines = ["def atoms(x):", "    c = 0"]
    for i, p in enumerate(preds):
        lines += [f"    if {_expr(p, columns, scalar)}:", f"        c += {1 << i}"]
    lines.append("    return c")
    return "\n".join(lines)


# Python's own float operations where they are numpy's to the bit (IEEE + - * /, abs, sqrt,
# comparisons); numpy's functions (on Python floats, the same inner loops as on arrays) for the rest
_SCALAR_OPS = {"+": "({} + {})", "-": "({} - {})", "*": "({} * {})", "/": "_div({}, {})"}
_SCALAR_FUNCS = {"abs": "abs", "sqrt": "_sqrt"}


def _div(a: float, b: float) -> float:
    if b:
        return a / b
    with np.errstate(divide="ignore", invalid="ignore"):  # x / 0: inf or nan, as numpy gives
        return float(np.divide(a, b))


def _sqrt(a: float) -> float:
    return math.sqrt(a) if a >= 0.0 else math.nan  # nan (not ValueError) below 0, as numpy gives


def scalar_atoms(preds: Sequence[P.Pred], columns: dict[str, int]) -> Callable[[Sequence[float]], int]:
    """``atoms(x)`` of :func:`atom_source` for one state given as Python floats, in plain Python:
    the atom code of one sample at a fraction of the cost of numpy calls on ``(1, n)`` arrays (the
    Gymnasium wrapper's step). The same truths as :meth:`~mitlc.runtime.NetRuntime.atom_code`:
    ``+ - * /``, ``abs``, ``sqrt`` and comparisons are IEEE operations that Python and numpy do
    alike; every other function is numpy's, called on the floats.

    >>> kappa = P.Compare((P.Call("abs", (P.Var("q"),)), P.Num(0.3)), ("<",))
    >>> scalar_atoms([kappa], {"q": 0, "qdot": 1})([0.1, 5.0])
    1
    """
    namespace: dict[str, Any] = {"np": np, "math": math, "_div": _div, "_sqrt": _sqrt}
    source = atom_source(preds, columns, scalar=True)
    exec(compile(source, "<mitlc scalar atoms>", "exec"), namespace)  # generated from the tree
    return namespace["atoms"]


def compile_atoms(preds: Sequence[P.Pred], columns: dict[str, int], jit_fn: Callable) -> Callable:
    """The atom-code function of :func:`atom_source`, defined (and compiled by ``jit_fn``)."""
    namespace: dict[str, Any] = {"np": np}
    source = atom_source(preds, columns)
    exec(compile(source, "<mitlc atoms>", "exec"), namespace)  # generated from the tree
    atoms = namespace["atoms"]
    atoms.__mitlc_source__ = source  # for mitlc.learn.jitcache, which writes kernels to files
    return jit_fn(atoms)


def observe_source(exprs: Sequence[P.Pred], columns: dict[str, int], periodic: Sequence[bool]) -> str:
    """Source of ``observe(x, out)``: state variable ``i`` of one copy of an environment, ``out[i]``,
    read off its flattened observation ``x`` by the mapping ``exprs[i]`` (variables ``obs[j]``, by
    ``columns``), an angle wrapped to ``[-pi, pi)`` where ``periodic[i]``: each node the numpy function
    :func:`~mitlc.spec.predicates.compile_numpy` applies, the wrap :func:`~mitlc.plants.base.wrap_angle`'s.

    >>> half = P.BinOp("/", P.Var("obs[2]"), P.Num(2.0))
    >>> print(observe_source([P.Var("obs[0]"), half], {"obs[0]": 0, "obs[2]": 2}, [True, False]))
    def observe(x, out):
        out[0] = np.subtract(np.remainder(np.add(x[0], 3.141592653589793), 6.283185307179586), 3.141592653589793)
        out[1] = np.divide(x[2], 2.0)
    """
    pi, two_pi = _literal(math.pi), _literal(2 * math.pi)
    lines = ["def observe(x, out):"]
    for i, (e, wrap) in enumerate(zip(exprs, periodic, strict=True)):
        v = _expr(e, columns)
        if wrap:
            v = f"np.subtract(np.remainder(np.add({v}, {pi}), {two_pi}), {pi})"
        lines.append(f"    out[{i}] = {v}")
    return "\n".join(lines)


def compile_observe(
    exprs: Sequence[P.Pred], columns: dict[str, int], periodic: Sequence[bool], jit_fn: Callable
) -> Callable:
    """The read of :func:`observe_source`, defined (and compiled by ``jit_fn``)."""
    namespace: dict[str, Any] = {"np": np}
    source = observe_source(exprs, columns, periodic)
    exec(compile(source, "<mitlc observe>", "exec"), namespace)  # generated from the tree
    observe = namespace["observe"]
    observe.__mitlc_source__ = source
    return jit_fn(observe)
