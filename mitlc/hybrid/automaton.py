"""The hybrid automaton: modes with their rewards, guarded edges, the memory ``(q0, t)``,
stepping a batch of runs through it, JSON and Graphviz forms.

:func:`mitlc.hybrid.compile.compile_requirements` builds one from a spec's ``require`` lines.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mitlc.errors import InputError
from mitlc.fileio import json_text
from mitlc.hybrid.criteria import DEFAULT_SETTLING_BAND
from mitlc.hybrid.guards import (
    AnyOf,
    Cmp,
    Guard,
    evaluate,
    fmt_const,
    guard_to_dict,
    parenthesized,
    variables,
)
from mitlc.hybrid.rewards import Reward, RewardConstants
from mitlc.spec.model import Requirement

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
            f"hybrid automaton: plant {self.plant_name or '-'}, set-point {fmt_const(self.setpoint)}, "
            f"q0 in [{fmt_const(self.q0_range[0])}, {fmt_const(self.q0_range[1])}], "
            f"horizon {fmt_const(self.horizon)} s",
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
            "requirements": [{"name": r.name, "lo": r.lo, "hi": r.hi, "band": r.band} for r in self.requirements],
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
                {
                    "src": e.src,
                    "dst": e.dst,
                    "kind": e.kind,
                    "guard": str(e.guard),
                    "guard_tree": guard_to_dict(e.guard),
                }
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
        """Strict JSON (a non-finite number is null)."""
        return json_text(self.to_dict(), indent=indent).rstrip("\n")

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
                "label": title if title is not None else f"{reqs}   (set-point {fmt_const(self.setpoint)})",
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
            g.edge(
                e.src,
                e.dst,
                label=_dot(e.guard) + ("\\l" if isinstance(e.guard, AnyOf) and len(str(e.guard)) > 40 else ""),
                color=color,
                fontcolor=color,
                style=style,
            )
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
        return " |\\l".join(parenthesized(a) for a in g.args)
    return str(g)


def _max_const(g: Guard, var: str) -> float:
    if isinstance(g, Cmp):
        return g.rhs.const if g.var == var and not g.rhs.terms else 0.0
    return max((_max_const(a, var) for a in g.args), default=0.0)


def _req_text(r: Requirement) -> str:
    sym = {"overshoot": "M_p", "rise_time": "t_r", "settling_time": "t_s", "steady_state_error": "e_ss"}[r.name]
    if r.name == "rise_time":
        text = f"{sym} in [{fmt_const(r.lo)}, {fmt_const(r.hi)}]"
    else:
        text = f"{sym} <= {fmt_const(r.hi)}"
    if r.name == "settling_time":
        text += f" (band {fmt_const(r.band if r.band is not None else DEFAULT_SETTLING_BAND)})"
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
