"""What a verification samples and a falsifier searches: starts, plant parameters, disturbances.

A :class:`SearchSpace` maps a point ``z`` of the unit cube ``[0, 1]^dim`` to one scenario:
an initial state in the spec's ``init`` box (a fixed variable, ``qdot = 0``, takes no
coordinate), a value for each varied plant parameter (``--vary M=0.4:0.6``), and a bounded
disturbance added to each disturbed input (``--disturb u=0.5``: ``|d| <= 0.5``) or to the rate
of each disturbed state variable (``--disturb qdot=2``: ``qdot' + d``), constant over each of
``pieces`` equal spans of the horizon. Uniform ``z`` is uniform sampling of
the scenarios; an optimiser searches the same cube.

>>> import numpy as np
>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec("plant mass-damper\\ninit q in [-1, 1], qdot = 0\\nhorizon 2\\n"
...                   "prop home = abs(q) < 0.1\\nformula F G home")
>>> space = SearchSpace.of(spec, vary=parse_vary(["M=0.4:0.6"], spec), disturb=parse_disturb(["u=2"], spec))
>>> space.names
('q', 'M', 'u[0]')
>>> s = space.decode(np.array([[0.0, 0.5, 1.0]]))
>>> s.x0.tolist(), s.params["M"].tolist(), s.disturbance.tolist()
([[-1.0, 0.0]], [0.5], [[[2.0]]])
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mitlc.errors import InputError
from mitlc.spec.model import Spec

__all__ = ["SearchSpace", "Scenarios", "parse_vary", "parse_disturb"]

FIXED = ("dt",)
"""Parameters that cannot vary per rollout: the sample time is the policy's and the monitor's clock."""


def _number(text: str, option: str, item: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise InputError(f"'{item}': '{text}' is not a number", file=option) from None
    if not math.isfinite(v):
        raise InputError(f"'{item}': {text} is not a finite number", file=option)
    return v


def parse_vary(items: Sequence[str], spec: Spec) -> tuple[tuple[str, float, float], ...]:
    """``NAME=LO:HI`` items of ``--vary`` as ``(name, lo, hi)``; one line naming the option for an
    unknown parameter, a fixed one (``dt``), a malformed item or an empty range (``LO > HI``)."""
    plant = spec.plant
    if plant is None:
        raise InputError("the spec names no plant: nothing to vary", file="--vary")
    known = sorted(plant.defaults)
    out: list[tuple[str, float, float]] = []
    for item in items:
        name, eq, rng = item.partition("=")
        name = name.strip()
        lo_text, colon, hi_text = rng.partition(":")
        if not eq or not colon:
            raise InputError(f"'{item}': expected NAME=LO:HI, e.g. {known[0]}=0.9:1.1", file="--vary")
        if name not in plant.defaults:
            raise InputError(
                f"'{name}' is not a parameter of plant '{plant.name}' (its parameters: {', '.join(known)})",
                file="--vary",
            )
        if name in FIXED:
            raise InputError(f"'{name}' cannot vary: it is the policy's and the monitor's sample time", file="--vary")
        if any(v[0] == name for v in out):
            raise InputError(f"'{name}' is given twice", file="--vary")
        lo, hi = _number(lo_text, "--vary", item), _number(hi_text, "--vary", item)
        if lo > hi:
            raise InputError(f"'{item}': an empty range ({lo:g} > {hi:g})", file="--vary")
        out.append((name, lo, hi))
    return tuple(out)


def parse_disturb(items: Sequence[str], spec: Spec) -> tuple[tuple[str, float], ...]:
    """``NAME=EPS`` items of ``--disturb`` as ``(name, eps)``: an input ``NAME`` (``u``, or a declared
    input's name) is driven with the policy's value plus a disturbance in ``[-EPS, EPS]``; a state
    variable ``NAME`` moves with its rate plus one (an input's name wins where both have it)."""
    plant = spec.plant
    if plant is None:
        raise InputError("the spec names no plant: no input to disturb", file="--disturb")
    names = plant.input_names
    states = plant.state_names
    out: list[tuple[str, float]] = []
    for item in items:
        name, eq, eps_text = item.partition("=")
        name = name.strip()
        if not eq:
            raise InputError(f"'{item}': expected NAME=EPS, e.g. {names[0]}=0.1", file="--disturb")
        if name not in names and name not in states:
            raise InputError(
                f"'{name}' is neither an input nor a state variable of plant '{plant.name}' (inputs: "
                f"{', '.join(names)}; state: {', '.join(states)})",
                file="--disturb",
            )
        if any(v[0] == name for v in out):
            raise InputError(f"'{name}' is given twice", file="--disturb")
        eps = _number(eps_text, "--disturb", item)
        if eps < 0:
            raise InputError(f"'{item}': a bound is 0 or more, got {eps:g}", file="--disturb")
        out.append((name, eps))
    return tuple(out)


@dataclass(frozen=True)
class Scenarios:
    """``B`` scenarios: starts ``x0 (B, n)``, varied parameters (name -> ``(B,)``), the
    disturbance ``(B, pieces, m)`` added to the ``m`` inputs and ``(B, pieces, n)`` to the state's
    rates (zero where not disturbed), and the policy's run each is rolled out with."""

    x0: np.ndarray
    params: Mapping[str, np.ndarray]
    disturbance: np.ndarray
    state_disturbance: np.ndarray
    run: np.ndarray
    """``(B,)``: the trained run of the policy each scenario is rolled out with."""


@dataclass(frozen=True)
class SearchSpace:
    """The scenarios of one verification, as the unit cube ``[0, 1]^dim``."""

    state_names: tuple[str, ...]
    init_lo: tuple[float, ...]
    """Per state variable, the low end of its ``init`` range (a variable the spec does not
    name starts at 0, as the trainers start it)."""
    init_hi: tuple[float, ...]
    vary: tuple[tuple[str, float, float], ...] = ()
    """``(parameter, lo, hi)`` per varied plant parameter."""
    input_names: tuple[str, ...] = ("u",)
    disturb: tuple[tuple[str, float], ...] = ()
    """``(name, eps)`` per disturbed input or state variable: ``|d| <= eps``."""
    pieces: int = 1
    """A disturbance is constant over each of ``pieces`` equal spans of the horizon."""
    runs: int = 1
    """The trained runs of the policy (``mitlc train --runs``): each an independent controller. With
    more than one, the first coordinate picks the run (``floor(z * runs)``): a training's runs are
    sampled and searched together, as ``mitlc train``'s success rate counts them together."""

    @classmethod
    def of(
        cls,
        spec: Spec,
        vary: Sequence[tuple[str, float, float]] = (),
        disturb: Sequence[tuple[str, float]] = (),
        pieces: int = 1,
        runs: int = 1,
    ) -> SearchSpace:
        """The space of ``spec``'s ``init`` box, with ``vary`` and ``disturb`` (:func:`parse_vary`,
        :func:`parse_disturb`)."""
        plant = spec.plant
        if plant is None:
            raise InputError("the spec names no plant: there is nothing to roll out", file=spec.path)
        if pieces < 1:
            raise InputError(f"a disturbance needs 1 or more pieces, got {pieces}", file="--pieces")
        init = {r.var: (float(r.lo), float(r.hi)) for r in spec.init}
        lo = tuple(init.get(v, (0.0, 0.0))[0] for v in plant.state_names)
        hi = tuple(init.get(v, (0.0, 0.0))[1] for v in plant.state_names)
        if runs < 1:
            raise ValueError(f"a policy has 1 run or more, got {runs}")
        return cls(plant.state_names, lo, hi, tuple(vary), plant.input_names, tuple(disturb), int(pieces), int(runs))

    @property
    def free(self) -> tuple[int, ...]:
        """The state variables whose ``init`` range is wider than a point."""
        return tuple(i for i, (a, b) in enumerate(zip(self.init_lo, self.init_hi, strict=True)) if b > a)

    @property
    def names(self) -> tuple[str, ...]:
        """A name per coordinate: ``run`` (with several runs), the free state variables, the varied
        parameters, then ``NAME[piece]`` per disturbed input or state variable and piece."""
        dist = tuple(f"{n}[{j}]" for n, _ in self.disturb for j in range(self.pieces))
        run = ("run",) if self.runs > 1 else ()
        return run + tuple(self.state_names[i] for i in self.free) + tuple(v[0] for v in self.vary) + dist

    @property
    def dim(self) -> int:
        return len(self.names)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points drawn uniformly from the cube, ``(n, dim)``."""
        return rng.random((n, self.dim))

    def decode(self, z: np.ndarray) -> Scenarios:
        """The scenarios of the points ``z (B, dim)`` in ``[0, 1]^dim`` (clipped to it)."""
        z = np.clip(np.atleast_2d(np.asarray(z, dtype=float)), 0.0, 1.0)
        if z.shape[1] != self.dim:
            raise ValueError(f"points have {z.shape[1]} coordinates; the space has {self.dim}")
        B = z.shape[0]
        lo, hi = np.array(self.init_lo), np.array(self.init_hi)
        x0 = np.repeat(lo[None, :], B, axis=0)
        c = 0
        run = np.zeros(B, dtype=np.int64)
        if self.runs > 1:
            run = np.minimum(self.runs - 1, np.floor(z[:, 0] * self.runs)).astype(np.int64)
            c = 1
        for i in self.free:
            x0[:, i] = lo[i] + (hi[i] - lo[i]) * z[:, c]
            c += 1
        params = {}
        for name, a, b in self.vary:
            params[name] = a + (b - a) * z[:, c]
            c += 1
        dist = np.zeros((B, self.pieces, len(self.input_names)))
        state_dist = np.zeros((B, self.pieces, len(self.state_names)))
        for name, eps in self.disturb:
            d = eps * (2.0 * z[:, c : c + self.pieces] - 1.0)
            if name in self.input_names:
                dist[:, :, self.input_names.index(name)] = d
            else:
                state_dist[:, :, self.state_names.index(name)] = d
            c += self.pieces
        return Scenarios(x0, params, dist, state_dist, run)

    def disturbance_of(self, scenarios: Scenarios, name: str) -> np.ndarray:
        """``(B, pieces)``: the disturbance of the input or state variable ``name`` in each scenario."""
        if name in self.input_names:
            return scenarios.disturbance[:, :, self.input_names.index(name)]
        return scenarios.state_disturbance[:, :, self.state_names.index(name)]
