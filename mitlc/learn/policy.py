"""Trained policies out of ``mitlc train``: load a directory and act, for SACPN and HyRL alike.

>>> import numpy as np, tempfile, pathlib
>>> from mitlc.spec.parse import parse_spec
>>> from mitlc.petri.compile import compile_spec
>>> from mitlc.learn.sacpn import Sacpn
>>> text = "plant pendulum(u_max = 3)\\ninit q = pi, qdot = 0\\nhorizon 3\\nprop k = abs(q) < 0.3\\n"
>>> spec = parse_spec(text + "formula F G k")
>>> agent = Sacpn(compile_spec(spec), runs=2, seed=1); _ = agent.train(2)
>>> tmp = tempfile.TemporaryDirectory(); d = pathlib.Path(tmp.name); agent.save(d / "params.npz")
>>> pol = load_policy(d)
>>> x = np.array([[np.pi, 0.0]])
>>> m = pol.reset(x)                 # the net's marking on x_0 (places: p_k, p_not_k)
>>> m.tolist(), pol.act(x, m).shape  # greedy input of run 0
([[0, 1]], (1,))
>>> m = pol.step(m, np.array([[3.0, -1.0]]))   # the net moves with the next state
>>> tmp.cleanup()
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import InputError
from mitlc.learn.checkpoint import check_against, damaged, read_meta, recorded_spec, restore_plant
from mitlc.spec.model import Spec

__all__ = ["Policy", "SacpnPolicy", "HyrlPolicy", "load_policy", "load_sacpn", "PARAMS"]

PARAMS = "params.npz"


class Policy:
    """A trained greedy controller with the net (or automaton) state it acts on.

    ``state = reset(x0)``, then per sample ``u = act(x, state)`` and
    ``state = step(state, x_next)``; rows of ``x`` are rollouts, row ``b`` uses the
    parameters of trained run ``b % runs``.  ``spec`` is the spec it was trained on.
    """

    spec: Spec
    runs: int
    dt: float

    def reset(self, x0: np.ndarray) -> Any:  # pragma: no cover - interface
        raise NotImplementedError

    def act(self, x: np.ndarray, state: Any) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def step(self, state: Any, x_next: np.ndarray) -> Any:  # pragma: no cover - interface
        raise NotImplementedError


class SacpnPolicy(Policy):
    """A SACPN policy: its state is the reward net's marking ``(B, places)``."""

    def __init__(self, agent: Any) -> None:
        self.agent = agent
        self.spec = agent.spec
        self.runs = agent.runs
        self.dt = agent.dt
        self.runtime = agent.runtime
        self.place_names = agent.rs.net.place_names
        self._k = 0

    def reset(self, x0: np.ndarray) -> np.ndarray:
        self._k = 0
        return self.runtime.reset(np.atleast_2d(np.asarray(x0, dtype=float)))

    def act(self, x: np.ndarray, state: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(np.asarray(x, dtype=float))
        code = self.runtime.encode(np.atleast_2d(state))
        run = np.arange(x.shape[0]) % self.runs
        return self.agent.policy(x, code, self.agent.xi[run])

    def step(self, state: np.ndarray, x_next: np.ndarray) -> np.ndarray:
        self._k += 1
        return self.runtime.step(
            np.atleast_2d(state), np.atleast_2d(np.asarray(x_next, dtype=float)), self._k * self.dt
        )


class HyrlPolicy(Policy):
    """A HyRL policy: its state is the automaton's ``(mode, t, q0)`` per row."""

    def __init__(self, learner: Any) -> None:
        self.learner = learner
        self.automaton = learner.automaton
        self.spec = learner.spec
        self.runs = learner.runs
        self.dt = float(learner.dt)
        self._k = 0

    def reset(self, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x0 = np.atleast_2d(np.asarray(x0, dtype=float))
        self._k = 0
        mode, t = self.automaton.reset(x0)
        return mode, t, x0[:, 0].copy()

    def act(self, x: np.ndarray, state: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
        x = np.atleast_2d(np.asarray(x, dtype=float))
        mode, t, q0 = state
        run = np.arange(x.shape[0]) % self.runs
        return self.learner.policy(x, q0, t, mode, self._k * self.dt, run)

    def step(self, state: tuple[np.ndarray, np.ndarray, np.ndarray], x_next: np.ndarray) -> Any:
        mode, t, q0 = state
        self._k += 1
        x_next = np.atleast_2d(np.asarray(x_next, dtype=float))
        mode1, t1, _ = self.automaton.step(mode, t, x_next, q0, self._k * self.dt, self.dt)
        return mode1, t1, q0


def load_sacpn(ckpt: str | Path, meta: dict[str, Any], spec: Spec | None = None) -> Any:
    """The :class:`~mitlc.learn.sacpn.Sacpn` a checkpoint holds (``meta``: its metadata), compiled with
    the options it was trained with, on ``spec`` (default: the spec it was trained on)."""
    from mitlc.learn.sacpn import Sacpn, SacpnSettings
    from mitlc.petri.compile import CompileOptions, compile_spec

    if spec is None:
        spec = recorded_spec(meta, ckpt)
    check_against(meta, spec, ckpt)
    options = CompileOptions.from_spec(
        spec,
        conjunction=meta.get("conjunction"),
        violations=meta.get("violations"),
        clock=meta.get("clock"),
        reward=meta.get("reward"),
    )
    try:
        settings = SacpnSettings.from_dict(meta["settings"])
    except (TypeError, ValueError, KeyError) as exc:
        raise damaged(ckpt, exc) from None
    agent = Sacpn(compile_spec(spec, options), settings, runs=int(meta["runs"]), seed=int(meta["seed"]))
    agent.load(ckpt)
    return agent


def load_policy(directory: str | Path) -> Policy:
    """The policy ``mitlc train --out DIRECTORY`` saved (its ``params.npz``), SACPN or HyRL.

    A plant from a plant file need not be registered: the folder's copy of the file is loaded
    (the code the training ran; a :class:`UserWarning` says when the original file differs now)."""
    if Path(directory).is_file() and Path(directory).suffix.lower() == ".zip":  # mitlc.gym, a later stage
        raise InputError(
            "a Stable-Baselines3 model: mitlc.gym.load_sb3(path, spec) loads it as a Policy", file=str(directory)
        )
    ckpt = Path(directory) / PARAMS
    if not ckpt.is_file() and (Path(directory) / "sac_000.zip").is_file():  # mitlc.gym, a later stage
        raise InputError(
            "a --learner sac training (Stable-Baselines3 models): mitlc.gym.load_policy(directory) loads it",
            file=str(directory),
        )
    if not ckpt.is_file() and (Path(directory) / "search.npz").is_file():
        from mitlc.learn.search import load_search

        return load_search(directory).policy()
    if not ckpt.is_file():
        raise InputError(f"no {PARAMS} in {directory} (train first with 'mitlc train --out DIR')", file=str(directory))
    meta = read_meta(ckpt)
    for note in restore_plant(meta, ckpt):
        warnings.warn(note, stacklevel=2)
    if meta.get("kind") == "hyrl":
        from mitlc.learn.hyrl import load_learner

        return HyrlPolicy(load_learner(ckpt))
    return SacpnPolicy(load_sacpn(ckpt, meta))
