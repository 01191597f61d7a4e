"""Normalised Gaussian RBF features on a grid: the features of both learners.

SACPN (Table 4-4: 10 x 10 centres over the pendulum's angle and velocity) and HyRL
(Table 3-2: 10 x 10 x 5 over position, velocity and the initial position, plus the
mode clocks) use the same features: a grid of Gaussians, normalised to sum to one.
A normalised grid factorises into one normalised kernel vector per variable, so
``phi`` is their outer product (run by run, over a leading run axis).

Per axis ``i`` with centres ``c_ij`` spaced ``s_i`` apart and width ``w`` (a multiple
of the spacing):

* ordinary variables: ``g_ij = exp(-(z_i - c_ij)^2 / (2 (w s_i)^2))``, ``z_i`` clipped to
  the axis bounds (for the features only);
* angles (``periodic``): the distance is the chord ``|e^{i z} - e^{i c}|``, so
  ``g_ij = exp((cos(z_i - c_ij) - 1) / (w s_i)^2)``, centres evenly round the circle;
* warped axes (``warp = (origin, power)``): centres even in the coordinate
  ``o + sign(z - o) D (|z - o| / D) ** power`` (``D`` the larger distance from ``o`` to
  a bound), so that with ``power < 1`` they crowd towards ``o`` and narrow with it.

Every exponent is at most 0 and the nearest centre's is at least ``-1 / (8 w^2)``, so
no grid, however fine, overflows or divides by zero (a grid of 40 x 40 or more at
width 0.5 used to, in SACPN's former closed form).

>>> from mitlc.plants import PLANTS
>>> f = RbfFeatures.for_state(PLANTS["pendulum"].state, (10, 10), bounds={"qdot": (-20.0, 20.0)})
>>> phi = f(np.array([[0.0, 0.0], [np.pi, 3.0]]))
>>> phi.shape, bool(np.allclose(phi.sum(axis=1), 1.0))
((2, 100), True)
>>> g = RbfFeatures([Axis("q", -1.0, 1.0, 10, warp=(0.0, 0.5)), Axis("qdot", -5.0, 5.0, 10)])
>>> [round(float(c), 3) for c in g.centres_in(0)[5:]]
[0.012, 0.111, 0.309, 0.605, 1.0]

SACPN's default grid follows from the plant's number of state variables
(:func:`default_rbf`): Table 4-4's 10 x 10 for two, and for more about as many
features in all (100), so that a grid over a plant of many variables stays small.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from mitlc.errors import TrainingError
from mitlc.plants import StateVar

if TYPE_CHECKING:
    from mitlc.spec.model import Spec

__all__ = [
    "Axis",
    "RbfFeatures",
    "default_rbf",
    "spec_grid",
    "spec_thresholds",
    "GRID_MARGIN",
    "RBF_PER_VARIABLE",
    "RBF_BUDGET",
]

RBF_PER_VARIABLE = 10
"""Centres per variable for one or two state variables (Table 4-4: 10 x 10)."""

RBF_BUDGET = RBF_PER_VARIABLE**2
"""Features in all that :func:`default_rbf` keeps to for three to six state variables."""


def default_rbf(n: int) -> tuple[int, ...]:
    """SACPN's default RBF grid for a plant of ``n`` state variables.

    One or two variables: :data:`RBF_PER_VARIABLE` centres each (the pendulum's and
    the mass-damper's 10 x 10 of Table 4-4). Three or more: ``c`` centres each, ``c``
    the largest count with ``c ** n <= RBF_BUDGET`` (at least 2), then one more centre
    on the first variables in state order while the product stays within the budget.
    So up to six variables the grid has at most 100 features; from seven on it is 2
    per variable (``2 ** n``: 128 for seven).

    >>> [default_rbf(n) for n in (1, 2, 3, 4)]
    [(10,), (10, 10), (5, 5, 4), (3, 3, 3, 3)]
    >>> [default_rbf(n) for n in (5, 6, 7)]
    [(3, 3, 2, 2, 2), (3, 2, 2, 2, 2, 2), (2, 2, 2, 2, 2, 2, 2)]
    """
    if n <= 2:
        return (RBF_PER_VARIABLE,) * n
    c = 2
    while (c + 1) ** n <= RBF_BUDGET:
        c += 1
    counts = [c] * n
    for i in range(n):
        if int(np.prod(counts)) // c * (c + 1) > RBF_BUDGET:
            break
        counts[i] = c + 1
    return tuple(counts)


@dataclass(frozen=True)
class Axis:
    """One variable of the grid: its bounds, number of centres, and how they are laid out."""

    name: str
    lo: float
    hi: float
    count: int
    periodic: bool = False
    """An angle: centres evenly round ``[lo, hi)``, chord distance."""
    warp: tuple[float, float] | None = None
    """``(origin, power)``: centres even in the warped coordinate (ordinary variables only)."""


class RbfFeatures:
    """Normalised Gaussian RBFs on a grid of axes, evaluated for a batch of states.

    ``features(z)`` maps ``z (R, len(axes))`` to ``phi (R, F)``, ``F`` the product of the
    counts; each row sums to one. An axis with one centre (or empty bounds) contributes
    a constant factor 1.
    """

    def __init__(self, axes: Sequence[Axis], width: float = 1.0) -> None:
        self.axes = tuple(axes)
        self.names = tuple(a.name for a in self.axes)
        self.bounds = tuple((float(a.lo), float(a.hi)) for a in self.axes)
        self.counts = tuple(int(a.count) if a.hi > a.lo else 1 for a in self.axes)
        self.warps = tuple(
            None if a.periodic or a.warp is None or a.warp[1] == 1.0 else (float(a.warp[0]), float(a.warp[1]))
            for a in self.axes
        )
        self.periodic = tuple(bool(a.periodic) for a in self.axes)
        self.n_features = int(np.prod(self.counts))
        self.centres: list[np.ndarray] = []
        """Per axis, the centres in the coordinate they are even in."""
        self.inv_w2: list[float] = []
        """Per axis, ``1 / (2 (width * spacing)^2)``."""
        for i, (n, (lo, hi)) in enumerate(zip(self.counts, self.bounds, strict=True)):
            if self.periodic[i]:
                span = hi - lo
                c = lo + span * np.arange(n) / n
                spacing = span / n
            else:
                wlo, whi = self.warp(i, np.array([lo, hi]))
                c = np.linspace(wlo, whi, n) if n > 1 else np.array([0.5 * (wlo + whi)])
                spacing = (whi - wlo) / (n - 1) if n > 1 else 1.0
            self.centres.append(c)
            self.inv_w2.append(1.0 / (2.0 * (width * spacing) ** 2))
        self._bufs: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}

    @classmethod
    def for_state(
        cls,
        state: Sequence[StateVar],
        counts: Sequence[int],
        width: float = 1.0,
        bounds: Mapping[str, tuple[float, float]] | None = None,
    ) -> RbfFeatures:
        """A grid over a plant's state variables (angles periodic), each over the variable's
        ``grid`` or else its box, ``bounds`` overriding that for some (SACPN's ``feature_bounds``)."""
        if len(counts) != len(state):
            raise TrainingError(f"rbf has {len(counts)} entries, the plant has {len(state)} state variables")
        over = dict(bounds or {})
        axes = []
        for v, n in zip(state, counts, strict=True):
            lo, hi = over.get(v.name, v.grid or (v.lo, v.hi))
            axes.append(Axis(v.name, lo, hi, int(n), periodic=v.periodic))
        return cls(axes, width)

    def warp(self, i: int, z: np.ndarray, inverse: bool = False) -> np.ndarray:
        """Axis ``i``'s values in the coordinate its centres are even in (``inverse``:
        back from that coordinate to the variable's own units)."""
        w = self.warps[i]
        if w is None:
            return z
        o, power = w
        lo, hi = self.bounds[i]
        D = max(o - lo, hi - o)
        return o + np.sign(z - o) * D * (np.abs(z - o) / D) ** (1.0 / power if inverse else power)

    def centres_in(self, i: int) -> np.ndarray:
        """Axis ``i``'s centres in its variable's own units."""
        return self.warp(i, self.centres[i], inverse=True)

    def _buffers(self, R: int) -> list[tuple[np.ndarray, np.ndarray]]:
        bufs = self._bufs.get(R)
        if bufs is None:
            bufs = self._bufs[R] = [(np.empty((R, len(c))), np.empty((R, len(c)))) for c in self.centres]
        return bufs

    def __call__(self, z: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Features ``(R, F)`` of ``z (R, len(axes))`` (written into ``out`` when given)."""
        R = z.shape[0]
        kernels = []
        for i, (c, k, (g, d)) in enumerate(zip(self.centres, self.inv_w2, self._buffers(R), strict=True)):
            if len(c) == 1:
                continue
            if self.periodic[i]:  # exp(-k |e^iz - e^ic|^2) = exp(2k cos(z - c) - 2k)
                np.subtract(z[:, i, None], c, out=g)
                np.cos(g, out=g)
                np.multiply(g, 2.0 * k, out=g)
                np.subtract(g, 2.0 * k, out=g)
            else:  # exp(-k (z - c)^2), z clipped (and warped)
                lo, hi = self.bounds[i]
                zi = np.minimum(np.maximum(z[:, i], lo), hi)
                np.subtract(self.warp(i, zi)[:, None], c, out=d)
                np.multiply(d, -k, out=g)
                np.multiply(g, d, out=g)
            np.exp(g, out=g)
            g /= g.sum(axis=1, keepdims=True)
            kernels.append(g)
        if len(kernels) < 2:
            phi = kernels[0].copy() if kernels else np.ones((R, 1))
        else:
            phi = kernels[0]
            for g in kernels[1:-1]:
                phi = (phi[:, :, None] * g[:, None, :]).reshape(R, -1)
            g = kernels[-1]
            if out is not None and out.flags.c_contiguous:  # the last product straight into out
                np.multiply(phi[:, :, None], g[:, None, :], out=out.reshape(R, phi.shape[1], g.shape[1]))
                return out
            phi = (phi[:, :, None] * g[:, None, :]).reshape(R, -1)
        if out is not None:
            out[...] = phi
            return out
        return phi


GRID_MARGIN = 0.5
"""How far past the thresholds and the initial set a spec-derived grid reaches, as a fraction
of their span on each side (chosen on the task suite: docs/suite.md)."""


GRID_SAMPLES = 4001
"""Samples along a variable's box at which :func:`spec_grid` looks for a proposition's thresholds."""


def spec_grid(spec: Spec) -> dict[str, tuple[float, float]]:
    """Feature ranges that follow from a spec: per non-periodic state variable that some
    proposition of that variable alone bounds, the span of those thresholds and the ``init``
    range, widened by :data:`GRID_MARGIN` of it on each side and kept within the plant's grid
    (:attr:`~mitlc.plants.StateVar.grid` or box). A variable no proposition bounds keeps the
    plant's grid (it is left out). The thresholds are where the proposition's truth changes
    along the variable's box (sampled at :data:`GRID_SAMPLES` points: any one-variable
    predicate, read as data, never evaluated as code).

    A speed limit of 1 m/s on a plant whose velocity box is 5 m/s puts the velocity's centres
    over [-2, 2] instead of [-5, 5]: two and a half times finer where the spec decides.

    >>> from mitlc.spec.parse import parse_spec
    >>> spec = parse_spec('''plant mass-damper
    ... init q in [-1, -0.8], qdot = 0
    ... prop far = abs(q - 0.9) < 0.1
    ... prop fast = abs(qdot) > 1
    ... formula F[0,3] G far & G !fast''')
    >>> {k: (round(a, 2), round(b, 2)) for k, (a, b) in spec_grid(spec).items()}
    {'q': (-1.0, 1.0), 'qdot': (-2.0, 2.0)}
    """
    from mitlc.spec.predicates import evaluate, variables

    plant = spec.plant
    if plant is None:
        return {}
    state = {v.name: v for v in plant.state}
    marks: dict[str, list[float]] = {}
    for p in spec.props:
        names = {v.name for v in variables(p.pred)}
        if len(names) != 1 or not names <= state.keys():
            continue
        v = state[names.pop()]
        z = np.linspace(v.lo, v.hi, GRID_SAMPLES)
        truth = np.broadcast_to(evaluate(p.pred, {v.name: z}), z.shape)
        flips = np.flatnonzero(truth[1:] != truth[:-1])
        marks.setdefault(v.name, []).extend((0.5 * (z[flips] + z[flips + 1])).tolist())
    out: dict[str, tuple[float, float]] = {}
    for v in plant.state:
        points = marks.get(v.name)
        if v.periodic or not points:
            continue
        glo, ghi = v.grid or (v.lo, v.hi)
        points = points + [b for r in spec.init if r.var == v.name for b in (r.lo, r.hi)]
        lo, hi = min(points), max(points)
        pad = GRID_MARGIN * max(hi - lo, 1e-3 * (ghi - glo))
        lo, hi = max(glo, lo - pad), min(ghi, hi + pad)
        if hi - lo > 1e-3 * (ghi - glo):
            out[v.name] = (float(lo), float(hi))
    return out


THRESHOLD_POINTS = 4096
"""Grid points over the variables a proposition reads at which :func:`spec_thresholds` looks for
where its truth changes (``4096 ** (1 / k)`` per axis for ``k`` variables, at least 2)."""


def spec_thresholds(spec: Spec) -> dict[str, np.ndarray]:
    r"""Per state variable, the values it takes on the boundaries of the spec's propositions: where a
    proposition's truth changes between neighbours of a grid over the plant's box of the variables it
    reads (one variable or several: a disc in ``(x, y)`` gives its extent in both). A proposition of
    no state variable, or of a variable the plant lacks, gives none.

    >>> from mitlc.spec.parse import parse_spec
    >>> spec = parse_spec("plant unicycle\ninit x in [-1.6, -1.2], y = 0, theta = 0\n"
    ...                   "prop goal = (x - 1) * (x - 1) + y * y < 0.09\nformula F G goal")
    >>> t = spec_thresholds(spec)
    >>> sorted(t), round(float(t["x"].min()), 1), round(float(t["x"].max()), 1), round(float(abs(t["y"]).max()), 1)
    (['x', 'y'], 0.7, 1.3, 0.3)
    """
    from mitlc.spec.predicates import evaluate, variables

    plant = spec.plant
    if plant is None:
        return {}
    state = {v.name: v for v in plant.state}
    out: dict[str, list[np.ndarray]] = {}
    for p in spec.props:
        names = sorted({v.name for v in variables(p.pred)})
        if not names or not set(names) <= state.keys():
            continue
        per_axis = max(2, int(round(THRESHOLD_POINTS ** (1.0 / len(names)))))
        axes = [np.linspace(state[n].lo, state[n].hi, per_axis) for n in names]
        grid = np.meshgrid(*axes, indexing="ij")
        truth = np.broadcast_to(evaluate(p.pred, dict(zip(names, grid, strict=True))), grid[0].shape)
        for a in range(len(names)):
            lo: list[slice] = [slice(None)] * len(names)
            hi: list[slice] = [slice(None)] * len(names)
            lo[a], hi[a] = slice(None, -1), slice(1, None)
            flips = truth[tuple(lo)] != truth[tuple(hi)]
            if not flips.any():
                continue
            for b, name in enumerate(names):  # the flip's place: the midpoint along axis a
                at = 0.5 * (grid[b][tuple(lo)] + grid[b][tuple(hi)])
                out.setdefault(name, []).append(at[flips])
    return {name: np.concatenate(parts) for name, parts in out.items()}
