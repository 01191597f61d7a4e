"""The task suite: satisfiable specs, each with a witness controller the monitor accepts.

A task is a spec file ``bench/suite/specs/NAME.mitl`` whose first comment lines say
what it asks (``# task: ...``) and which operator families it uses (``# families:
...``), and a witness, ``WITNESSES[NAME]`` in :mod:`bench.suite.witnesses`: a fixed
controller ``witness(x, t, params) -> u`` (``x`` the states ``(R, n)`` in the spec's
state order, ``t`` the time in s, ``params`` the plant's parameters with the spec's
overrides; ``u`` the inputs, ``(R,)``, or ``(R, m)`` for a plant with ``m`` inputs).

:func:`rollout` rolls a controller out from starts spread over the spec's ``init``
box with mitlc's own simulators (:meth:`mitlc.plants.Plant.simulator`, what training
and ``mitlc simulate`` step) and :meth:`Rollouts.judge` judges every rollout with
mitlc's monitor (:func:`mitlc.monitor.monitor`, what ``mitlc check`` runs).

    python -m bench.suite                  # every task: its witness from every start, and zero input
"""

from __future__ import annotations

import itertools
import re
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from mitlc.limits import check_steps
from mitlc.monitor import MonitorResult, monitor
from mitlc.plants import Plant
from mitlc.spec import ast as A
from mitlc.spec.model import Spec
from mitlc.spec.parse import load_spec

__all__ = [
    "FAMILIES",
    "SPECS",
    "Task",
    "Rollouts",
    "load_tasks",
    "task",
    "nested_intervals",
    "spread",
    "rollout",
    "zero_input",
    "input_shape",
    "clip_inputs",
]

HERE = Path(__file__).resolve().parent
SPECS = HERE / "specs"

FAMILIES = (
    "reach-by-deadline",
    "reach-and-stay",
    "avoid",
    "sequence",
    "recurrence",
    "bounded-response",
    "until",
    "timed-window",
    "disjunction",
    "rate-limit",
)
"""The operator families a task may name in its ``# families:`` line: reach a region by a deadline
(``F[0,b] goal``), reach it and stay (``F G``), avoid a region (``G !obs``), a sequence with nested
deadlines (``F[0,a] (p & F[0,b] q)``), recurrence (``G[..] F[0,b] p``), bounded response
(``G (p -> F[0,b] q)``), until with a deadline (``p U[0,b] q``), timed visit windows (``F[a,b]``,
``G[a,b]``), a disjunction of goals, and rate limits (a bound on a velocity)."""

Witness = Callable[[np.ndarray, float, Mapping[str, float]], np.ndarray]

MAX_STARTS = 25
"""About this many starts per task by default (:func:`spread`)."""


@dataclass(frozen=True)
class Task:
    """One task of the suite."""

    name: str
    spec_path: Path
    spec: Spec
    description: str
    families: tuple[str, ...]
    nested: bool
    """The formula has an interval nested under another temporal operator (``F[0,4] G[0,2] up``,
    ``G (push -> F[0,1] calm)``): :func:`nested_intervals`."""
    witness: Witness

    @property
    def plant(self) -> str:
        """The plant's name as the spec gives it (``pendulum``, ``gym:Pendulum-v1``)."""
        assert self.spec.plant is not None
        return self.spec.plant.name


def _header(path: Path) -> dict[str, str]:
    """The ``# key: value`` lines of a spec's first comment block."""
    out: dict[str, str] = {}
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        m = re.match(r"#\s*(task|families)\s*:\s*(.*\S)\s*$", line)
        if m:
            out[m.group(1)] = m.group(2)
    return out


