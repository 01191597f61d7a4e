"""One task of a sweep: parse, reweight, compile, train, judge; a pure function of its payload."""

from __future__ import annotations

import socket
import time
from collections import Counter
from collections.abc import Mapping
from typing import Any

from mitlc.errors import TrainingError
from mitlc.sweep.grid import with_weights

FINAL_TRIALS = 10
"""The final mean return is the mean over runs of the last this many trials (as ``mitlc train`` prints)."""


# ---------------------------------------------------------------- one task


def sacpn_learner(rs: Any, settings: Any, runs: int, seed: int) -> Any:
    """A SACPN learner on the reward system ``rs``, with the monitor paying the rewards it pays
    (``sparse``, ``robustness``, ``robustness-window``): how ``mitlc train``, a sweep's task and the
    race build one."""
    from mitlc.learn.sacpn import Sacpn

    agent = Sacpn(rs, settings, runs=runs, seed=seed)
    if rs.paid_by_monitor:
        from mitlc.monitor.rewards import pay

        pay(agent)
    return agent


def run_task(payload: Mapping[str, Any]) -> dict:
    """Train and judge one configuration and seed; a pure function of ``payload`` (bar the times and ``host``).

    Returns the result record: the resolved configuration, ``seed``,
    ``success_rate`` (fraction of runs whose final greedy rollout satisfies the
    spec by :mod:`mitlc.monitor`), ``final_return`` (mean over runs of the last
    10 trials' returns), ``greedy_return`` (mean return of those rollouts),
    ``failing`` (for the runs that fail, how many fail by each subformula,
    the monitor's blame), ``wall_s`` and ``cpu_s`` (the task's wall and CPU seconds: a wall time well
    above the CPU time means the worker waited for a core) and ``host``.  Training that diverges is a result too: the
    metrics are None and ``error`` says why.
    """
    import numpy as np

    from mitlc.learn.sacpn import SacpnSettings
    from mitlc.monitor.offline import monitor
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.plants.gym_env import import_gym_module
    from mitlc.plants.user import load_plants
    from mitlc.spec.parse import parse_spec

    start, cpu_start = time.perf_counter(), time.process_time()
    for module in payload.get("gym_modules", ()):  # the --gym-module modules: their environments registered again
        import_gym_module(module)
    for source in payload.get("plant_sources", ()):  # a worker process starts with mitlc's own plants only
        load_plants(source)
    spec = with_weights(parse_spec(payload["spec_text"], payload.get("spec_path")), payload["weights"])
    rs = compile_spec(spec, CompileOptions(**payload["options"]))
    agent = sacpn_learner(rs, SacpnSettings.from_dict(payload["settings"]), int(payload["runs"]), int(payload["seed"]))
    record: dict[str, Any] = {
        "task": payload["key"],
        "seed": int(payload["seed"]),
        "settings": payload["settings"],
        "weights": payload["weights"],
        "options": payload["options"],
        "success_rate": None,
        "final_return": None,
        "greedy_return": None,
        "failing": {},
        "error": None,
    }
    # numpy's overflow warnings from the workers would interleave on the terminal, a line per place and
    # worker: a task's outcome is its record (a diverged one says so in "error"), as in mitlc train
    with np.errstate(all="ignore"):
        try:
            agent.train(int(payload["trials"]))
        except TrainingError as exc:
            record["error"] = exc.message
            ro = None
        else:
            ro = agent.rollout(agent.evaluation_states())
    if ro is not None:
        verdict = monitor(spec, ro.states, ro.dt, spec.monitor_formula)
        record["success_rate"] = float(np.mean(verdict.satisfied))
        record["final_return"] = float(agent.returns[:, -FINAL_TRIALS:].mean())
        record["greedy_return"] = float(ro.returns.mean())
        record["failing"] = dict(sorted(Counter(f for f in verdict.failing if f is not None).items()))
    record["wall_s"] = round(time.perf_counter() - start, 3)
    record["cpu_s"] = round(time.process_time() - cpu_start, 3)
    record["host"] = socket.gethostname()
    return record
