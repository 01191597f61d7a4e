"""Hybrid automata for classical step-response criteria (thesis chapter 3, appendix B).

A classical-performance spec (``setpoint`` and ``require`` statements, no
formula) compiles to a hybrid automaton whose modes time the evaluation of each
criterion and whose mode-wise rewards are the thesis's building blocks
(3-11)/(3-12):

* ``I`` (idle): the start; penalised when moving away from the set-point.
* one evaluating mode per criterion, chained in the order of appendix B-3
  (rise time, then overshoot), then the two criteria beyond the thesis::

      I -> E_tr -> E_Mp -> E_ts -> E_ess -> S

  ``I`` jumps to the first of them at its checkpoint; each ``E`` jumps to the
  next on success and to ``P`` on a violation.
* ``S`` (stabilising): stay within the band of the criteria; ``+3`` per step
  spent in it.
* ``P`` (penalising): ``-9`` per step.

The continuous state is the plant's ``(q, qdot)``; the memory ``z = (q0, t)``
holds the initial position and the mode clock, which starts at 0 and runs only
in the modes marked ``clock`` (``E_tr``, appendix B-2).  Guards may also read
``tau``, the time since the start of the trial (used only by the settling
time, which is measured from the step).

Guards and rewards are data (:class:`Cmp`, :class:`AllOf`, :class:`AnyOf`,
reward terms), evaluated with numpy over a leading run axis; nothing is ever
passed to ``eval``.  Thresholds are points of the step: ``thr(f) = s + f (q0 -
s)`` is where ``f`` of the step is still to go (``f = 0.9``: 10% done, the
thesis's ``0.9 q0`` for set-point 0).  Every directional guard is built for
the rising case (``q0 < s``, the thesis's "overshoot" case) and the falling
case (``q0 >= s``, "undershoot"), with a case split on ``q0`` when the spec's
initial range holds both (Table B-1); when it holds only one, only that case
is written (Tables B-3, B-5).

>>> from mitlc.spec.parse import parse_spec
>>> h = compile_requirements(parse_spec('''
... plant mass-damper
... init q in [-1, -0.5], qdot = 0
... setpoint 0
... require rise_time in [0.6, 0.8]'''))
>>> [m.name for m in h.modes]
['I', 'E_tr', 'S', 'P']
>>> print(h.edge("I", "E_tr").guard)
q > 0.9*q0
>>> print(h.edge("E_tr", "P").guard)
qdot < 0 | (q > 0.1*q0 & t < 0.6) | t > 0.8
>>> h.mode("P").permanent, h.mode("S").permanent
(True, True)
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Union

import numpy as np

from mitlc.spec.ast import fmt_number
from mitlc.hybrid.criteria import DEFAULT_SETTLING_BAND
from mitlc.errors import InputError, MitlError, SpecError
from mitlc.spec.model import Requirement, Spec

__all__ = [
    "VARS",
    "Lin",
    "Cmp",
    "AllOf",
    "AnyOf",
    "Guard",
    "TRUE",
    "FALSE",
    "all_of",
    "any_of",
    "negate",
    "interior",
    "evaluate",
    "guard_to_dict",
    "guard_from_dict",
    "Const",
    "AbsError",
    "IfElse",
    "StayBonus",
    "Reward",
    "RewardConstants",
    "Mode",
    "Edge",
    "HybridAutomaton",
    "Trace",
    "compile_requirements",
    "render_bytes",
    "DEFAULT_HORIZON",
    "DEFAULT_SETTLING_BAND",
    "MODE_OF",
    "ORDER",
]

VARS = ("q", "qdot", "q0", "t", "tau")
"""Variables a guard or reward may read: position, velocity, the memory ``(q0, t)``
(initial position, mode clock) and ``tau``, the time since the start of the trial."""

DEFAULT_HORIZON = 5.0
"""Trial duration when the spec gives no ``horizon`` (Table 3-2: T_t = 5 s)."""


ORDER = ("rise_time", "overshoot", "settling_time", "steady_state_error")
"""The order of the evaluating modes in the chain (rise time before overshoot: Table B-5)."""

MODE_OF = {
    "rise_time": "E_tr",
    "overshoot": "E_Mp",
    "settling_time": "E_ts",
    "steady_state_error": "E_ess",
}
"""The evaluating mode of each criterion."""

# thresholds as the fraction of the step still to go (thesis: 0.9 q0, 0.05 q0, 0.1 q0)
F_RISE_START = 0.9  # 10% of the step done: I -> E_tr (Table B-3)
F_RISE_END = 0.1  # 90% done: the rise is complete (Table B-3)
F_NEAR = 0.05  # 95% done: I -> E_Mp (Table B-1)
F_S_LOW = 0.1  # S lives between 90% and the allowed peak (Inv(delta_3) of (B-1))

_OPS: dict[str, Callable[[Any, Any], Any]] = {
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
}
_NEG = {"<": ">=", "<=": ">", ">": "<=", ">=": "<"}
_STRICT = {"<": "<", "<=": "<", ">": ">", ">=": ">"}


def _fmt(x: float) -> str:
    return fmt_number(round(float(x), 12))


# ---------------------------------------------------------------- linear forms


@dataclass(frozen=True, slots=True)
class Lin:
    """A linear form ``const + sum(c * var)`` over :data:`VARS` (a guard threshold).

    >>> print(Lin((("q0", 0.05),)))
    0.05*q0
    >>> print(Lin((("q0", 0.1),), 0.9))
    0.1*q0 + 0.9
    >>> print(Lin((), -0.5))
    -0.5
    """

    terms: tuple[tuple[str, float], ...] = ()
    const: float = 0.0

    def value(self, env: Mapping[str, Any]) -> Any:
        out: Any = self.const
        for var, c in self.terms:
            out = out + c * env[var]
        return out

    def __str__(self) -> str:
        parts: list[tuple[float, str]] = []
        for var, c in self.terms:
            mag = abs(c)
            parts.append((c, var if mag == 1 else f"{_fmt(mag)}*{var}"))
        if self.const != 0 or not parts:
            parts.append((self.const, _fmt(abs(self.const))))
        out = ""
        for i, (c, text) in enumerate(parts):
            if i == 0:
                out = ("-" if c < 0 else "") + text
            else:
                out += (" - " if c < 0 else " + ") + text
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"terms": {v: c for v, c in self.terms}, "const": self.const}

    @staticmethod
    def from_dict(d: Mapping[str, Any]) -> "Lin":
        return Lin(tuple((str(v), float(c)) for v, c in dict(d.get("terms", {})).items()), float(d.get("const", 0.0)))


# ---------------------------------------------------------------- guards


@dataclass(frozen=True, slots=True)
class Cmp:
    """``var op rhs``, e.g. ``q > 0.05*q0``."""

    var: str
    op: str
    rhs: Lin = Lin()

    def __post_init__(self) -> None:
        if self.var not in VARS:
            raise SpecError(f"unknown guard variable '{self.var}' (known: {', '.join(VARS)})")
        if self.op not in _OPS:
            raise SpecError(f"unknown comparison '{self.op}'")

    def __str__(self) -> str:
        return f"{self.var} {self.op} {self.rhs}"


@dataclass(frozen=True, slots=True)
class AllOf:
    """Conjunction; ``AllOf(())`` is true."""

    args: tuple["Guard", ...] = ()

    def __str__(self) -> str:
        if not self.args:
            return "true"
        return " & ".join(_wrap(a) for a in self.args)


@dataclass(frozen=True, slots=True)
class AnyOf:
    """Disjunction; ``AnyOf(())`` is false."""

    args: tuple["Guard", ...] = ()

    def __str__(self) -> str:
        if not self.args:
            return "false"
        return " | ".join(_wrap(a) for a in self.args)


Guard = Union[Cmp, AllOf, AnyOf]
TRUE: Guard = AllOf(())
FALSE: Guard = AnyOf(())


def _wrap(g: Guard) -> str:
    return f"({g})" if isinstance(g, (AllOf, AnyOf)) and len(g.args) > 1 else str(g)


def _join(cls: type, absorbing: Guard, gs: tuple[Guard, ...]) -> Guard:
    """``cls`` (AllOf or AnyOf) of ``gs``, flattened and deduplicated; ``absorbing`` decides it at once."""
    out: list[Guard] = []
    for g in gs:
        if isinstance(g, cls):
            out.extend(a for a in g.args if a not in out)  # type: ignore[attr-defined]
        elif g == absorbing:
            return absorbing
        elif g not in out:
            out.append(g)
    return out[0] if len(out) == 1 else cls(tuple(out))


def all_of(*gs: Guard) -> Guard:
    """Conjunction, flattened: ``TRUE`` parts dropped, any ``FALSE`` part makes ``FALSE``."""
    return _join(AllOf, FALSE, gs)


def any_of(*gs: Guard) -> Guard:
    """Disjunction, flattened: ``FALSE`` parts dropped, any ``TRUE`` part makes ``TRUE``."""
    return _join(AnyOf, TRUE, gs)


def negate(g: Guard) -> Guard:
    """The complement, pushed down to the comparisons (De Morgan).

    >>> print(negate(all_of(Cmp("q", ">=", Lin((("q0", 0.1),))), Cmp("q", "<=", Lin()))))
    q < 0.1*q0 | q > 0
    """
    if isinstance(g, Cmp):
        return Cmp(g.var, _NEG[g.op], g.rhs)
    if isinstance(g, AllOf):
        return any_of(*(negate(a) for a in g.args)) if g.args else FALSE
    return all_of(*(negate(a) for a in g.args)) if g.args else TRUE


def interior(g: Guard) -> Guard:
    """The same guard with every comparison strict (the interior of a closed band)."""
    if isinstance(g, Cmp):
        return Cmp(g.var, _STRICT[g.op], g.rhs)
    if isinstance(g, AllOf):
        return AllOf(tuple(interior(a) for a in g.args))
    return AnyOf(tuple(interior(a) for a in g.args))


def evaluate(g: Guard, env: Mapping[str, Any]) -> np.ndarray:
    """Evaluate ``g`` on arrays of a common shape (one entry per run); no ``eval``.

    >>> env = {"q": np.array([-0.5, 0.2]), "q0": np.array([-1.0, -1.0])}
    >>> evaluate(Cmp("q", ">", Lin((("q0", 0.9),))), env)
    array([ True,  True])
    >>> evaluate(Cmp("q", ">", Lin()), env)
    array([False,  True])
    """
    if isinstance(g, Cmp):
        return np.asarray(_OPS[g.op](env[g.var], g.rhs.value(env)))
    shape = np.shape(env["q"])
    if isinstance(g, AllOf):
        out = np.ones(shape, dtype=bool)
        for a in g.args:
            out &= evaluate(a, env)
        return out
    out = np.zeros(shape, dtype=bool)
    for a in g.args:
        out |= evaluate(a, env)
    return out


def variables(g: Guard) -> set[str]:
    """The variables a guard reads."""
    if isinstance(g, Cmp):
        return {g.var} | {v for v, _ in g.rhs.terms}
    out: set[str] = set()
    for a in g.args:
        out |= variables(a)
    return out


def guard_to_dict(g: Guard) -> dict[str, Any]:
    """The guard as nested JSON-able dicts (``cmp``, ``all``, ``any``)."""
    if isinstance(g, Cmp):
        return {"cmp": {"var": g.var, "op": g.op, "rhs": g.rhs.to_dict()}}
    key = "all" if isinstance(g, AllOf) else "any"
    return {key: [guard_to_dict(a) for a in g.args]}


def guard_from_dict(d: Mapping[str, Any]) -> Guard:
    """Inverse of :func:`guard_to_dict`."""
    if "cmp" in d:
        c = d["cmp"]
        return Cmp(str(c["var"]), str(c["op"]), Lin.from_dict(c.get("rhs", {})))
    if "all" in d:
        return AllOf(tuple(guard_from_dict(a) for a in d["all"]))
    if "any" in d:
        return AnyOf(tuple(guard_from_dict(a) for a in d["any"]))
    raise InputError(f"not a guard: {sorted(d)}")


# ---------------------------------------------------------------- rewards


@dataclass(frozen=True, slots=True)
class Const:
    """A constant reward per step (the discrete reward (3-11) with S = X)."""

    value: float

    def __str__(self) -> str:
        return _fmt(self.value)


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
        return f"-{_fmt(self.weight)}*|{err}|"


@dataclass(frozen=True, slots=True)
class IfElse:
    """``then`` where ``guard`` holds after the step, else ``otherwise`` (the discrete reward (3-11))."""

    guard: Guard
    then: float
    otherwise: float

    def __str__(self) -> str:
        return f"({_fmt(self.then)} if {self.guard} else {_fmt(self.otherwise)})"


@dataclass(frozen=True, slots=True)
class StayBonus:
    """``value`` when the automaton was in this mode before and after the step
    (Table 3-1: ``+3 if delta = delta' = S``)."""

    value: float

    def __str__(self) -> str:
        return f"({_fmt(self.value)} if stayed)"


RewardTerm = Union[Const, AbsError, IfElse, StayBonus]


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


# ---------------------------------------------------------------- the automaton


@dataclass(frozen=True)
class Mode:
    """One discrete state ``delta``: its invariant, reward, whether the clock runs in it,
    and whether it is permanent (no edge leaves it)."""

    name: str
    kind: str  # "I", "E", "S", "P"
    invariant: Guard
    reward: Reward
    clock: bool = False
    permanent: bool = False
    criterion: str | None = None
    doc: str = ""


@dataclass(frozen=True)
class Edge:
    """A guarded jump ``src -> dst``; ``kind`` is ``checkpoint`` (I to the first E),
    ``success``, ``violation`` or ``recovery`` (P back to S)."""

    src: str
    dst: str
    guard: Guard
    kind: str


@dataclass
class Trace:
    """The automaton run along given trajectories: ``modes (R, N+1)`` (indices into
    ``automaton.modes``), clock ``t (R, N+1)``, ``rewards (R, N)``."""

    modes: np.ndarray
    t: np.ndarray
    rewards: np.ndarray
    names: tuple[str, ...]

    def mode_names(self, run: int = 0) -> list[str]:
        """The mode of every sample of one run, by name."""
        return [self.names[i] for i in self.modes[run]]

    def sequence(self, run: int = 0) -> list[str]:
        """The modes one run visits, consecutive repeats collapsed."""
        out: list[str] = []
        for name in self.mode_names(run):
            if not out or out[-1] != name:
                out.append(name)
        return out


@dataclass(frozen=True)
class HybridAutomaton:
    """``H = (D, X, f, Init, Inv, E, G, R, rho)`` of section 3-2 for a classical spec.

    The plant moves ``(q, qdot)``; the memory ``(q0, t)`` is fixed / clocked; a
    step of the automaton after each sample is: advance the clock by ``dt`` if
    the current mode runs it, then take enabled edges (the first enabled edge of
    the current mode, in the listed order, repeated until none is enabled, at
    most once per mode: jumps are urgent), then pay the reward of the mode the
    automaton is now in, evaluated on the state after the sample.
    """

    modes: tuple[Mode, ...]
    edges: tuple[Edge, ...]
    setpoint: float
    q0_range: tuple[float, float]
    qdot0_range: tuple[float, float]
    horizon: float
    requirements: tuple[Requirement, ...]
    constants: RewardConstants = RewardConstants()
    plant_name: str | None = None
    cases: tuple[str, ...] = ("rising",)
    spec_path: str | None = None
    initial: str = "I"

    def __post_init__(self) -> None:
        names = [m.name for m in self.modes]
        object.__setattr__(self, "_index", {n: i for i, n in enumerate(names)})
        by_src: list[list[tuple[int, Guard]]] = [[] for _ in names]
        for e in self.edges:
            by_src[names.index(e.src)].append((names.index(e.dst), e.guard))
        object.__setattr__(self, "_out", by_src)
        object.__setattr__(self, "_clock", np.array([m.clock for m in self.modes], dtype=bool))

    # ------------------------------------------------------------ lookup
    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.modes)

    def index(self, name: str) -> int:
        try:
            return self._index[name]  # type: ignore[attr-defined]
        except KeyError:
            raise KeyError(f"no mode '{name}' (modes: {', '.join(self.names)})") from None

    def mode(self, name: str) -> Mode:
        return self.modes[self.index(name)]

    def edge(self, src: str, dst: str) -> Edge:
        for e in self.edges:
            if e.src == src and e.dst == dst:
                return e
        raise KeyError(f"no edge {src} -> {dst}")

    @property
    def evaluating(self) -> tuple[str, ...]:
        """The evaluating modes in chain order."""
        return tuple(m.name for m in self.modes if m.kind == "E")

    @property
    def memory(self) -> tuple[str, str]:
        return ("q0", "t")

    def time_vars(self) -> tuple[str, ...]:
        """The clocks the guards read, in ``(t, tau)`` order: what a learner must see."""
        used: set[str] = set()
        for e in self.edges:
            used |= variables(e.guard)
        return tuple(v for v in ("t", "tau") if v in used)

    def time_range(self, var: str) -> tuple[float, float]:
        """The range of a clock worth resolving: up to its largest guard constant (``t``)
        or the horizon (``tau``)."""
        if var == "tau":
            return (0.0, self.horizon)
        hi = 0.0
        for e in self.edges:
            hi = max(hi, _max_const(e.guard, "t"))
        return (0.0, hi if hi > 0 else self.horizon)

    # ------------------------------------------------------------ running (vectorised)
    def env(self, x: np.ndarray, q0: np.ndarray, t: np.ndarray, tau: float | np.ndarray) -> dict[str, Any]:
        """The guard variables for states ``x (R, 2)``."""
        return {"q": x[:, 0], "qdot": x[:, 1], "q0": q0, "t": t, "tau": np.broadcast_to(tau, q0.shape)}

    def jump(self, mode: np.ndarray, env: Mapping[str, Any]) -> np.ndarray:
        """Take enabled edges until none is (urgent jumps), each mode entered at most once."""
        mode = mode.copy()
        moving = np.ones(mode.shape, dtype=bool)
        for _ in range(len(self.modes)):
            cur = mode.copy()
            took = np.zeros(mode.shape, dtype=bool)
            for src in np.unique(cur[moving]):
                rows = moving & (cur == src)
                for dst, guard in self._out[src]:  # type: ignore[attr-defined]
                    hit = rows & ~took & evaluate(guard, env)
                    if hit.any():
                        mode[hit] = dst
                        took |= hit
            if not took.any():
                break
            moving = took
        return mode

    def reset(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Initial modes and clocks for initial states ``x (R, 2)`` (``q0 = x[:, 0]``)."""
        R = x.shape[0]
        t = np.zeros(R)
        mode = np.full(R, self.index(self.initial), dtype=np.int64)
        return self.jump(mode, self.env(x, x[:, 0], t, 0.0)), t

    def step(
        self, mode: np.ndarray, t: np.ndarray, x1: np.ndarray, q0: np.ndarray, tau1: float, dt: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One sample: ``(mode_k, t_k)`` and the new plant state ``x_k+1`` give
        ``(mode_k+1, t_k+1, r_k+1)``."""
        t1 = t + dt * self._clock[mode]  # type: ignore[attr-defined]
        env = self.env(x1, q0, t1, tau1)
        mode1 = self.jump(mode, env)
        return mode1, t1, self.reward(mode, mode1, env)

    def reward(self, mode: np.ndarray, mode1: np.ndarray, env: Mapping[str, Any]) -> np.ndarray:
        """The reward of the mode after the step, ``rho_delta'(x_k, u_k, x_k+1)``."""
        r = np.zeros(mode1.shape)
        stayed = mode == mode1
        for i in np.unique(mode1):
            rows = mode1 == i
            sub = {k: (v[rows] if np.ndim(v) else v) for k, v in env.items()}
            r[rows] = self.modes[i].reward.value(sub, stayed[rows])
        return r

    def trace(self, states: np.ndarray, dt: float) -> Trace:
        """Run the automaton along given trajectories ``states (R, N+1, 2)`` (or ``(N+1, 2)``);
        ``q0`` is each trajectory's first position."""
        states = np.asarray(states, dtype=float)
        if states.ndim == 2:
            states = states[None]
        R, N1, _ = states.shape
        modes = np.empty((R, N1), dtype=np.int64)
        clocks = np.empty((R, N1))
        rewards = np.empty((R, N1 - 1))
        q0 = states[:, 0, 0].copy()
        mode, t = self.reset(states[:, 0])
        modes[:, 0], clocks[:, 0] = mode, t
        for k in range(N1 - 1):
            mode, t, r = self.step(mode, t, states[:, k + 1], q0, (k + 1) * dt, dt)
            modes[:, k + 1], clocks[:, k + 1], rewards[:, k] = mode, t, r
        return Trace(modes, clocks, rewards, self.names)

    # ------------------------------------------------------------ printing
    def __str__(self) -> str:
        lines = [
            f"hybrid automaton: plant {self.plant_name or '-'}, set-point {_fmt(self.setpoint)}, "
            f"q0 in [{_fmt(self.q0_range[0])}, {_fmt(self.q0_range[1])}], horizon {_fmt(self.horizon)} s",
            "requirements: " + ", ".join(_req_text(r) for r in self.requirements),
            f"cases: {', '.join(self.cases)}",
            "memory z = (q0, t); t runs in: " + (", ".join(m.name for m in self.modes if m.clock) or "none"),
            "modes:",
        ]
        width = max(len(m.name) for m in self.modes)
        for m in self.modes:
            flags = " (permanent)" if m.permanent else ""
            lines.append(f"  {m.name:<{width}}  {_KIND[m.kind]}{flags}")
            lines.append(f"  {'':<{width}}    inv:    {m.invariant}")
            lines.append(f"  {'':<{width}}    reward: {m.reward}")
        lines.append("edges:")
        for e in self.edges:
            lines.append(f"  {e.src} -> {e.dst}  [{e.kind}]  {e.guard}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able data: modes, edges (guards as strings and trees), memory, rewards."""
        return {
            "kind": "hybrid_automaton",
            "spec": self.spec_path,
            "plant": self.plant_name,
            "setpoint": self.setpoint,
            "init": {"q0": list(self.q0_range), "qdot0": list(self.qdot0_range)},
            "horizon": self.horizon,
            "requirements": [
                {"name": r.name, "lo": r.lo, "hi": r.hi, "band": r.band} for r in self.requirements
            ],
            "cases": list(self.cases),
            "memory": {"vars": ["q0", "t"], "clock_runs_in": [m.name for m in self.modes if m.clock]},
            "initial": self.initial,
            "modes": [
                {
                    "name": m.name,
                    "kind": m.kind,
                    "criterion": m.criterion,
                    "permanent": m.permanent,
                    "clock": m.clock,
                    "invariant": str(m.invariant),
                    "invariant_tree": guard_to_dict(m.invariant),
                    "reward": str(m.reward),
                    "reward_terms": m.reward.to_dict(),
                    "doc": m.doc,
                }
                for m in self.modes
            ],
            "edges": [
                {"src": e.src, "dst": e.dst, "kind": e.kind, "guard": str(e.guard), "guard_tree": guard_to_dict(e.guard)}
                for e in self.edges
            ],
            "constants": {
                "idle_penalty": self.constants.idle_penalty,
                "error_weight": self.constants.error_weight,
                "stay_bonus": self.constants.stay_bonus,
                "penalty": self.constants.penalty,
            },
        }

    def to_json(self, indent: int = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    def to_digraph(self, title: str | None = None):
        """A :class:`graphviz.Digraph`: modes as rounded boxes coloured as in Figure 3-7
        (I green, E yellow, S blue, P red), edges labelled with their guards, a
        permanent mode drawn with a double, heavy border.  Writes nothing."""
        import graphviz

        reqs = ", ".join(_req_text(r) for r in self.requirements)
        g = graphviz.Digraph(
            "automaton",
            graph_attr={
                "rankdir": "LR",
                "fontname": "Helvetica",
                "label": title if title is not None else f"{reqs}   (set-point {_fmt(self.setpoint)})",
                "labelloc": "t",
                "fontsize": "16",
                "nodesep": "0.5",
                "ranksep": "0.9",
            },
        )
        g.attr("node", fontname="Helvetica", fontsize="10")
        g.attr("edge", fontname="Helvetica", fontsize="9", arrowsize="0.7")
        g.node("__init", label="", shape="point", width="0.12")
        for m in self.modes:
            fill, line = MODE_COLORS[m.kind]
            head = f"{m.name}: {_KIND[m.kind]}" + ("  (permanent)" if m.permanent else "")
            clock = "\\lt' = t + T_s" if m.clock else ""
            label = f"{head}\\linv: {_dot(m.invariant)}\\lr = {m.reward}{clock}\\l"
            attrs = {"shape": "box", "style": "rounded,filled", "fillcolor": fill, "color": line}
            if m.permanent and m.kind == "P":
                attrs.update(penwidth="3", peripheries="2")
            g.node(m.name, label=label, **attrs)
        g.edge("__init", self.initial)
        for e in self.edges:
            color = {"violation": "#b91c1c", "recovery": "#1d4ed8"}.get(e.kind, "#374151")
            style = "dashed" if e.kind == "recovery" else "solid"
            g.edge(e.src, e.dst, label=_dot(e.guard) + ("\\l" if isinstance(e.guard, AnyOf) and len(str(e.guard)) > 40 else ""), color=color, fontcolor=color, style=style)
        return g


MODE_COLORS = {
    "I": ("#dcfce7", "#15803d"),
    "E": ("#fef9c3", "#a16207"),
    "S": ("#dbeafe", "#1d4ed8"),
    "P": ("#fee2e2", "#b91c1c"),
}
"""Fill and line colour per mode kind: Figure 3-7's green, yellow, blue and red."""

_KIND = {"I": "idle", "E": "evaluating", "S": "stabilising", "P": "penalising"}


def _dot(g: Guard | str) -> str:
    """A guard for a Graphviz label: a long disjunction one alternative per line."""
    if isinstance(g, AnyOf) and len(str(g)) > 40:
        return " |\\l".join(_wrap(a) for a in g.args)
    return str(g)


def _max_const(g: Guard, var: str) -> float:
    if isinstance(g, Cmp):
        return g.rhs.const if g.var == var and not g.rhs.terms else 0.0
    return max((_max_const(a, var) for a in g.args), default=0.0)


def _req_text(r: Requirement) -> str:
    sym = {"overshoot": "M_p", "rise_time": "t_r", "settling_time": "t_s", "steady_state_error": "e_ss"}[r.name]
    if r.name == "rise_time":
        text = f"{sym} in [{_fmt(r.lo)}, {_fmt(r.hi)}]"
    else:
        text = f"{sym} <= {_fmt(r.hi)}"
    if r.name == "settling_time":
        text += f" (band {_fmt(r.band if r.band is not None else DEFAULT_SETTLING_BAND)})"
    return text


def render_bytes(h: HybridAutomaton, fmt: str) -> bytes:
    """The automaton drawn as ``svg`` or ``png`` bytes (needs the Graphviz ``dot`` binary)."""
    import graphviz

    try:
        return h.to_digraph().pipe(format=fmt)
    except graphviz.ExecutableNotFound:
        raise InputError(
            "the Graphviz 'dot' program is not installed, so the automaton cannot be drawn",
            file=f"--format {fmt}",
            hint="install it (Debian/Ubuntu: sudo apt-get install graphviz; macOS: brew install graphviz), "
            "or use --format dot and render elsewhere",
        ) from None


# ---------------------------------------------------------------- the compiler


class _Builder:
    """Guards of one spec, for the rising (``d = +1``) or falling (``d = -1``) case."""

    def __init__(self, setpoint: float, q0_lo: float, q0_hi: float) -> None:
        self.s = setpoint
        self.rising = q0_lo < setpoint
        self.falling = q0_hi >= setpoint
        self.cases = tuple(c for c, on in (("rising", self.rising), ("falling", self.falling)) if on)

    def thr(self, f: float) -> Lin:
        """The point with fraction ``f`` of the step still to go: ``s + f (q0 - s)``."""
        f = round(f, 12)
        terms = (("q0", f),) if f != 0 else ()
        return Lin(terms, round((1.0 - f) * self.s, 12) if f != 1 else 0.0)

    def past(self, f: float, d: int, strict: bool = True) -> Guard:
        """``q`` has passed ``thr(f)`` in the direction of the step."""
        op = (">" if strict else ">=") if d > 0 else ("<" if strict else "<=")
        return Cmp("q", op, self.thr(f))

    def before(self, f: float, d: int) -> Guard:
        """``q`` has not passed ``thr(f)`` (closed)."""
        return Cmp("q", "<=" if d > 0 else ">=", self.thr(f))

    def toward(self, d: int) -> Guard:
        return Cmp("qdot", ">" if d > 0 else "<", Lin())

    def reversed(self, d: int) -> Guard:
        return Cmp("qdot", "<" if d > 0 else ">", Lin())

    def cases_of(self, build: Callable[[int], Guard]) -> Guard:
        """``build(+1)`` for ``q0 < s`` and ``build(-1)`` for ``q0 >= s``, split on ``q0`` only
        when the initial range holds both and the two differ (Table B-1)."""
        if self.rising and self.falling:
            up, down = build(+1), build(-1)
            if up == down:
                return up
            s = Lin((), self.s)
            return any_of(all_of(Cmp("q0", "<", s), up), all_of(Cmp("q0", ">=", s), down))
        return build(+1 if self.rising else -1)


@dataclass(frozen=True)
class _Criterion:
    """What one criterion contributes (each a function of the direction ``d``)."""

    req: Requirement
    entry: Callable[[int], Guard]  # checkpoint from I when this E comes first
    invariant: Callable[[int, bool], Guard]  # (d, first) -> Inv(E)
    success: Callable[[int], Guard]
    failure: Callable[[int], Guard]
    hold: Callable[[int], Guard]  # must hold in every later mode (violation -> P)
    s_band: Callable[[int], Guard] | None  # contributes to Inv(S)
    target: Lin  # E's reward: -c |q - target|
    clock: bool = False
    doc: str = ""


def _criteria(spec: Spec, b: _Builder) -> list[_Criterion]:
    reqs = {r.name: r for r in spec.requirements}
    out: list[_Criterion] = []
    for name in ORDER:
        r = reqs.get(name)
        if r is None:
            continue
        if name == "rise_time":
            lo, hi = r.lo, r.hi
            t_lo, t_hi = Lin((), lo), Lin((), hi)
            out.append(
                _Criterion(
                    r,
                    entry=lambda d: b.past(F_RISE_START, d),
                    invariant=lambda d, first: all_of(
                        b.past(F_RISE_START, d), b.before(F_RISE_END, d), Cmp("t", "<=", t_hi)
                    ),
                    success=lambda d: all_of(b.past(F_RISE_END, d), Cmp("t", ">=", t_lo), Cmp("t", "<=", t_hi)),
                    failure=lambda d: any_of(
                        b.reversed(d), all_of(b.past(F_RISE_END, d), Cmp("t", "<", t_lo)), Cmp("t", ">", t_hi)
                    ),
                    hold=lambda d: TRUE,
                    s_band=None,
                    target=b.thr(F_RISE_END),
                    clock=True,
                    doc="Table B-3: from 10% to 90% of the step within [lo, hi] s of the mode clock, rising all the way",
                )
            )
        elif name == "overshoot":
            if r.lo > 0:
                raise _located(SpecError("overshoot takes an upper bound only ('require overshoot <= M_p')"), r)
            f_peak = -r.hi  # (3-1): q_peak = q_des + M_p (q_des - q0)
            out.append(
                _Criterion(
                    r,
                    entry=lambda d: b.past(F_NEAR, d),
                    invariant=lambda d, first: all_of(
                        b.past(F_NEAR if first else F_RISE_END, d), b.before(f_peak, d)
                    ),
                    success=lambda d: b.reversed(d),
                    failure=lambda d: b.past(f_peak, d),
                    hold=lambda d: b.before(f_peak, d),
                    s_band=lambda d: all_of(b.past(F_S_LOW, d, strict=False), b.before(f_peak, d)),
                    target=b.thr(0.0),
                    doc="Table B-1: from 95% of the step until the velocity turns, never past the peak (3-1)",
                )
            )
        elif name == "settling_time":
            if r.lo > 0:
                raise _located(SpecError("settling_time takes an upper bound only ('require settling_time <= t_s')"), r)
            band = r.band if r.band is not None else DEFAULT_SETTLING_BAND
            t_s = Lin((), r.hi)

            def in_band(d: int, band: float = band) -> Guard:
                return all_of(b.past(band, d, strict=False), b.before(-band, d))

            out.append(
                _Criterion(
                    r,
                    entry=lambda d, band=band: any_of(b.past(band, d, strict=False), Cmp("tau", ">=", t_s)),
                    invariant=lambda d, first: Cmp("tau", "<", t_s),
                    success=lambda d: all_of(Cmp("tau", ">=", t_s), in_band(d)),
                    failure=lambda d: all_of(Cmp("tau", ">=", t_s), negate(in_band(d))),
                    hold=in_band,
                    s_band=in_band,
                    target=b.thr(0.0),
                    doc="beyond the thesis: within the band (a fraction of the step) at tau = t_s "
                    "and ever after (the band joins Inv(S))",
                )
            )
        else:  # steady_state_error
            if r.lo > 0:
                raise _located(
                    SpecError("steady_state_error takes an upper bound only ('require steady_state_error <= e')"), r
                )
            lo_b, hi_b = Lin((), round(b.s - r.hi, 12)), Lin((), round(b.s + r.hi, 12))
            ess_band = all_of(Cmp("q", ">=", lo_b), Cmp("q", "<=", hi_b))
            out.append(
                _Criterion(
                    r,
                    entry=lambda d: b.past(F_NEAR, d),
                    invariant=lambda d, first: negate(ess_band),
                    success=lambda d: ess_band,
                    failure=lambda d: FALSE,
                    hold=lambda d: ess_band,
                    s_band=lambda d: ess_band,
                    target=b.thr(0.0),
                    doc="beyond the thesis: reach |q - q_des| <= e_ss (absolute) and stay there "
                    "(the band joins Inv(S)); the E mode has no violation of its own",
                )
            )
    return out


def _located(err: SpecError, r: Requirement) -> SpecError:
    if r.pos is not None:
        err.line, err.column = r.pos.line, r.pos.column
    return err


def compile_requirements(
    spec: Spec,
    constants: RewardConstants | None = None,
    permanent_penalty: bool | None = None,
) -> HybridAutomaton:
    """Compile a classical-performance spec into its hybrid automaton (appendix B).

    ``permanent_penalty``: ``None`` follows the thesis: P is permanent exactly when
    S has no band (rise time alone, (B-2)); with a band (overshoot, settling time,
    steady-state error) S and P are linked both ways (Tables B-1, B-5).  ``True``
    removes the way back from P.

    >>> from mitlc.spec.parse import parse_spec
    >>> h = compile_requirements(parse_spec('''
    ... plant mass-damper
    ... init q in [-1, 1], qdot = 0
    ... setpoint 0
    ... require overshoot <= 0'''))
    >>> print(h.edge("I", "E_Mp").guard)
    (q0 < 0 & q > 0.05*q0) | (q0 >= 0 & q < 0.05*q0)
    >>> print(h.edge("S", "P").guard)
    (q0 < 0 & (q < 0.1*q0 | q > 0)) | (q0 >= 0 & (q > 0.1*q0 | q < 0))
    """
    try:
        return _compile(spec, constants, permanent_penalty)
    except MitlError as exc:
        raise exc.located(spec.path, spec.source) from None


def _compile(spec: Spec, constants: RewardConstants | None, permanent_penalty: bool | None) -> HybridAutomaton:
    if not spec.requirements:
        raise SpecError("the spec has no 'require' statement: nothing to build a hybrid automaton from",
                        file=spec.path)
    plant = spec.plant
    if plant is not None and tuple(plant.state_names[:2]) != ("q", "qdot"):
        raise SpecError(
            f"classical criteria need a plant with position q and velocity qdot; '{plant.name}' has "
            f"{', '.join(plant.state_names)}",
            file=spec.path,
        )
    init = {r.var: (r.lo, r.hi) for r in spec.init}
    if "q" not in init:
        raise SpecError(
            "a classical-performance spec needs the initial positions: add 'init q in [a, b], qdot = 0'",
            file=spec.path,
        )
    q0_lo, q0_hi = init["q"]
    qdot0 = init.get("qdot", (0.0, 0.0))
    horizon = float(spec.horizon) if spec.horizon is not None else DEFAULT_HORIZON
    for r in spec.requirements:
        if r.name in ("rise_time", "settling_time") and r.hi >= horizon:
            raise _located(
                SpecError(
                    f"{r.name} bound {_fmt(r.hi)} s cannot be judged within the {_fmt(horizon)} s trial",
                    file=spec.path,
                    hint="raise 'horizon' or lower the bound",
                ),
                r,
            )
    c = constants or RewardConstants()
    s = float(spec.setpoint)
    b = _Builder(s, q0_lo, q0_hi)
    crits = _criteria(spec, b)

    e_names = [MODE_OF[cr.req.name] for cr in crits]
    bands = [cr.s_band for cr in crits if cr.s_band is not None]
    def band_of(d: int) -> Guard:
        return all_of(*(f(d) for f in bands))

    s_band: Guard | None = b.cases_of(band_of) if bands else None
    if permanent_penalty is None:
        permanent = s_band is None
    elif not permanent_penalty and s_band is None:
        raise SpecError(
            "P can only lead back to S when S has a band (overshoot, settling_time or steady_state_error)",
            file=spec.path,
        )
    else:
        permanent = bool(permanent_penalty)

    first_entry = b.cases_of(crits[0].entry)
    modes: list[Mode] = [
        Mode(
            "I",
            "I",
            invariant=b.cases_of(lambda d: negate(crits[0].entry(d))),
            reward=Reward((IfElse(b.cases_of(b.toward), 0.0, -c.idle_penalty),)),
            doc="Table 3-1 rho_1: no penalty while moving towards the set-point",
        )
    ]
    edges: list[Edge] = [Edge("I", e_names[0], first_entry, "checkpoint")]
    for i, cr in enumerate(crits):
        name = e_names[i]
        nxt = e_names[i + 1] if i + 1 < len(crits) else "S"
        earlier = crits[:i]
        modes.append(
            Mode(
                name,
                "E",
                invariant=b.cases_of(lambda d, cr=cr, i=i: cr.invariant(d, i == 0)),
                reward=Reward((AbsError(c.error_weight, cr.target),)),
                clock=cr.clock,
                criterion=cr.req.name,
                doc=cr.doc,
            )
        )
        violation = b.cases_of(
            lambda d, cr=cr, earlier=earlier: any_of(cr.failure(d), *(negate(e.hold(d)) for e in earlier))
        )
        if violation != FALSE:
            edges.append(Edge(name, "P", violation, "violation"))
        edges.append(Edge(name, nxt, b.cases_of(cr.success), "success"))
    modes.append(
        Mode(
            "S",
            "S",
            invariant=s_band if s_band is not None else TRUE,
            reward=Reward((AbsError(c.error_weight, b.thr(0.0)), StayBonus(c.stay_bonus))),
            permanent=s_band is None,
            doc="Table 3-1 rho_3: close to the set-point, +3 per step spent in S",
        )
    )
    modes.append(
        Mode(
            "P",
            "P",
            invariant=TRUE if permanent or s_band is None else b.cases_of(lambda d: negate(interior(band_of(d)))),
            reward=Reward((Const(-c.penalty),)),
            permanent=permanent,
            doc="Table 3-1 rho_4: the criterion was violated",
        )
    )
    if s_band is not None:
        edges.append(Edge("S", "P", b.cases_of(lambda d: negate(band_of(d))), "violation"))
        if not permanent:
            edges.append(Edge("P", "S", b.cases_of(lambda d: interior(band_of(d))), "recovery"))
    return HybridAutomaton(
        modes=tuple(modes),
        edges=tuple(edges),
        setpoint=s,
        q0_range=(q0_lo, q0_hi),
        qdot0_range=qdot0,
        horizon=horizon,
        requirements=tuple(sorted(spec.requirements, key=lambda r: ORDER.index(r.name))),
        constants=c,
        plant_name=spec.plant_name,
        cases=b.cases,
        spec_path=spec.path,
    )