def nested_intervals(f: A.Formula) -> bool:
    """Whether a temporal operator with an interval other than ``[0, inf)`` sits under another
    temporal operator.

    >>> from mitlc.spec.parse import parse_formula
    >>> [nested_intervals(parse_formula(s)) for s in ("F[0,2] G k", "F[0,4] G[0,2] k", "G (a -> F[0,1] b)")]
    [False, True, True]
    """
    temporal = (A.Eventually, A.Globally, A.Until, A.Release, A.WeakUntil)

    def walk(g: A.Formula, under: bool) -> bool:
        here = isinstance(g, temporal)
        if here and under and not g.interval.is_unbounded:  # type: ignore[attr-defined]
            return True
        return any(walk(c, under or here) for c in g.children)

    return walk(f, False)


@cache
def load_tasks() -> tuple[Task, ...]:
    """Every task, by name: the spec files of ``bench/suite/specs/`` with their witnesses."""
    from bench.suite.witnesses import WITNESSES

    out = []
    names = sorted(p.stem for p in SPECS.glob("*.mitl"))
    missing = sorted(set(names) - set(WITNESSES))
    extra = sorted(set(WITNESSES) - set(names))
    if missing or extra:
        raise ValueError(f"tasks without a witness: {missing}; witnesses without a task: {extra}")
    for name in names:
        path = SPECS / f"{name}.mitl"
        head = _header(path)
        if "task" not in head or "families" not in head:
            raise ValueError(f"{path}: its first comment lines need '# task: ...' and '# families: ...'")
        families = tuple(f.strip() for f in head["families"].split(","))
        unknown = [f for f in families if f not in FAMILIES]
        if unknown:
            raise ValueError(f"{path}: unknown families {unknown}; known: {', '.join(FAMILIES)}")
        spec = load_spec(path)
        if spec.plant is None or spec.horizon is None or spec.formula is None:
            raise ValueError(f"{path}: a task names a plant, a horizon and a formula")
        formula = spec.monitor_formula
        assert formula is not None
        out.append(
            Task(
                name=name,
                spec_path=path,
                spec=spec,
                description=head["task"],
                families=families,
                nested=nested_intervals(formula),
                witness=WITNESSES[name],
            )
        )
    return tuple(out)


def task(name: str) -> Task:
    """The task called ``name``."""
    for t in load_tasks():
        if t.name == name:
            return t
    raise KeyError(f"no task {name!r}; tasks: {', '.join(t.name for t in load_tasks())}")


def zero_input(x: np.ndarray, t: float, params: Mapping[str, float]) -> np.ndarray:
    """The controller that does nothing: what a task must not be satisfied by, mostly. It returns
    ``(R,)``; :func:`rollout` gives it every input's zero, ``(R, m)``, on a plant with ``m`` inputs."""
    return np.zeros(x.shape[0])


def input_shape(plant: Plant, rows: int) -> tuple[int, ...]:
    """The shape a controller returns for ``rows`` states: ``(R,)`` for one input, ``(R, m)`` for ``m``."""
    return (rows,) if plant.n_inputs == 1 else (rows, plant.n_inputs)


def clip_inputs(
    t: Task, u: np.ndarray, rows: int, params: Mapping[str, float], who: str = "the controller"
) -> np.ndarray:
    """``u`` clipped to the plant's input bound: each input to its own box for a plant that declares
    its inputs (:meth:`~mitlc.plants.Plant.input_box`), ``+-u_max`` for the others (none for an
    environment without ``u_max``). A ``u`` of another shape than :func:`input_shape`'s is a
    ``ValueError`` naming the task, ``who`` returned it, and both shapes."""
    plant = t.spec.plant
    assert plant is not None
    want = input_shape(plant, rows)
    if u.shape != want:
        names = ", ".join(plant.input_names)
        raise ValueError(
            f"task {t.name}: {who} returned inputs of shape {u.shape}; expected {want} "
            f"(plant '{plant.name}', inputs: {names})"
        )
    if plant.inputs is None:
        u_max = params.get("u_max", np.inf)
        return np.clip(u, -u_max, u_max)
    lo, hi = plant.input_box(params)
    return np.clip(u, lo, hi) if plant.n_inputs > 1 else np.clip(u, lo[0], hi[0])


