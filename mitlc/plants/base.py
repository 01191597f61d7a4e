"""Plants: the dynamical systems a spec talks about.

A plant declares its state variables with their bounds (used by the compiler's
interval analysis and by the learner's features), which of them are angles
(periodic), its inputs with their boxes, its parameters with defaults, and a
vectorised ``step``.

Inputs: a plant that declares none has one, ``u``, in ``[-u_max, u_max]`` with
``u_max`` a parameter (so a spec may set it: ``plant pendulum(u_max = 10)``); a
plant with several (a unicycle's speed and turn rate) declares them as
:class:`InputVar` s, each with its own box. The learners and the integrators pass
``u`` as ``(R,)`` to a plant with one input and as ``(R, m)``, a column per
input in the declared order, to a plant with ``m > 1``.

To add a plant, build a :class:`Plant` and :func:`register` it (the shipped ones
are registered by :mod:`mitlc.plants`, one module each):

>>> import numpy as np
>>> import mitlc.plants
>>> p = PLANTS["pendulum"]
>>> p.state_names
('q', 'qdot')
>>> x = np.array([[-np.pi, 0.0]])         # hanging down, at rest
>>> np.allclose(p.step(x, np.zeros(1), p.params()), x)
True
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from mitlc.errors import InputError, MitlError

__all__ = [
    "StateVar",
    "InputVar",
    "Plant",
    "PLANTS",
    "register",
    "wrap_angle",
    "make_integrator",
    "Simulator",
    "OdeSimulator",
    "ode_dynamics",
    "rk4_kernel_step",
    "pairwise_sum",
    "pairwise_sum_for",
]


def wrap_angle(q: np.ndarray) -> np.ndarray:
    """Wrap angles to ``[-pi, pi)``.

    >>> float(wrap_angle(np.array(3 * np.pi / 2)))
    -1.5707963267948966
    """
    return (q + np.pi) % (2 * np.pi) - np.pi


def _real(v: object) -> bool:
    """A real number (``bool`` is not one here)."""
    return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool | np.bool_)


@dataclass(frozen=True)
class StateVar:
    """One state variable: its name, bounds, and whether it is an angle.

    Checked when built: a name, finite bounds with ``lo < hi``.

    >>> StateVar("v", 3.0, -3.0)
    Traceback (most recent call last):
    ...
    ValueError: state variable 'v': its bounds must be finite numbers with lo < hi, got [3, -3]
    """

    name: str
    lo: float
    hi: float
    periodic: bool = False
    grid: tuple[float, float] | None = None
    """Where a learner's feature grid lies when it should be narrower than ``[lo, hi]`` (the
    pendulum's velocity: its box, 15 pi, is far wider than any swing); ``None``: the box."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"a state variable's name must be a name such as 'x' or 'qdot', got {self.name!r}")
        if not (_real(self.lo) and _real(self.hi) and math.isfinite(self.lo) and math.isfinite(self.hi)) or not (
            self.lo < self.hi
        ):
            raise ValueError(
                f"state variable '{self.name}': its bounds must be finite numbers with lo < hi, "
                f"got [{_num(self.lo)}, {_num(self.hi)}]"
            )
        object.__setattr__(self, "lo", float(self.lo))
        object.__setattr__(self, "hi", float(self.hi))
        if self.grid is not None:
            g = tuple(self.grid)
            if not (len(g) == 2 and all(_real(b) and math.isfinite(b) for b in g) and g[0] < g[1]):
                raise ValueError(
                    f"state variable '{self.name}': its grid must be two finite numbers with lo < hi, got {self.grid!r}"
                )
            object.__setattr__(self, "grid", (float(g[0]), float(g[1])))


