"""Stable-Baselines3's SAC on a spec's plant, run by run: ``mitlc train --learner sac``.

SACPN learns a linear policy over a grid of Gaussians per region of the net; some tasks need
more than that (a cart-pole kept upright while it moves, docs/suite.md). :class:`SacRuns` trains
``runs`` independent SAC models (Stable-Baselines3, two-layer networks) on
:class:`~mitlc.gym.MitlPlantEnv` of the same compiled reward system (its ``--reward``,
``--violations`` and ``--clock`` options included), observing the plant's state, the net's
marking and its obligations' clocks in one flat vector. Run ``r`` is seeded from ``(seed, r)``;
each model is judged, as a SACPN run is, by the monitor on its greedy rollout from its own
evaluation start drawn from the spec's ``init`` box.

A *trial* is one episode of the spec's horizon, as for SACPN; SAC needs far fewer of them (and
each costs far more: a gradient step per sample), so :func:`default_trials` gives about
:data:`SAC_STEPS` samples per run.

Stable-Baselines3 and PyTorch are imported when a training starts or a model is loaded:
``pip install 'mitlc[sb3]'``.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import InputError, TrainingError
from mitlc.gym.sb3 import SB3_EXTRA, Sb3Policy, plant_episode
from mitlc.learn.policy import Policy
from mitlc.learn.sacpn.sacpn import default_gamma
from mitlc.petri.compile import RewardSystem

__all__ = [
    "SacSettings",
    "SacRuns",
    "SacRunsPolicy",
    "SAC_STEPS",
    "default_trials",
    "model_name",
    "load_policy",
    "load_sac_runs",
]

SAC_STEPS = 20_000
"""Samples per run that :func:`default_trials` aims at: on ``cartpole_lean_response`` one SAC model
after 20,000 samples satisfies the spec from 74 % of 50 fresh starts (SACPN: 0 %)."""


def default_trials(n_steps: int) -> int:
    """Trials (episodes of ``n_steps`` samples) per run for about :data:`SAC_STEPS` samples."""
    return max(1, math.ceil(SAC_STEPS / max(1, n_steps)))


def model_name(run: int) -> str:
    """The file of run ``run``'s model in a training folder."""
    return f"sac_{run:03d}.zip"


@dataclass(frozen=True)
class SacSettings:
    """SAC's settings (``mitlc train --learner sac --set NAME=VALUE``); the rest are SB3's defaults."""

    gamma: float | None = None
    """Discount; None: ``1 - 3 / N`` for a trial of ``N`` steps, as SACPN's default."""
    learning_rate: float = 3e-4
    batch_size: int = 256
    buffer_size: int = 100_000
    """Replay buffer; at most the run's samples are kept (one run's buffer lives at a time)."""
    learning_starts: int = 1000
    """Random-action samples before the first gradient step."""
    net: tuple[int, ...] = (256, 256)
    """Hidden layers of the actor and of each critic (``--set net=64x64``)."""

    def check(self) -> None:
        if self.gamma is not None and not 0.0 < self.gamma < 1.0:
            raise TrainingError(f"gamma must be in (0, 1), got {self.gamma}")
        if not 0.0 < self.learning_rate <= 1.0:
            raise TrainingError(f"learning_rate must be in (0, 1], got {self.learning_rate}")
        for name in ("batch_size", "buffer_size"):
            if getattr(self, name) < 1:
                raise TrainingError(f"{name} must be at least 1, got {getattr(self, name)}")
        if self.learning_starts < 0:
            raise TrainingError(f"learning_starts must be at least 0, got {self.learning_starts}")
        if not self.net or any(n < 1 or n > 4096 for n in self.net):
            raise TrainingError(f"net must be 1 to 4096 units per layer, got {'x'.join(map(str, self.net))}")

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["net"] = list(self.net)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SacSettings:
        known = {f.name for f in dataclasses.fields(cls)}
        values = {k: v for k, v in d.items() if k in known}
        if "net" in values:
            values["net"] = tuple(int(n) for n in values["net"])
        return cls(**values)


def _sb3() -> Any:
    try:
        import stable_baselines3
    except ImportError:
        raise InputError(
            f"--learner sac trains Stable-Baselines3's SAC, which is not installed: {SB3_EXTRA}", file="--learner"
        ) from None
    return stable_baselines3


def _run_seed(seed: int, run: int) -> int:
    return int(np.random.SeedSequence([seed, run]).generate_state(1)[0])