def params_of(spec: Spec) -> dict[str, float]:
    """The plant's parameters with the spec's overrides."""
    assert spec.plant is not None
    return spec.plant.params(dict(spec.plant_params))


def init_box(spec: Spec) -> list[tuple[float, float]]:
    """``(lo, hi)`` per state variable, in the plant's order (``(0, 0)`` where ``init`` says nothing)."""
    assert spec.plant is not None
    init = {r.var: (r.lo, r.hi) for r in spec.init}
    return [init.get(v, (0.0, 0.0)) for v in spec.plant.state_names]


def spread(box: Sequence[tuple[float, float]], count: int = MAX_STARTS, seed: int = 0) -> np.ndarray:
    """About ``count`` points spread over ``box``: every corner, the centre, and a grid or a seeded
    sample for the rest, ``(R, n)``.

    The variables with a range (``lo < hi``) span a grid of ``k`` values each, ``k`` the largest with
    ``k^d <= count`` (at least 2: the corners); what is left of ``count`` is drawn uniformly (``seed``).

    >>> spread([(0.0, 1.0), (2.0, 2.0)], 5).tolist()
    [[0.0, 2.0], [0.25, 2.0], [0.5, 2.0], [0.75, 2.0], [1.0, 2.0]]
    >>> spread([(0.0, 1.0)] * 4).shape  # 16 corners, the centre and 8 drawn
    (25, 4)
    """
    ranged = [i for i, (lo, hi) in enumerate(box) if hi > lo]
    base = np.array([lo for lo, _ in box], dtype=float)
    if not ranged:
        return base[None, :].copy()
    d = len(ranged)
    k = 2
    while (k + 1) ** d <= count:
        k += 1
    axes = [np.linspace(box[i][0], box[i][1], k) for i in ranged]
    pts = []
    for combo in itertools.product(*axes):
        p = base.copy()
        p[ranged] = combo
        pts.append(p)
    if k % 2 == 0:  # the centre is not on the grid
        p = base.copy()
        p[ranged] = [(box[i][0] + box[i][1]) / 2 for i in ranged]
        pts.append(p)
    rng = np.random.default_rng(seed)
    while len(pts) < count:
        p = base.copy()
        p[ranged] = [rng.uniform(box[i][0], box[i][1]) for i in ranged]
        pts.append(p)
    return np.array(pts)


@dataclass
class Rollouts:
    """Rollouts of one controller on one task, from ``R`` starts."""

    task: Task
    states: np.ndarray
    """``(R, N+1, n)``, in the plant's state order."""
    inputs: np.ndarray
    """``(R, N)`` (``(R, N, m)`` for ``m`` inputs), after clipping to the inputs' boxes."""
    dt: float

    @property
    def starts(self) -> np.ndarray:
        return self.states[:, 0]

    @property
    def t(self) -> np.ndarray:
        return np.arange(self.states.shape[1]) * self.dt

    def judge(self) -> MonitorResult:
        """The monitor's verdicts, one per rollout, by the spec's ``check`` line or its formula."""
        return monitor(self.task.spec, self.states, self.dt)

    def columns(self, r: int) -> dict[str, np.ndarray]:
        """Rollout ``r`` as named columns (for :func:`mitlc.monitor.trace.write_trace`)."""
        names = self.task.spec.plant.state_names  # type: ignore[union-attr]
        return {v: self.states[r, :, i] for i, v in enumerate(names)}


GYM_CANDIDATES = 256
"""Seeded resets an environment makes, of which :func:`_gym_seeds` picks those nearest the spread."""


