"""What a :mod:`mitlc.gym` environment observes: the spec's state read off the environment's
observation, and the marking and the obligations' clocks shown beside it.

The spec's state variables are read off each observation by ``observe``: a function
``obs -> {variable: value}`` such as :func:`pendulum_v1_state`, or a dict mapping each
variable to an index into the flattened observation or to a function ``obs -> float``
(:func:`state_reader` checks it and builds the reader). :func:`token_bounds`,
:func:`n_clocks` and :func:`clock_high` size the marking and clock entries of the
observation space; :func:`plant_observation` lays out what :class:`mitlc.gym.MitlPlantEnv`
observes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from mitlc.errors import InputError
from mitlc.petri.compile import RewardSystem
from mitlc.plants.base import wrap_angle

Observe = Callable[[Any], Mapping[str, float]] | Mapping[str, int | Callable[[Any], float]]
"""How to read the spec's state variables off an observation."""

MARKING_OBS = ("dict", "box")
"""How the marking joins the observation: a ``Dict`` space or one flat ``Box``."""

_SCALARS = (float, int, np.floating, np.integer)
_FLOAT_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))
_TWO_PI = 2 * np.pi


def pendulum_v1_state(obs: Any) -> dict[str, Any]:
    """Gymnasium ``Pendulum-v1`` observation ``[cos th, sin th, thdot]`` -> ``{"q", "qdot"}``.

    Gymnasium's ``theta = 0`` is upright and positive ``thdot`` increases theta,
    as for the spec's pendulum (``q`` from upright).  ``q = atan2(sin, cos)``
    wrapped to ``[-pi, pi)``.  Works on one observation or a batch ``(..., 3)``.

    >>> pendulum_v1_state(np.array([-1.0, 0.0, 0.5], dtype=np.float32))
    {'q': -3.141592653589793, 'qdot': 0.5}
    >>> pendulum_v1_state(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -2.0]]))["q"].round(4)
    array([0.    , 1.5708])
    """
    one = _pendulum_v1_one(obs)
    if one is not None:
        return {"q": one[0], "qdot": one[1]}
    o = np.asarray(obs, dtype=float)
    if o.shape[-1:] != (3,):
        raise InputError(f"a Pendulum-v1 observation has 3 entries [cos th, sin th, thdot], got shape {o.shape}")
    if o.ndim == 1:  # one observation: floats, the same numbers (wrap_angle's operations on a float)
        q = float(np.arctan2(o[1], o[0]))
        return {"q": (q + math.pi) % _TWO_PI - math.pi, "qdot": float(o[2])}
    return {"q": np.asarray(wrap_angle(np.arctan2(o[..., 1], o[..., 0]))), "qdot": o[..., 2]}


def _pendulum_v1_one(obs: Any) -> tuple[float, float] | None:
    """``(q, qdot)`` of one float ``Pendulum-v1`` observation as :func:`pendulum_v1_state` gives them,
    on Python floats; None for anything else (a batch, another dtype or shape: the general path)."""
    if type(obs) is not np.ndarray or obs.shape != (3,) or obs.dtype not in _FLOAT_DTYPES:
        return None
    c, s, thdot = obs.tolist()  # float32 -> the float64 numbers np.asarray(obs, dtype=float) holds
    q = float(np.arctan2(s, c))  # numpy's arctan2 on float64 (math.atan2 differs in the last bit)
    return (q + math.pi) % _TWO_PI - math.pi, thdot


def spec_observe(plant: Any, base: spaces.Space) -> Callable[[Any], dict[str, float]]:
    """A gym plant's ``state`` lines as an ``observe`` function of one observation."""
    cols = plant.observation

    def observe(obs: Any) -> dict[str, float]:
        flat = np.asarray(spaces.flatten(base, obs), dtype=float).reshape(1, -1)
        return {o.var.name: float(np.asarray(o.read(flat)).reshape(-1)[0]) for o in cols}

    return observe


def _call_getter(f: Callable[[Any], float]) -> Callable[[Any, np.ndarray], float]:
    """A state variable read by a user function of the observation."""
    return lambda obs, flat: float(np.asarray(f(obs), dtype=float))