class SacRuns:
    """``runs`` independent SAC models on the plant of ``rs``'s spec (see the module's text).

    ``returns`` ``(runs, trials)``: each episode's compiled return, as SACPN's; ``models``: one per
    run once trained (or loaded). :meth:`rollout` rolls row ``b`` out with run ``b % runs``.
    """

    def __init__(self, rs: RewardSystem, runs: int, seed: int, settings: SacSettings | None = None) -> None:
        s = rs.spec
        ep = plant_episode(
            s,
            "--learner sac trains on mitlc's own plants; train SAC on a Gymnasium environment through "
            "mitlc.gym.MitlRewardWrapper (docs/gymnasium.md)",
            "the episodes' length",
        )
        self.settings = settings or SacSettings()
        self.settings.check()
        self.rs, self.spec, self.runs, self.seed = rs, s, int(runs), int(seed)
        self.plant, self.params, self.dt, self.n_steps = ep.plant, ep.params, ep.dt, ep.n_steps
        self.gamma = self.settings.gamma if self.settings.gamma is not None else default_gamma(self.n_steps)
        self.init_ranges = ep.init_ranges
        self.models: list[Any] = []
        self.returns = np.zeros((self.runs, 0))
        self.trial = 0
        self._members: list[Sb3Policy] = []

    # ------------------------------------------------------------------ training
    def _env(self) -> Any:
        from mitlc.gym.envs import MitlPlantEnv

        return MitlPlantEnv(self.rs, plant=self.spec.plant_name or "", marking_obs="box", verdict="off")

    def train(self, trials: int, progress: Callable[[int, int], None] | None = None) -> None:
        """Train every run for ``trials`` episodes, one run after another; ``progress(done, total)``
        after each episode (episodes of all runs). Stops on a non-finite network output or return."""
        sb3 = _sb3()
        import torch

        threads = torch.get_num_threads()
        torch.set_num_threads(1)  # small networks: one thread is fastest, and the same bits on any machine
        try:
            total = self.runs * trials
            returns = np.full((self.runs, trials), np.nan)
            models = []
            for r in range(self.runs):

                def done(k: int, r: int = r) -> None:
                    if progress is not None:
                        progress(r * trials + k, total)

                models.append(self._learn(sb3, r, trials, returns[r], done))
        finally:
            torch.set_num_threads(threads)
        self.models, self.returns, self.trial = models, returns, trials
        self._members = [Sb3Policy(m, self.rs) for m in models]

    def _learn(self, sb3: Any, run: int, trials: int, out: np.ndarray, progress: Callable[[int], None]) -> Any:
        from stable_baselines3.common.callbacks import BaseCallback

        st = self.settings
        steps = trials * self.n_steps
        env = self._env()
        seed = _run_seed(self.seed, run)
        model = sb3.SAC(
            "MlpPolicy",
            env,
            learning_rate=st.learning_rate,
            buffer_size=max(1, min(st.buffer_size, steps)),
            learning_starts=min(st.learning_starts, steps),
            batch_size=st.batch_size,
            gamma=self.gamma,
            policy_kwargs={"net_arch": list(st.net)},
            seed=seed,
            device="cpu",
            verbose=0,
        )
        spec_path = self.spec.path

        class Episodes(BaseCallback):
            def __init__(self) -> None:
                super().__init__()
                self.k, self.ret = 0, 0.0

            def _on_step(self) -> bool:
                reward = float(self.locals["rewards"][0])
                if not math.isfinite(reward):
                    raise TrainingError(f"run {run}: a non-finite reward at episode {self.k}", file=spec_path)
                self.ret += reward
                if self.locals["dones"][0]:
                    if self.k < len(out):
                        out[self.k] = self.ret
                    self.k += 1
                    self.ret = 0.0
                    progress(self.k)
                return True

        model.learn(total_timesteps=steps, callback=Episodes())
        model.replay_buffer = None  # up to buffer_size samples: not kept past the run
        return model

    # ------------------------------------------------------------------ judging
    def evaluation_states(self) -> np.ndarray:
        """One initial state per run, drawn from the ``init`` box by run ``r``'s evaluation stream ``(seed, r, 1)``."""
        x0 = np.empty((self.runs, len(self.init_ranges)))
        for r in range(self.runs):
            rng = np.random.default_rng([self.seed, r, 1])
            x0[r] = [rng.uniform(lo, hi) for lo, hi in self.init_ranges]
        return x0

    @property
    def runtime(self) -> Any:
        return self._member(0).runtime

    def _member(self, r: int) -> Sb3Policy:
        if not self._members:
            raise TrainingError("no model trained or loaded yet")
        return self._members[r]

    def rollout(self, x0: np.ndarray) -> Any:
        """Greedy rollouts from ``x0`` ``(B, n)``, row ``b`` by run ``b % runs``, as a
        :class:`mitlc.learn.sacpn.Rollout` (the compiled rewards as the training's)."""
        from mitlc.learn.sacpn import Rollout

        x0 = np.atleast_2d(np.asarray(x0, dtype=float))
        rows = np.arange(x0.shape[0]) % self.runs
        parts = {}
        for r in np.unique(rows):
            parts[int(r)] = self._member(int(r)).rollout(x0[rows == r])
        first = next(iter(parts.values()))
        B = x0.shape[0]
        states = np.empty((B, *first.states.shape[1:]))
        actions = np.empty((B, *first.actions.shape[1:]))
        codes = np.empty((B, first.codes.shape[1]), dtype=first.codes.dtype)
        rewards = np.empty((B, first.rewards.shape[1]))
        for r, ro in parts.items():
            sel = rows == r
            states[sel], actions[sel], codes[sel], rewards[sel] = ro.states, ro.actions, ro.codes, ro.rewards
        return Rollout(states, actions, codes, rewards, first.dt)

    def policy(self) -> SacRunsPolicy:
        """The trained runs as a :class:`mitlc.learn.policy.Policy`."""
        return SacRunsPolicy(self)

    # ------------------------------------------------------------------ files
    def save(self, folder: str | os.PathLike) -> list[Path]:
        """Each run's model as ``folder/sac_RRR.zip`` (:func:`model_name`); the paths."""
        paths = []
        for r, m in enumerate(self.models):
            p = Path(folder) / model_name(r)
            m.save(p)
            paths.append(p)
        return paths

    def model_bytes(self, run: int) -> bytes:
        """Run ``run``'s model as the bytes ``model.save`` writes."""
        import io

        buf = io.BytesIO()
        self.models[run].save(buf)
        return buf.getvalue()


