"""Graded propositions (``reward = graded`` or ``shaped``): how near a state is to making a proposition hold.

The flat reward of an atomic proposition ``a`` is ``p_a - p_not_a``: +1 where it holds, -1 where
not, with no sense of how near the boundary the state is. With ``option reward = graded`` the
compiler puts the proposition's *grade* there instead, with ``shaped`` the mean of the flat value
and the grade (:class:`mitlc.petri.reward.Graded`):

* each comparison ``e1 < e2`` (and ``<=``, ``>``, ``>=``, ``==``, ``!=``) has the margin the
  monitor uses for its robustness (``e2 - e1``, ``-|e1 - e2|`` for ``==``, ...), divided by the
  comparison's *scale*: the largest margin in absolute value over the state box (the plant's
  state bounds, on a grid of at most 4096 points over the variables it reads), so that a grade
  of -1 is about as far from the boundary as the box allows;
* ``and``, ``or`` and ``not`` combine the scaled margins as the monitor combines robustness
  (min, max, minus), and the result is clipped to ``[-1, 1]``.

Dividing each margin by a positive number keeps its sign, and min, max and minus keep signs, so a
grade is >= 0 where the proposition holds and <= 0 where it does not (a margin that is nan, as
the monitor reads it, is 0): the graded reward has the sign of the flat one on every step, and
its size is at most the flat one's. Without plant bounds for a variable the scale is 1 (raw
margins, clipped).

>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec("plant pendulum\\nprop kappa = abs(q) < 0.3\\nformula F G kappa")
>>> g = Grader.of(spec, ("kappa",))
>>> g.scales
((2.8415926535897933,),)
>>> g.grades({"q": np.array([0.0, 0.3, 3.0])}).round(4).tolist()
[[0.1056], [0.0], [-0.9502]]
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mitlc.errors import CompileError
from mitlc.spec import predicates as P
from mitlc.spec.model import Spec

__all__ = ["Grader", "GRID_POINTS", "margin"]

GRID_POINTS = 4096
"""Most points of the state box a comparison's scale is measured on."""


def margin(op: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The robustness of ``a op b`` (>= 0 where it holds), as the monitor defines it."""
    if op in ("<", "<="):
        return b - a
    if op in (">", ">="):
        return a - b
    if op == "==":
        return -np.abs(a - b)
    if op == "!=":
        return np.abs(a - b)
    raise CompileError(f"unknown comparison '{op}'")  # pragma: no cover - the grammar only has these


def _links(p: P.Pred) -> list[tuple[P.Pred, P.Pred, str]]:
    """The comparisons of a boolean predicate, in the order :func:`_combine` reads them."""
    if isinstance(p, P.Compare):
        return [(a, b, op) for a, b, op in zip(p.operands, p.operands[1:], p.ops, strict=False)]
    if isinstance(p, (P.PAnd, P.POr)):
        return _links(p.left) + _links(p.right)
    if isinstance(p, P.PNot):
        return _links(p.arg)
    raise CompileError(f"'{p}' is a number, not a condition")


def _combine(p: P.Pred, scaled: Sequence[np.ndarray], at: list[int]) -> np.ndarray:
    if isinstance(p, P.Compare):
        n = len(p.ops)
        out = scaled[at[0]]
        for i in range(1, n):
            out = np.minimum(out, scaled[at[0] + i])
        at[0] += n
        return out
    if isinstance(p, (P.PAnd, P.POr)):
        left = _combine(p.left, scaled, at)
        right = _combine(p.right, scaled, at)
        return np.minimum(left, right) if isinstance(p, P.PAnd) else np.maximum(left, right)
    assert isinstance(p, P.PNot)
    return -_combine(p.arg, scaled, at)


def _column(name: str) -> Callable[[Any], np.ndarray]:
    return lambda env: np.asarray(env[name], dtype=float)


def _box_grid(names: Sequence[str], bounds: Mapping[str, tuple[float, float]]) -> dict[str, np.ndarray] | None:
    """A regular grid over the box of ``names`` (at most :data:`GRID_POINTS` points); None if unbounded."""
    if not names:
        return {}
    if any(n not in bounds for n in names):
        return None
    per_axis = max(2, int(GRID_POINTS ** (1.0 / len(names))))
    axes = [np.linspace(*bounds[n], per_axis) for n in names]
    mesh = np.meshgrid(*axes, indexing="ij")
    return {n: m.reshape(-1) for n, m in zip(names, mesh, strict=True)}


@dataclass(frozen=True)
class Grader:
    """The grades of a spec's propositions (module text): :meth:`grades` of states, ``(R, atoms)``."""

    atoms: tuple[str, ...]
    preds: tuple[P.Pred, ...]
    scales: tuple[tuple[float, ...], ...]
    """Per proposition, the scale of each comparison (in :func:`_links` order)."""
    _reads: tuple[tuple[tuple[Callable[[Any], Any], Callable[[Any], Any], str], ...], ...] = field(
        default=(), compare=False, repr=False
    )

    @staticmethod
    def of(spec: Spec, atoms: Sequence[str]) -> Grader:
        """The grader of ``atoms`` (the reward system's order), scaled by the spec's plant bounds."""
        # a StateVar's bounds are finite with lo < hi (checked when it is built)
        bounds = {v.name: (float(v.lo), float(v.hi)) for v in spec.plant.state} if spec.plant is not None else {}
        preds, scales = [], []
        for a in atoms:
            pred = spec.prop(a).pred
            preds.append(pred)
            row = []
            for left, right, op in _links(pred):
                names = sorted({v.name for side in (left, right) for v in P.variables(side)})
                grid = _box_grid(names, bounds)
                s = 1.0
                if grid is not None:
                    with np.errstate(all="ignore"):
                        m = margin(op, _value(left, grid), _value(right, grid))
                    m = np.abs(m[np.isfinite(m)]) if np.ndim(m) else np.abs(np.array([m], dtype=float))
                    m = m[np.isfinite(m)]
                    if m.size and float(m.max()) > 0.0:
                        s = float(m.max())
                row.append(s)
            scales.append(tuple(row))
        reads = tuple(
            tuple((P.compile_numpy(a, _column), P.compile_numpy(b, _column), op) for a, b, op in _links(p))
            for p in preds
        )
        return Grader(tuple(atoms), tuple(preds), tuple(scales), reads)

    def grades(self, env: Mapping[str, np.ndarray]) -> np.ndarray:
        """Grades ``(R, atoms)`` in ``[-1, 1]`` of the states ``env`` (state variable -> ``(R,)``)."""
        n = len(next(iter(env.values()))) if env else 1
        out = np.empty((n, len(self.atoms)))
        with np.errstate(all="ignore"):
            for j, (pred, scales, reads) in enumerate(zip(self.preds, self.scales, self._reads, strict=True)):
                scaled = []
                for (left, right, op), s in zip(reads, scales, strict=True):
                    m = margin(op, np.asarray(left(env), dtype=float), np.asarray(right(env), dtype=float))
                    scaled.append(np.where(np.isnan(m), 0.0, m) / s)
                out[:, j] = np.clip(np.broadcast_to(_combine(pred, scaled, [0]), (n,)), -1.0, 1.0)
        return out


def _value(e: P.Pred, env: Mapping[str, np.ndarray]) -> np.ndarray:
    return np.asarray(P.compile_numpy(e, _column)(env), dtype=float)