def _index_getter(i: int) -> Callable[[Any, np.ndarray], float]:
    """A state variable read at index ``i`` of the flattened observation."""
    return lambda obs, flat: float(flat[i])


def state_reader(
    observe: Observe, base: spaces.Space, names: Sequence[str], needed: Sequence[str], periodic: np.ndarray
) -> Callable[[Any], list[float]]:
    """The reader of the spec's state off one observation of the space ``base``: ``observe``
    checked against the state variables ``names`` (those the propositions read, ``needed``, must
    be given), giving a list of floats in ``names`` order, every needed value finite and the
    ``periodic`` ones (a bool per variable) wrapped to ``[-pi, pi)``."""
    column = {n: i for i, n in enumerate(names)}
    if callable(observe) and not isinstance(observe, Mapping):
        fn = observe

        seen: list[Any] = [None]  # the last key set found good: later samples check it in one comparison

        def read(obs: Any) -> list[float]:
            values = fn(obs)
            if type(values) is not dict and not isinstance(values, Mapping):
                raise InputError(
                    f"observe() must return a mapping from state variable to value, got {type(values).__name__}"
                )
            if values.keys() != seen[0]:
                missing = [n for n in needed if n not in values]
                if missing:
                    raise InputError(
                        f"observe() gave no value for state variable '{missing[0]}' "
                        f"(the propositions read {', '.join(needed)})"
                    )
                for key in values:
                    if key not in column:
                        raise InputError(
                            f"observe() gave '{key}', which is not a state variable of the spec ({', '.join(names)})"
                        )
                seen[0] = frozenset(values)
            x = [math.nan] * len(names)
            for key, v in values.items():
                if type(v) is not float:
                    v = float(v) if isinstance(v, _SCALARS) else float(np.asarray(v, dtype=float))
                x[column[key]] = v
            return x

    elif isinstance(observe, Mapping):
        unknown = [k for k in observe if k not in column]
        if unknown:
            raise InputError(
                f"observe maps '{unknown[0]}', which is not a state variable of the spec ({', '.join(names)})"
            )
        missing = [n for n in needed if n not in observe]
        if missing:
            raise InputError(
                f"observe gives no value for state variable '{missing[0]}' (the propositions read {', '.join(needed)})"
            )
        try:
            size: int | None = spaces.flatdim(base)
        except (NotImplementedError, ValueError, TypeError):
            size = None
        getters: list[tuple[int, Callable[[Any, np.ndarray], float]]] = []
        for key, how in observe.items():
            if callable(how):
                getters.append((column[key], _call_getter(how)))
            elif isinstance(how, (int, np.integer)) and not isinstance(how, bool):
                i = int(how)
                if size is not None and not -size <= i < size:
                    raise InputError(
                        f"observe maps '{key}' to index {i}, outside the flattened observation of size {size}"
                    )
                getters.append((column[key], _index_getter(i)))
            else:
                raise InputError(f"observe maps '{key}' to {how!r}: expected an index or a function obs -> value")
        needs_flat = any(isinstance(h, (int, np.integer)) for h in observe.values())

        def read(obs: Any) -> list[float]:
            flat = np.asarray(spaces.flatten(base, obs), dtype=float).reshape(-1) if needs_flat else np.empty(0)
            x = [math.nan] * len(names)
            for col, get in getters:
                x[col] = float(get(obs, flat))
            return x

    else:
        raise InputError(f"observe must be a function or a mapping, got {type(observe).__name__}")

    checks = [(n, column[n]) for n in needed]
    angles = [i for i, n in enumerate(names) if periodic[i]]

    def checked(obs: Any) -> list[float]:
        x = read(obs)
        for n, i in checks:
            if not math.isfinite(x[i]):
                raise InputError(f"observe gave a non-finite value for '{n}': {x[i]}")
        for i in angles:  # wrap_angle's operations on one float (Python's % is numpy's remainder)
            x[i] = (x[i] + math.pi) % _TWO_PI - math.pi
        return x

    if observe is pendulum_v1_state and "q" in column and "qdot" in column and set(needed) <= {"q", "qdot"}:
        # the dict it would give has good keys: its two floats straight into their columns, then checked
        iq, iw, width = column["q"], column["qdot"], len(names)
        # numpy's arctan2 on arrays of one, kept by this reader: the same loop and numbers as on two
        # floats, without making arrays of them every sample (0.5 us of the reader's 1.5)
        sin1, cos1, q1 = np.empty(1), np.empty(1), np.empty(1)
        arctan2 = np.arctan2

        def checked_pendulum(obs: Any) -> list[float]:
            if type(obs) is not np.ndarray or obs.shape != (3,) or obs.dtype not in _FLOAT_DTYPES:
                return checked(obs)  # a batch, another dtype: the general path
            c, sin1[0], thdot = obs.tolist()
            cos1[0] = c
            arctan2(sin1, cos1, out=q1)
            x = [math.nan] * width
            x[iq] = (q1.item() + math.pi) % _TWO_PI - math.pi
            x[iw] = thdot
            for n, i in checks:
                if not math.isfinite(x[i]):
                    raise InputError(f"observe gave a non-finite value for '{n}': {x[i]}")
            for i in angles:
                x[i] = (x[i] + math.pi) % _TWO_PI - math.pi
            return x

        return checked_pendulum
    return checked


