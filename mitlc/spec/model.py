"""The parsed spec: propositions, formula and task settings (immutable).

>>> from mitlc.spec.parse import parse_spec
>>> spec = parse_spec('''
... plant pendulum(u_max = 10)
... init q in [2.4, pi], qdot = 0
... horizon 3
... prop kappa = abs(q) < 0.3
... prop psi = 0.3 < q < pi/2 + 0.5
... formula F G kappa & 10 * G !psi
... ''')
>>> print(spec.formula)
F G kappa & 10 * G !psi
>>> spec.param("u_max"), spec.horizon
(10.0, 3.0)
>>> [str(p.pred) for p in spec.props]
['abs(q) < 0.3', '0.3 < q < pi / 2 + 0.5']
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mitlc.plants.base import PLANTS, Plant
from mitlc.spec.ast import Formula, Pos
from mitlc.spec.predicates import IntervalSet, Pred

__all__ = ["PropDef", "InitRange", "Requirement", "Spec", "OPTIONS", "CRITERIA"]

CRITERIA: dict[str, str] = {
    "overshoot": "largest overshoot past the set-point, as a fraction of the step (M_p)",
    "rise_time": "time to go from 10% to 90% of the step, in seconds (t_r)",
    "settling_time": "time after which the state stays within the band around the set-point (t_s)",
    "steady_state_error": "distance from the set-point at the end of the trial (e_ss)",
}
"""Classical step-response criteria a spec may ``require`` (thesis section 2-2-2)."""

OPTIONS: dict[str, tuple[str, ...]] = {
    "conjunction": ("literal", "active"),
    "violations": ("off", "permanent", "counted"),
    "clock": ("standard", "trial"),
    "reward": ("net", "shaped", "graded", "sparse", "robustness", "robustness-window"),
}
"""Spec options (``option NAME = VALUE``) and their allowed values; the first is the default."""

MONITOR_REWARDS = ("sparse", "robustness", "robustness-window")
"""The ``reward`` options paid by the monitor (:mod:`mitlc.monitor.rewards`), not by the net."""


@dataclass(frozen=True, slots=True)
class PropDef:
    """``prop name = predicate``."""

    name: str
    pred: Pred
    pos: Pos | None = field(default=None, compare=False)
    inline: bool = field(default=False, compare=False)
    """Written inside the formula (``G (abs(q) < 0.3)``), named by :func:`readable_name`."""


@dataclass(frozen=True, slots=True)
class InitRange:
    """``init var in [lo, hi]`` (``var = v`` gives ``lo == hi``)."""

    var: str
    lo: float
    hi: float


@dataclass(frozen=True, slots=True)
class Requirement:
    """``require name <= hi`` or ``require name in [lo, hi]`` (``band`` for the settling time)."""

    name: str
    lo: float
    hi: float
    band: float | None = None
    pos: Pos | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Spec:
    """Everything a spec file says, checked.

    ``formula`` is None only for a classical-performance spec (``require``).
    """

    formula: Formula | None
    props: tuple[PropDef, ...] = ()
    check: Formula | None = None
    plant_name: str | None = None
    plant_params: tuple[tuple[str, float], ...] = ()
    init: tuple[InitRange, ...] = ()
    horizon: float | None = None
    options: tuple[tuple[str, str], ...] = ()
    setpoint: float = 0.0
    requirements: tuple[Requirement, ...] = ()
    path: str | None = None
    source: str | None = field(default=None, repr=False, compare=False)
    warnings: tuple[str, ...] = field(default=(), compare=False)
    env_plant: Plant | None = field(default=None, compare=False, repr=False)
    """The plant a ``plant gym:ID`` line and its ``state`` lines build (not in the registry)."""

    @property
    def plant(self) -> Plant | None:
        if self.env_plant is not None:
            return self.env_plant
        return PLANTS.get(self.plant_name) if self.plant_name else None

    @property
    def monitor_formula(self) -> Formula | None:
        """The formula a trajectory is judged by: ``check`` if given, else ``formula``."""
        return self.check if self.check is not None else self.formula

    def prop(self, name: str) -> PropDef:
        for p in self.props:
            if p.name == name:
                return p
        raise KeyError(name)

    def param(self, name: str) -> float:
        """A plant parameter: the spec's value, else the plant's default."""
        for k, v in self.plant_params:
            if k == name:
                return v
        plant = self.plant
        if plant is not None and name in plant.defaults:
            return float(plant.defaults[name])
        raise KeyError(name)

    def option(self, name: str) -> str:
        for k, v in self.options:
            if k == name:
                return v
        return OPTIONS[name][0]

    def domains(self) -> dict[str, IntervalSet]:
        """Bounds of the state variables, for interval analysis (empty if no plant)."""
        plant = self.plant
        if plant is None:
            return {}
        return {v.name: IntervalSet.of(v.lo, v.hi, True, not v.periodic) for v in plant.state}