class SacRunsPolicy(Policy):
    """:class:`SacRuns` as a :class:`mitlc.learn.policy.Policy`: row ``b`` acts by run ``b % runs``,
    each run's rows with their own net runtime (marking and clocks)."""

    def __init__(self, runs: SacRuns) -> None:
        self.learner, self.spec, self.runs, self.dt = runs, runs.spec, runs.runs, runs.dt
        self._rows: np.ndarray = np.zeros(0, dtype=int)

    def _split(self, B: int) -> list[tuple[int, np.ndarray]]:
        rows = np.arange(B) % self.runs
        return [(int(r), rows == r) for r in np.unique(rows)]

    def reset(self, x0: np.ndarray) -> np.ndarray:
        x0 = np.atleast_2d(np.asarray(x0, dtype=float))
        out = None
        for r, sel in self._split(x0.shape[0]):
            m = self.learner._member(r).reset(x0[sel])
            if out is None:
                out = np.zeros((x0.shape[0], m.shape[1]), dtype=m.dtype)
            out[sel] = m
        assert out is not None
        return out

    def act(self, x: np.ndarray, state: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(np.asarray(x, dtype=float))
        m = self.learner.plant.n_inputs
        u = np.empty((x.shape[0],) if m == 1 else (x.shape[0], m))
        for r, sel in self._split(x.shape[0]):
            u[sel] = self.learner._member(r).act(x[sel], np.atleast_2d(state)[sel])
        return u

    def step(self, state: np.ndarray, x_next: np.ndarray) -> np.ndarray:
        x_next = np.atleast_2d(np.asarray(x_next, dtype=float))
        state = np.atleast_2d(state)
        out = np.empty_like(state)
        for r, sel in self._split(x_next.shape[0]):
            out[sel] = self.learner._member(r).step(state[sel], x_next[sel])
        return out


def load_policy(directory: str | os.PathLike) -> Policy:
    """The policy ``mitlc train --out DIRECTORY`` saved: a ``--learner sac`` folder's runs as a
    :class:`SacRunsPolicy` (its ``learner``: the :class:`SacRuns`), any other as
    :func:`mitlc.learn.policy.load_policy` loads it. Loading unpickles the models, as SB3 does:
    load only folders you trust."""
    import json

    from mitlc.learn.policy import load_policy as load_learned

    metrics = Path(directory) / "metrics.json"
    try:
        meta = json.loads(metrics.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        meta = None
    if not isinstance(meta, dict) or meta.get("learner") != "sac":
        return load_learned(Path(directory))
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.spec.parse import parse_spec

    try:
        spec = parse_spec(str(meta["spec_source"]), meta.get("spec") or None)
        options = CompileOptions.from_spec(
            spec, **{k: meta[k] for k in ("conjunction", "violations", "clock", "reward") if meta.get(k) is not None}
        )
    except KeyError as exc:
        raise InputError(f"metrics.json lacks {exc}: not a whole --learner sac training", file=str(metrics)) from None
    return load_sac_runs(directory, compile_spec(spec, options), meta).policy()


def load_sac_runs(folder: str | os.PathLike, rs: RewardSystem, meta: dict[str, Any]) -> SacRuns:
    """The runs a ``mitlc train --learner sac`` folder holds (``meta``: its metrics.json), on ``rs``."""
    sb3 = _sb3()
    runs = int(meta["runs"])
    learner = SacRuns(rs, runs, int(meta["seed"]), SacSettings.from_dict(meta.get("settings") or {}))
    models = []
    for r in range(runs):
        p = Path(folder) / model_name(r)
        if not p.is_file():
            raise InputError(
                f"no {model_name(r)}: the folder holds fewer models than its {runs} runs", file=str(folder)
            )
        try:
            models.append(sb3.SAC.load(p, device="cpu"))
        except Exception as exc:  # a damaged file: SB3 raises anything from zipfile to torch
            raise InputError(f"cannot load it as a SAC model: {exc}", file=str(p)) from None
    learner.models, learner.trial = models, int(meta.get("trials", 0))
    learner.returns = np.asarray(meta.get("returns", np.zeros((runs, 0))), dtype=float)
    learner._members = [Sb3Policy(m, rs) for m in models]
    return learner