@cache
def _gym_seeds(name: str, count: int) -> tuple[int, ...]:
    """Seeds whose resets of task ``name``'s environment come nearest the points :func:`spread` puts
    over its ``init`` box (an environment cannot be put in a state: it starts where its reset puts it).
    Distances are measured in units of each variable's range; a seed is used once."""
    t = task(name)
    spec = t.spec
    assert spec.plant is not None
    sim = spec.plant.simulator(params_of(spec), {r.var: (r.lo, r.hi) for r in spec.init})
    try:
        cand = sim.reset([np.random.default_rng(s) for s in range(GYM_CANDIDATES)])
    finally:
        getattr(sim, "close", lambda: None)()
    box = init_box(spec)
    scale = np.array([(hi - lo) or 1.0 for lo, hi in box])
    chosen: list[int] = []
    for p in spread(box, count):
        d = np.abs((cand - p) / scale).max(axis=1)
        d[chosen] = np.inf
        chosen.append(int(np.argmin(d)))
    return tuple(chosen)


def rollout(t: Task, controller: Witness | None = None, count: int = MAX_STARTS) -> Rollouts:
    """Roll ``controller`` (default: the task's witness) out on the task's plant for the spec's
    horizon, from about ``count`` starts spread over its ``init`` box (:func:`spread`; an
    environment: the seeded resets nearest them, :func:`_gym_seeds`).

    The plant is stepped by its simulator, as SACPN's trials and ``mitlc simulate`` step it. The
    controller returns ``(R,)`` for a plant with one input and ``(R, m)`` for one with ``m``
    (another shape is a ``ValueError`` naming the task); each input is clipped to its own box
    (``+-u_max`` for a plant bounded by ``u_max``) before it is recorded and applied
    (:func:`clip_inputs`)."""
    who = "the controller" if controller is not None and controller is not t.witness else "its witness"
    controller = controller or t.witness
    spec = t.spec
    plant = spec.plant
    assert plant is not None and spec.horizon is not None
    params = params_of(spec)
    dt = float(params["dt"])
    steps = check_steps(spec.horizon, dt, "a task")
    sim = plant.simulator(params, {r.var: (r.lo, r.hi) for r in spec.init})
    try:
        if sim.settable:
            x = spread(init_box(spec), count)
            for i, v in enumerate(plant.state):
                if v.periodic:
                    x[:, i] = (x[:, i] + np.pi) % (2 * np.pi) - np.pi
            sim.start(x)
        else:
            x = sim.reset([np.random.default_rng(s) for s in _gym_seeds(t.name, count)])
        R = x.shape[0]
        states = np.empty((R, steps + 1, x.shape[1]))
        states[:, 0] = x
        want = input_shape(plant, R)
        inputs = np.empty((R, steps, *want[1:]))
        for k in range(steps):
            if controller is zero_input:
                u = np.zeros(want)
            else:
                u = clip_inputs(t, np.asarray(controller(x.copy(), k * dt, params), dtype=float), R, params, who)
            inputs[:, k] = u
            sim.step(x, u)
            states[:, k + 1] = x
    finally:
        getattr(sim, "close", lambda: None)()
    return Rollouts(t, states, inputs, dt)


def main(argv: Sequence[str] = ()) -> int:
    """Every task (or those named): the witness's verdicts from every start and zero input's."""
    names = list(argv) or [t.name for t in load_tasks()]
    bad = 0
    for name in names:
        t = task(name)
        t0 = time.perf_counter()
        res = rollout(t).judge()
        wall = time.perf_counter() - t0
        zero = rollout(t, zero_input).judge()
        ok = int(res.satisfied.sum())
        bad += ok < len(res.satisfied)
        fails = sorted({f for f in res.failing if f})
        print(
            f"{t.name:32s} {t.plant:28s} witness {ok:2d}/{len(res.satisfied):2d} (min robustness "
            f"{res.robustness.min():+.3f}, {wall:.2f} s)  zero input {int(zero.satisfied.sum()):2d}/"
            f"{len(zero.satisfied):2d}  nested={t.nested}" + (f"  failing: {fails}" if fails else "")
        )
    return 1 if bad else 0