@dataclass(frozen=True)
class InputVar:
    """One input of a plant: its name and its box ``lo <= u <= hi``.

    The learners clip what they apply to the box and scale their exploration to its
    half-width; the box need not be symmetric. Checked when built: a name, finite bounds
    with ``lo < hi``.

    >>> InputVar("omega", -2, 2)
    InputVar(name='omega', lo=-2.0, hi=2.0)
    >>> InputVar("v", 1.0, 1.0)
    Traceback (most recent call last):
    ...
    ValueError: input 'v': its box must be finite numbers with lo < hi, got [1, 1]
    """

    name: str
    lo: float
    hi: float

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"an input's name must be a name such as 'v' or 'omega', got {self.name!r}")
        if not (_real(self.lo) and _real(self.hi) and math.isfinite(self.lo) and math.isfinite(self.hi)) or not (
            self.lo < self.hi
        ):
            raise ValueError(
                f"input '{self.name}': its box must be finite numbers with lo < hi, "
                f"got [{_num(self.lo)}, {_num(self.hi)}]"
            )
        object.__setattr__(self, "lo", float(self.lo))
        object.__setattr__(self, "hi", float(self.hi))


def _inputs_of(value: object, where: str) -> tuple[InputVar, ...]:
    """A plant's ``inputs`` as :class:`InputVar` s: each given as one or as ``(name, lo, hi)``;
    a ``ValueError`` naming the plant and the entry otherwise."""
    if isinstance(value, str | bytes) or not isinstance(value, Sequence):
        raise ValueError(f"{where}: inputs must be a sequence of InputVar (or (name, lo, hi)), got {value!r}")
    if not value:
        raise ValueError(
            f"{where}: inputs is empty: a plant needs at least one input "
            "(leave inputs out for one input u bounded by the parameter u_max)"
        )
    out = []
    for i, item in enumerate(value):
        if isinstance(item, InputVar):
            out.append(item)
            continue
        if isinstance(item, str | bytes) or not isinstance(item, Sequence) or len(item) != 3:
            got = f"{len(item)} entries" if isinstance(item, Sequence) and not isinstance(item, str) else repr(item)
            raise ValueError(f"{where}: input {i + 1} must be InputVar(name, lo, hi) or (name, lo, hi), got {got}")
        try:
            out.append(InputVar(*item))
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
    names = [v.name for v in out]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"{where}: input {', '.join(map(repr, twice))} is given twice")
    return tuple(out)


