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

from collections.abc import Callable
from dataclasses import dataclass

from mitlc.errors import MitlError, SpecError
from mitlc.hybrid.automaton import Edge, HybridAutomaton, Mode
from mitlc.hybrid.criteria import DEFAULT_SETTLING_BAND
from mitlc.hybrid.guards import (
    FALSE,
    TRUE,
    Cmp,
    Guard,
    Lin,
    all_of,
    any_of,
    fmt_const,
    interior,
    negate,
)
from mitlc.hybrid.rewards import (
    AbsError,
    Const,
    IfElse,
    Reward,
    RewardConstants,
    StayBonus,
)
from mitlc.spec.model import Requirement, Spec

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


def _rise_time(r: Requirement, b: _Builder) -> _Criterion:
    """Rise time within ``[lo, hi]`` s (Table B-3)."""
    lo, hi = r.lo, r.hi
    t_lo, t_hi = Lin((), lo), Lin((), hi)
    return _Criterion(
        r,
        entry=lambda d: b.past(F_RISE_START, d),
        invariant=lambda d, first: all_of(b.past(F_RISE_START, d), b.before(F_RISE_END, d), Cmp("t", "<=", t_hi)),
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


def _overshoot(r: Requirement, b: _Builder) -> _Criterion:
    """Overshoot at most ``M_p`` (Table B-1)."""
    if r.lo > 0:
        raise _located(SpecError("overshoot takes an upper bound only ('require overshoot <= M_p')"), r)
    f_peak = -r.hi  # (3-1): q_peak = q_des + M_p (q_des - q0)
    return _Criterion(
        r,
        entry=lambda d: b.past(F_NEAR, d),
        invariant=lambda d, first: all_of(b.past(F_NEAR if first else F_RISE_END, d), b.before(f_peak, d)),
        success=lambda d: b.reversed(d),
        failure=lambda d: b.past(f_peak, d),
        hold=lambda d: b.before(f_peak, d),
        s_band=lambda d: all_of(b.past(F_S_LOW, d, strict=False), b.before(f_peak, d)),
        target=b.thr(0.0),
        doc="Table B-1: from 95% of the step until the velocity turns, never past the peak (3-1)",
    )


def _settling_time(r: Requirement, b: _Builder) -> _Criterion:
    """Settling time at most ``t_s`` within a band (beyond the thesis)."""
    if r.lo > 0:
        raise _located(SpecError("settling_time takes an upper bound only ('require settling_time <= t_s')"), r)
    band = r.band if r.band is not None else DEFAULT_SETTLING_BAND
    t_s = Lin((), r.hi)

    def in_band(d: int, band: float = band) -> Guard:
        return all_of(b.past(band, d, strict=False), b.before(-band, d))

    def entry(d: int, band: float = band) -> Guard:
        return any_of(b.past(band, d, strict=False), Cmp("tau", ">=", t_s))

    return _Criterion(
        r,
        entry=entry,
        invariant=lambda d, first: Cmp("tau", "<", t_s),
        success=lambda d: all_of(Cmp("tau", ">=", t_s), in_band(d)),
        failure=lambda d: all_of(Cmp("tau", ">=", t_s), negate(in_band(d))),
        hold=in_band,
        s_band=in_band,
        target=b.thr(0.0),
        doc="beyond the thesis: within the band (a fraction of the step) at tau = t_s "
        "and ever after (the band joins Inv(S))",
    )


def _steady_state_error(r: Requirement, b: _Builder) -> _Criterion:
    """Steady-state error at most ``e`` (beyond the thesis)."""
    if r.lo > 0:
        raise _located(SpecError("steady_state_error takes an upper bound only ('require steady_state_error <= e')"), r)
    lo_b, hi_b = Lin((), round(b.s - r.hi, 12)), Lin((), round(b.s + r.hi, 12))
    ess_band = all_of(Cmp("q", ">=", lo_b), Cmp("q", "<=", hi_b))
    return _Criterion(
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


_CRITERIA: dict[str, Callable[[Requirement, _Builder], _Criterion]] = {
    "rise_time": _rise_time,
    "overshoot": _overshoot,
    "settling_time": _settling_time,
    "steady_state_error": _steady_state_error,
}
"""The builder of each criterion's contribution."""


def _criteria(spec: Spec, b: _Builder) -> list[_Criterion]:
    reqs = {r.name: r for r in spec.requirements}
    return [_CRITERIA[name](reqs[name], b) for name in ORDER if name in reqs]


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
        raise SpecError("the spec has no 'require' statement: nothing to build a hybrid automaton from", file=spec.path)
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
                    f"{r.name} bound {fmt_const(r.hi)} s cannot be judged within the {fmt_const(horizon)} s trial",
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

        def invariant(d: int, cr: _Criterion = cr, i: int = i) -> Guard:
            return cr.invariant(d, i == 0)

        modes.append(
            Mode(
                name,
                "E",
                invariant=b.cases_of(invariant),
                reward=Reward((AbsError(c.error_weight, cr.target),)),
                clock=cr.clock,
                criterion=cr.req.name,
                doc=cr.doc,
            )
        )

        def violated(d: int, cr: _Criterion = cr, earlier: list[_Criterion] = earlier) -> Guard:
            return any_of(cr.failure(d), *(negate(e.hold(d)) for e in earlier))

        violation = b.cases_of(violated)
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