def token_bounds(rs: RewardSystem) -> np.ndarray:
    """Most tokens each place can hold: 1, or inf for a counting place (``violations = counted``).

    >>> from mitlc.spec.parse import parse_spec
    >>> from mitlc.petri.compile import CompileOptions, compile_spec
    >>> spec = parse_spec("plant pendulum\\nhorizon 3\\nprop a = q < 1\\nformula G a")
    >>> token_bounds(compile_spec(spec, CompileOptions(violations="counted")))
    array([ 1.,  1.,  1.,  1., inf])
    """
    bounds = np.ones(len(rs.net.places))
    bounds[list(rs.net.counters)] = np.inf
    return bounds


def n_clocks(rs: RewardSystem) -> int:
    """The live obligations' clocks an observation shows: one per timed obligation sub-net."""
    return sum(len(tn.subnets) for tn in rs.timed)


def clock_high(rs: RewardSystem) -> np.ndarray:
    """The most each clock can show ``(clocks,)``: the horizon over its interval's upper end (1 when
    unbounded), inf without a horizon."""
    high = np.full(n_clocks(rs), np.inf, np.float32)
    if rs.timed and rs.spec.horizon is not None:
        h = float(rs.spec.horizon)
        his = [tn.tree.nodes[node].interval.hi for tn in rs.timed for node, _ in tn.subnets]
        high[:] = [h / hi if math.isfinite(hi) and hi > 0 else 1.0 for hi in his]
    return high


def plant_observation(x: np.ndarray, marking: np.ndarray, clocks: np.ndarray, marking_obs: str) -> Any:
    """What :class:`mitlc.gym.MitlPlantEnv` observes, for a batch: states ``x`` ``(B, n)``, markings ``(B, places)``
    and clocks ``(B, clocks)`` as ``{"obs", "marking"[, "clocks"]}`` of ``(B, ...)`` arrays, or one
    ``(B, n + places + clocks)`` float32 array with ``marking_obs="box"``. In the ``Dict`` an int8
    marking (one-token places) stays int8, any other becomes float32.

    >>> o = plant_observation(np.array([[0.5, -1.0]]), np.array([[0, 1]]), np.zeros((1, 0)), "box")
    >>> o.tolist(), o.dtype
    ([[0.5, -1.0, 0.0, 1.0]], dtype('float32'))
    """
    x = np.asarray(x, dtype=np.float32)
    marking = np.asarray(marking)
    clocks = np.asarray(clocks, dtype=np.float32)
    if marking_obs == "box":
        return np.concatenate([x, marking.astype(np.float32), clocks], axis=1)
    out: dict[str, np.ndarray] = {
        "obs": x,
        "marking": marking if marking.dtype == np.int8 else marking.astype(np.float32),
    }
    if clocks.shape[1]:
        out["clocks"] = clocks
    return out