def _num(v: object) -> str:
    """A value for a message: numbers as ``%g``, anything else as its repr."""
    return f"{float(v):g}" if _real(v) else repr(v)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Plant:
    """A plant: state variables, inputs, parameters and a batched one-step map.

    ``dynamics(x, u, params) -> xdot`` works on arrays of shape ``(R, n)``, with ``u``
    ``(R,)`` for one input and ``(R, m)`` for ``m`` (:attr:`inputs`); :meth:`step`
    integrates it with RK4 over ``params['dt']``, clips the inputs to their boxes,
    wraps the angles and clips bounded velocities.
    """

    name: str
    state: tuple[StateVar, ...]
    defaults: Mapping[str, float]
    dynamics: Callable[[np.ndarray, np.ndarray, Mapping[str, float]], np.ndarray]
    description: str = ""
    default_spec: str | None = None
    clip: tuple[str, ...] = field(default=())
    fast_step: Callable[[Plant, Mapping[str, float]], Callable[[np.ndarray, np.ndarray], None]] | None = None
    """Optional: builds an in-place one-step map ``step(x, u)`` that agrees with
    :meth:`step` to rounding and is faster (the pendulum's fused RK4);
    :func:`make_integrator` uses it."""
    make_simulator: Callable[[Plant, Mapping[str, float], Mapping[str, tuple[float, float]]], Simulator] | None = None
    """Optional: builds the :class:`Simulator` trainers reset and step, for a plant that
    is stepped rather than integrated (a Gymnasium environment,
    :mod:`mitlc.plants.gym_env`); None: an :class:`OdeSimulator` of :meth:`step`."""

    kernel_step: Callable[[Plant, Mapping[str, float], Callable], tuple[Callable, np.ndarray, int]] | None = None
    """Optional: ``kernel_step(plant, params, jit) -> (step, consts, work)``, the one-step map
    of :func:`make_integrator` for *one* copy, as plain Python over scalars that numba can
    compile: ``step(x, u, consts, scratch)`` moves ``x (n,)`` in place, bit for bit as the
    batched step does (``scratch``: ``work`` floats). ``jit`` compiles the functions
    ``step`` calls (the identity when the fused SACPN kernel, :mod:`mitlc.learn.sacpn.kernel`,
    runs uncompiled). A plant without one trains on the numpy path.
    :func:`rk4_kernel_step` builds it from an ``ode``."""

    observation: tuple = ()
    """An environment plant's state lines (:class:`mitlc.plants.gym_env.ObsVar`: each state
    variable read off the flattened observation); empty for an ODE plant."""

    inputs: tuple[InputVar, ...] | None = None
    """The inputs, each with its box (:class:`InputVar`, or ``(name, lo, hi)``), in the order of
    ``u``'s columns; ``None`` (the default): one input ``u`` in ``[-u_max, u_max]``, ``u_max``
    a parameter (so ``defaults`` needs it and a spec may set it). ``dynamics`` gets ``u`` as
    ``(R,)`` with one input and ``(R, m)`` with several; a plant with inputs has no ``u_max``."""

    def __post_init__(self) -> None:
        """Refuse, when the plant is built, what would fail later (in a trainer, with a traceback)."""
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"a plant's name must be a non-empty string, got {self.name!r}")
        where = f"plant '{self.name}'"
        state = tuple(self.state) if isinstance(self.state, Sequence) and not isinstance(self.state, str) else None
        if not state or not all(isinstance(v, StateVar) for v in state):
            raise ValueError(f"{where}: state must be a non-empty sequence of StateVar, got {self.state!r}")
        names = [v.name for v in state]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"{where}: state variable {', '.join(map(repr, twice))} is given twice")
        object.__setattr__(self, "state", state)
        if not isinstance(self.defaults, Mapping):
            raise ValueError(f"{where}: defaults must be a mapping of parameter names to numbers")
        for k, v in self.defaults.items():
            if not isinstance(k, str) or not k.isidentifier():
                raise ValueError(f"{where}: parameter names must be names such as 'dt', got {k!r}")
            if not (_real(v) and math.isfinite(v)):
                raise ValueError(f"{where}: parameter '{k}' must be a finite number, got {_num(v)}")
        dt = self.defaults.get("dt")
        if dt is None or not dt > 0:
            got = "none" if dt is None else _num(dt)
            raise ValueError(f"{where}: parameter 'dt' (seconds per step) must be a positive number, got {got}")
        u_max = self.defaults.get("u_max")
        if self.inputs is not None:
            object.__setattr__(self, "inputs", _inputs_of(self.inputs, where))
            if u_max is not None:
                raise ValueError(
                    f"{where}: it declares its inputs ({', '.join(self.input_names)}), each with its box, and a "
                    "parameter 'u_max', which would bound nothing: drop u_max from defaults"
                )
        elif u_max is None and self.make_simulator is None:
            raise ValueError(f"{where}: parameter 'u_max' (the input bound, |u| <= u_max) is missing from defaults")
        if u_max is not None and not u_max >= 0:
            raise ValueError(
                f"{where}: parameter 'u_max' (the input bound, |u| <= u_max) must be 0 or more, got {_num(u_max)}"
            )
        if not callable(self.dynamics):
            raise ValueError(f"{where}: dynamics must be a function dynamics(x, u, params) -> xdot")
        unknown = [c for c in self.clip if c not in names]
        if unknown:
            raise ValueError(f"{where}: clip names {', '.join(map(repr, unknown))}, not among its state {names}")

    def _dynamics_fault(self, message: str, exc: BaseException | None = None) -> InputError:
        """``FILE:LINE: error: plant 'NAME': ...``: the user's dynamics failed (the file and line where,
        as far as Python knows where the function lives)."""
        code = getattr(self.dynamics, "__code__", None)
        file = code.co_filename if code is not None else None
        line = code.co_firstlineno if code is not None else None
        tb = exc.__traceback__ if exc is not None else None
        while tb is not None:  # the last line of the dynamics' file the error passed through
            if tb.tb_frame.f_code.co_filename == file:
                line = tb.tb_lineno
            tb = tb.tb_next
        return InputError(f"plant '{self.name}': {message}", file=file or f"plant '{self.name}'", line=line)

    def dynamics_checked(self, x: np.ndarray, u: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        """``dynamics(x, u, params)``, or one line naming the plant, its file and line: an exception
        in it, or a result that is not one row of ``n`` numbers per copy."""
        try:
            out = self.dynamics(x, u, params)
        except MitlError:
            raise
        except IndexError as exc:  # most often an input (or a state column) it does not have
            raise self._dynamics_fault(
                f"its dynamics raised IndexError: {exc} (is it reading an input it does not have? {self._u_shape()})",
                exc,
            ) from None
        except Exception as exc:  # the user's code: any failure is one line
            raise self._dynamics_fault(f"its dynamics raised {type(exc).__name__}: {exc}", exc) from None
        shape = getattr(out, "shape", None)
        if shape != x.shape or not isinstance(out, np.ndarray) or out.dtype.kind not in "fiu":
            what = (
                f"an array of shape {shape} and dtype {out.dtype}"
                if isinstance(out, np.ndarray)
                else f"a {type(out).__name__}"
            )
            raise self._dynamics_fault(
                f"its dynamics returned {what}; expected a float array of shape {x.shape} "
                f"(one row per copy, one column per state variable: {', '.join(self.state_names)})"
            )
        return out

    def _u_shape(self) -> str:
        """How ``dynamics`` gets ``u``, for a message."""
        if self.n_inputs == 1:
            return f"the plant has one input, {self.input_names[0]}: u is an array of shape (R,)"
        cols = ", ".join(f"u[:, {i}] = {n}" for i, n in enumerate(self.input_names))
        return f"the plant has {self.n_inputs} inputs: u is an array of shape (R, {self.n_inputs}), {cols}"

    @property
    def input_names(self) -> tuple[str, ...]:
        """The inputs' names, in the order of ``u``'s columns (``("u",)`` for a plant bounded by ``u_max``)."""
        return ("u",) if self.inputs is None else tuple(v.name for v in self.inputs)

    @property
    def n_inputs(self) -> int:
        """``m``, the number of inputs: ``u`` is ``(R,)`` when it is 1, ``(R, m)`` otherwise."""
        return 1 if self.inputs is None else len(self.inputs)

    def input_box(self, params: Mapping[str, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(lo, hi)``, each ``(m,)``: the inputs' boxes; for a plant without declared inputs
        ``[-u_max, u_max]`` with ``u_max`` from ``params`` (default: the plant's defaults).

        >>> import mitlc.plants
        >>> [b.tolist() for b in PLANTS["pendulum"].input_box({"u_max": 10.0})]
        [[-10.0], [10.0]]
        """
        if self.inputs is not None:
            return np.array([v.lo for v in self.inputs]), np.array([v.hi for v in self.inputs])
        p = self.defaults if params is None else params
        if "u_max" not in p:
            raise InputError(f"plant '{self.name}' has no input bound u_max")
        u_max = float(p["u_max"])
        return np.array([-u_max]), np.array([u_max])

    def check_inputs(self, params: Mapping[str, float]) -> None:
        """For a plant that declares its inputs: one step of one copy from the middle of the state
        bounds with every input at the middle of its box. A dynamics that reads an input it does not
        have (``u[:, 2]`` with two) fails here, as one line naming it, rather than silently in a
        compiled kernel (which checks no bounds). A plant bounded by ``u_max`` is stepped as before."""
        if self.stepped or self.inputs is None:
            return
        lo, hi = self.input_box(params)
        mid = 0.5 * (lo + hi)
        u = mid if self.n_inputs > 1 else mid[:1]
        x = np.array([[0.5 * (v.lo + v.hi) for v in self.state]])
        with np.errstate(all="ignore"):
            self.dynamics_checked(x, u[None, :] if self.n_inputs > 1 else u, params)

    @property
    def stepped(self) -> bool:
        """True for a plant that cannot be set to a state (an environment), only reset and stepped."""
        return self.make_simulator is not None

    def simulator(
        self, params: Mapping[str, float], init: Mapping[str, tuple[float, float]] | None = None
    ) -> Simulator:
        """``B`` copies of the plant to reset (starts drawn from ``init``) and step."""
        init = dict(init or {})
        if self.make_simulator is not None:
            return self.make_simulator(self, params, init)
        return OdeSimulator(self, params, init)

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.state)

    def var(self, name: str) -> StateVar:
        for v in self.state:
            if v.name == name:
                return v
        raise KeyError(name)

    def params(self, overrides: Mapping[str, float] | None = None) -> dict[str, float]:
        out = dict(self.defaults)
        out.update(overrides or {})
        return out

    def step(self, x: np.ndarray, u: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        """One sample period of RK4; ``x`` is ``(R, n)``, ``u`` is ``(R,)`` (one input) or ``(R, m)``,
        clipped to the inputs' boxes."""
        dt = params["dt"]
        if self.inputs is None:
            u = np.clip(u, -params["u_max"], params["u_max"])
        else:
            u = np.asarray(u, dtype=float)
            want = (x.shape[0],) if self.n_inputs == 1 else (x.shape[0], self.n_inputs)
            if u.shape != want:
                raise InputError(
                    f"plant '{self.name}': u has shape {u.shape}, expected {want} "
                    f"(inputs: {', '.join(self.input_names)})"
                )
            lo, hi = self.input_box(params)
            u = np.clip(u, lo, hi) if self.n_inputs > 1 else np.clip(u, lo[0], hi[0])
        f = self.dynamics_checked
        k1 = f(x, u, params)
        k2 = f(x + 0.5 * dt * k1, u, params)
        k3 = f(x + 0.5 * dt * k2, u, params)
        k4 = f(x + dt * k3, u, params)
        x = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        for i, v in enumerate(self.state):
            if v.periodic:
                x[:, i] = wrap_angle(x[:, i])
            elif v.name in self.clip:
                x[:, i] = np.clip(x[:, i], v.lo, v.hi)
        return x


def _pairwise_block(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of at most 128 entries: sequential below 8, else 8 accumulators."""
    if n < 8:
        s = a[lo]
        for i in range(1, n):
            s += a[lo + i]
        return s
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    end = n - n % 8
    while i < end:
        j = lo + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    s = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        s += a[lo + i]
        i += 1
    return s


@functools.cache
def pairwise_sum_for(jit: Callable[[Callable], Callable]) -> Callable[[np.ndarray, int, int], float]:
    """:func:`pairwise_sum` with it and its helper compiled by ``jit`` (numba's, in
    :mod:`mitlc.learn.sacpn.kernel`; the identity gives the plain-Python one). Kept per ``jit``."""
    block = jit(_pairwise_block)

    def pairwise_sum(a: np.ndarray, lo: int, n: int) -> float:
        """``a[lo : lo + n].sum()`` in the order numpy's ``add.reduce`` sums a contiguous run
        (pairwise: blocks of eight accumulators, halves above 128 summed left then right), as
        plain Python that numba compiles, so that compiled scalar code gives numpy's sums to
        the bit (tested). The halving is an explicit stack (numba compiles no recursion here)."""
        if n <= 128:
            return block(a, lo, n)
        tasks = np.empty((128, 3), dtype=np.int64)  # (lo, n, combine?)
        vals = np.empty(128)
        nt, nv = 1, 0
        tasks[0, 0], tasks[0, 1], tasks[0, 2] = lo, n, 0
        while nt > 0:
            nt -= 1
            t_lo, t_n, combine = tasks[nt, 0], tasks[nt, 1], tasks[nt, 2]
            if combine:
                nv -= 1
                vals[nv - 1] = vals[nv - 1] + vals[nv]
            elif t_n <= 128:
                vals[nv] = block(a, t_lo, t_n)
                nv += 1
            else:
                h = t_n // 2
                h -= h % 8
                tasks[nt, 0], tasks[nt, 1], tasks[nt, 2] = 0, 0, 1
                tasks[nt + 1, 0], tasks[nt + 1, 1], tasks[nt + 1, 2] = t_lo + h, t_n - h, 0
                tasks[nt + 2, 0], tasks[nt + 2, 1], tasks[nt + 2, 2] = t_lo, h, 0
                nt += 3
        return vals[0]

    return jit(pairwise_sum)


pairwise_sum = pairwise_sum_for(lambda f: f)


def ode_dynamics(
    ode: Callable, names: Sequence[str]
) -> Callable[[np.ndarray, np.ndarray, Mapping[str, float]], np.ndarray]:
    """The batched :attr:`Plant.dynamics` of a plain-Python ``ode(x, u, p, out)``.

    ``ode`` is the physics written once, over the state's *first* axis: ``x[i]`` is
    variable ``i`` (a scalar for one copy, a row of ``R`` values for a batch), ``p``
    the parameters in ``names`` order, and it writes ``xdot[i]`` into ``out[i]``. The
    input is ``u`` itself for a plant with one input, and ``u[j]`` is input ``j`` for a
    plant with several (the same first-axis rule). The batched dynamics calls it on rows;
    :func:`rk4_kernel_step` compiles it for one copy.
    """
    names = tuple(names)

    def dynamics(x: np.ndarray, u: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        values = [params[n] for n in names]
        if all(type(v) is float for v in values):  # the common case, four RK4 stages a step: no broadcasting
            p = np.array(values)
        else:  # a parameter may be a row of R values, one per copy (mitlc verify --vary): p[i] is then a row too
            p = np.array(np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in values)))
        out = np.empty((x.shape[1], x.shape[0]))
        ode(x.T, u.T, p, out)  # several inputs: u[j] is input j's row, as x[i] is variable i's
        return out.T

    return dynamics


PLANTS: dict[str, Plant] = {}


def register(plant: Plant) -> Plant:
    """Make ``plant`` available to specs (``plant NAME``) and the CLI."""
    PLANTS[plant.name] = plant
    return plant


def make_integrator(plant: Plant, params: Mapping[str, float]) -> Callable[[np.ndarray, np.ndarray], None]:
    """An in-place one-step map ``step(x, u)`` equal to ``plant.step`` (``u``: ``(R,)`` for one
    input, ``(R, m)`` for ``m``).

    A plant with a :attr:`Plant.fast_step` (the pendulum: a fused RK4 on the two
    state rows with the constants of (A-2) folded, about twice as fast, agreeing
    with :meth:`Plant.step` to rounding) gets that; any other plant uses
    :meth:`Plant.step`.
    """
    p = dict(params)
    if plant.fast_step is not None:
        return plant.fast_step(plant, p)

    def generic(x: np.ndarray, u: np.ndarray) -> None:
        x[...] = plant.step(x.copy(), u, p)

    return generic


def rk4_kernel_step(
    ode: Callable, names: Sequence[str]
) -> Callable[[Plant, Mapping[str, float], Callable], tuple[Callable, np.ndarray, int]]:
    """A :attr:`Plant.kernel_step` from the plant's ``ode`` (see :func:`ode_dynamics`): the
    RK4 of :meth:`Plant.step` for one copy, with its operations in the same order (so the
    same numbers to the bit, tested), then the same wraps and clips. The step takes ``u`` as
    a number for a plant with one input and as an array ``(m,)`` for one with several."""
    names = tuple(names)

    def build(plant: Plant, params: Mapping[str, float], jit: Callable) -> tuple[Callable, np.ndarray, int]:
        n, m = len(plant.state), plant.n_inputs
        f = jit(ode)
        # consts: dt, the inputs' lo (m) and hi (m), per variable (kind, lo, hi) with kind
        # 1 = angle, 2 = clipped, then p
        kinds = [1.0 if v.periodic else 2.0 if v.name in plant.clip else 0.0 for v in plant.state]
        rows = [[k, v.lo, v.hi] for k, v in zip(kinds, plant.state, strict=True)]
        lo, hi = plant.input_box(params)
        consts = np.array(
            [float(params["dt"]), *lo.tolist(), *hi.tolist()]
            + [c for row in rows for c in row]
            + [float(params[name]) for name in names]
        )
        at = 1 + 2 * m  # where the rows start

        def rk4(x: np.ndarray, u: Any, c: np.ndarray, w: np.ndarray) -> None:
            dt = c[0]
            p = c[at + 3 * n :]
            k1, k2, k3, k4, y = w[0:n], w[n : 2 * n], w[2 * n : 3 * n], w[3 * n : 4 * n], w[4 * n : 5 * n]
            f(x, u, p, k1)
            for i in range(n):
                y[i] = x[i] + 0.5 * dt * k1[i]
            f(y, u, p, k2)
            for i in range(n):
                y[i] = x[i] + 0.5 * dt * k2[i]
            f(y, u, p, k3)
            for i in range(n):
                y[i] = x[i] + dt * k3[i]
            f(y, u, p, k4)
            for i in range(n):
                x[i] = x[i] + dt / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i])
            for i in range(n):
                kind = c[at + 3 * i]
                if kind == 1.0:
                    x[i] = (x[i] + np.pi) % (2 * np.pi) - np.pi
                elif kind == 2.0:
                    x[i] = np.minimum(np.maximum(x[i], c[at + 1 + 3 * i]), c[at + 2 + 3 * i])

        rk4_j = jit(rk4)

        def step(x: np.ndarray, u: float, c: np.ndarray, w: np.ndarray) -> None:
            """One input: ``u`` a number, clipped to its box (np.clip's order)."""
            rk4_j(x, np.minimum(np.maximum(u, c[1]), c[2]), c, w)

        def step_inputs(x: np.ndarray, u: np.ndarray, c: np.ndarray, w: np.ndarray) -> None:
            """Several inputs: ``u (m,)``, each clipped to its box into the scratch's last ``m``."""
            v = w[5 * n : 5 * n + m]
            for j in range(m):
                v[j] = np.minimum(np.maximum(u[j], c[1 + j]), c[1 + m + j])
            rk4_j(x, v, c, w)

        if m == 1:
            return jit(step), consts, 5 * n
        return jit(step_inputs), consts, 5 * n + m

    return build


class Simulator(Protocol):
    """What a trainer resets and steps: ``B`` copies of a plant in lock-step.

    ``reset(rngs)`` returns one start per generator, ``(B, n)``, drawn from copy
    ``b``'s own ``rngs[b]``; ``step(x, u)`` applies ``u (B,)`` (``(B, m)`` for a plant
    with ``m`` inputs) and writes the next states into ``x`` in place. ``settable`` says whether a rollout may start
    anywhere (an ODE plant) or only where the last reset left the copies
    (:meth:`start` checks it).
    """

    settable: bool

    def reset(self, rngs: Sequence[np.random.Generator]) -> np.ndarray: ...

    def step(self, x: np.ndarray, u: np.ndarray) -> None: ...

    def start(self, x0: np.ndarray) -> None: ...


class OdeSimulator:
    """An ODE plant's copies: starts uniform in the ``init`` ranges (0 where none is
    given; angles wrapped), steps by :func:`make_integrator`."""

    settable = True

    def __init__(self, plant: Plant, params: Mapping[str, float], init: Mapping[str, tuple[float, float]]) -> None:
        self.plant = plant
        self.ranges = [init.get(v, (0.0, 0.0)) for v in plant.state_names]
        plant.check_inputs(params)  # a dynamics reading an input it does not have: one line, now
        self.step = make_integrator(plant, params)

    def reset(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        x = np.empty((len(rngs), len(self.ranges)))
        for r, g in enumerate(rngs):
            for i, (lo, hi) in enumerate(self.ranges):
                x[r, i] = g.uniform(lo, hi)
        for i, v in enumerate(self.plant.state):
            if v.periodic:
                x[:, i] = (x[:, i] + np.pi) % (2 * np.pi) - np.pi
        return x

    def start(self, x0: np.ndarray) -> None:
        """Any state will do."""
