"""What a training's report shows, gathered from its folder.

:func:`training_data` loads the learner the folder holds (``params.npz``, or a ``--learner sac``
folder's models), rolls each run's greedy policy out from its evaluation start (the rollout
``mitlc train`` judged), steps a fresh :class:`~mitlc.runtime.NetRuntime` along each rollout for
the marking per step (what the page animates: the browser only shows these markings, it computes
none), judges each rollout with the monitor (verdict, robustness, the failing part and when) and
reads the learning curves and settings from ``metrics.json``. The result is plain JSON data
(numbers rounded for size) that :mod:`mitlc.cli.reports.page` puts into the page.
"""

from __future__ import annotations

import json
import math
import platform
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from mitlc.errors import InputError

__all__ = ["training_data", "progress_data", "rollout_markings", "CURVE_POINTS"]

CURVE_POINTS = 400
"""A learning curve longer than this many trials is shown as this many bin means (the page's size
stays bounded however long the training was)."""

_DIGITS = 5
"""Significant digits of the states, inputs and returns in the page."""


def _num(v: float, digits: int = _DIGITS) -> float | None:
    """``v`` rounded to ``digits`` significant digits; None for nan and infinities (JSON has neither)."""
    v = float(v)
    if not math.isfinite(v):
        return None
    return float(f"{v:.{digits}g}")


def _nums(a: np.ndarray, digits: int = _DIGITS) -> list[float | None]:
    return [_num(v, digits) for v in np.asarray(a, dtype=float).ravel().tolist()]


def _read_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as exc:
        raise InputError(f"cannot read {path.name}: {exc}", file=str(path.parent)) from None
    if not isinstance(data, dict):
        raise InputError(f"{path.name} is not a mitlc training's metrics", file=str(path.parent))
    return data


def rollout_markings(rs: Any, state_names: tuple[str, ...], states: np.ndarray, dt: float) -> np.ndarray:
    """The markings ``(R, N+1, P)`` a fresh :class:`~mitlc.runtime.NetRuntime` of ``rs`` steps
    through along ``states`` ``(R, N+1, n)``: :meth:`~mitlc.runtime.NetRuntime.reset` on the first
    state, then :meth:`~mitlc.runtime.NetRuntime.step` on each next one at trial time ``(k+1) dt``
    (as the learners step it)."""
    from mitlc.runtime import NetRuntime

    R, K, _ = states.shape
    rt = NetRuntime(rs, state_names, dt=dt, steps=K - 1)
    out = np.empty((R, K, rt.n_places), dtype=np.int64)
    M = rt.reset(states[:, 0])
    out[:, 0] = M
    for k in range(1, K):
        M = rt.step(M, states[:, k], k * dt)
        out[:, k] = M
    return out


def _marks(M: np.ndarray) -> list[list[int | list[int]]]:
    """Per step, the marked places of one run's markings ``(N+1, P)``: an index where one token
    lies, ``[index, tokens]`` where more."""
    steps: list[list[int | list[int]]] = []
    for row in M:
        (idx,) = np.nonzero(row)
        steps.append([int(i) if row[i] == 1 else [int(i), int(row[i])] for i in idx])
    return steps


def _curves(returns: np.ndarray) -> dict[str, Any]:
    """Every run's learning curve and their mean (over the runs with a finite return), binned to at
    most :data:`CURVE_POINTS` points."""
    returns = np.asarray(returns, dtype=float)
    if returns.ndim != 2 or returns.shape[1] == 0:
        return {"x": [], "runs": [], "mean": [], "binned": 1}
    R, T = returns.shape
    size = max(1, math.ceil(T / CURVE_POINTS))
    n = math.ceil(T / size)
    padded = np.full((R, n * size), np.nan)
    padded[:, :T] = returns
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a bin where every run diverged: empty, not news
        binned = np.nanmean(padded.reshape(R, n, size), axis=2)
        mean = np.nanmean(binned, axis=0)
    starts = np.arange(n) * size + 1
    x = (starts + np.minimum(starts + size - 1, T)) / 2  # each bin's middle trial (1-based)
    return {"x": [_num(v) for v in x], "runs": [_nums(r, 4) for r in binned], "mean": _nums(mean, 4), "binned": size}


def _versions() -> dict[str, str]:
    """mitlc's, Python's and the installed libraries' versions (the same page for the same folder, whatever
    the process imported before)."""
    from importlib import metadata

    from mitlc import __version__

    out = {"mitlc": __version__, "python": platform.python_version()}
    for name in ("numpy", "numba", "lark", "graphviz", "gymnasium", "stable-baselines3", "torch"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    out["platform"] = platform.platform()
    return out


def _net_svg(rs: Any) -> tuple[str | None, str | None]:
    """The net drawn by Graphviz as SVG text (without its XML prologue), or None and why not."""
    import graphviz

    from mitlc.petri.render import to_digraph

    try:
        svg = to_digraph(rs).pipe(format="svg", encoding="utf-8")
    except graphviz.ExecutableNotFound:
        return None, "the Graphviz 'dot' program is not installed, so the net is not drawn"
    except (graphviz.CalledProcessError, OSError) as exc:  # pragma: no cover - dot failing on a net it drew before
        return None, f"Graphviz could not draw the net: {exc}"
    start = svg.find("<svg")
    return svg[start:], None


def _agent(folder: Path, metrics: dict) -> tuple[Any, Any, list[str]]:
    """The learner the folder holds, the spec it was trained on and notes for the page (a HyRL
    training: no learner, and its spec's text)."""
    notes: list[str] = []
    if metrics.get("learner") in ("sac", "search"):
        from mitlc.cli.train import _runs_learner

        agent = _runs_learner(folder, metrics["learner"])
        return agent, agent.spec, notes
    from mitlc.learn.checkpoint import read_meta, recorded_spec, restore_plant
    from mitlc.learn.policy import load_sacpn

    ckpt = folder / "params.npz"
    if not ckpt.is_file():
        raise InputError(f"no params.npz in {folder}: not a finished mitlc training", file=str(folder))
    meta = read_meta(ckpt)
    if meta.get("kind") == "hyrl":
        notes.append(
            "a training of classical criteria (HyRL): a run succeeds when its policy meets the criteria from "
            "every initial state checked (mitlc docs hyrl); there is no net to show"
        )
        return None, str(meta.get("spec_source") or ""), notes
    notes += restore_plant(meta, ckpt)
    spec = recorded_spec(meta, ckpt)
    return load_sacpn(ckpt, meta, spec), spec, notes


def _verdict_rows(metrics: dict) -> list[dict[str, Any]]:
    """Per run, what metrics.json says (a HyRL training, whose runs are judged by their criteria:
    ``runs_succeeding``)."""
    sat = metrics.get("satisfied") or metrics.get("runs_succeeding") or []
    rob = metrics.get("robustness") or []
    rows = []
    for r in range(int(metrics.get("runs") or len(sat))):
        rows.append(
            {
                "verdict": bool(sat[r]) if r < len(sat) else None,
                "robustness": _num(rob[r]) if r < len(rob) and rob[r] is not None else None,
                "violation_time": None,
                "failing": None,
            }
        )
    return rows


def training_data(folder: Path) -> dict[str, Any]:
    """Everything a training's page shows, as JSON-ready data (see the module's docstring)."""
    from mitlc.cli.outputs import read_manifest

    folder = Path(folder)
    metrics = _read_json(folder / "metrics.json")
    manifest = read_manifest(folder) or {}
    returns = np.asarray(metrics.get("returns") or [], dtype=float)
    runs = int(metrics.get("runs") or (returns.shape[0] if returns.ndim == 2 else 0))
    final = [_num(v, 4) for v in _final_returns(returns)] if returns.ndim == 2 and returns.shape[1] else [None] * runs
    diverged = {int(d["run"]): int(d["trial"]) for d in metrics.get("diverged") or [] if isinstance(d, dict)}
    data: dict[str, Any] = {
        "kind": "training",
        "title": Path(str(metrics.get("spec") or manifest.get("spec") or folder.name)).name,
        "folder": folder.name,
        "summary": {
            "learner": metrics.get("learner", "sacpn"),
            "runs": runs,
            "trials": metrics.get("trials"),
            "seed": metrics.get("seed"),
            "success_rate": metrics.get("success_rate"),
            "wall_s": metrics.get("wall_s"),
            "interrupted": bool(metrics.get("interrupted")),
        },
        "formula": metrics.get("formula"),
        "check": metrics.get("check"),
        "options": {k: metrics[k] for k in ("conjunction", "violations", "clock", "reward") if k in metrics},
        "settings": metrics.get("settings") or {},
        "race": metrics.get("race"),
        "manifest": {k: manifest[k] for k in ("spec", "spec_sha256", "state", "plant") if k in manifest},
        "curves": _curves(returns),
        "versions": _versions(),
        "notes": [],
        "net_svg": None,
        "rollout": None,
    }
    agent, spec, notes = (None, None, []) if metrics.get("interrupted") else _agent(folder, metrics)
    data["notes"] += notes
    if isinstance(spec, str):  # HyRL
        data["spec_source"], data["summary"]["learner"], spec = spec, "hyrl", None
    if metrics.get("interrupted"):
        data["notes"].append("the training was interrupted: no final rollouts were judged (mitlc train --resume)")
    if agent is None or spec is None or int(metrics.get("trials") or 0) == 0:
        rows = _verdict_rows(metrics)
        for r, row in enumerate(rows):
            row.update(greedy_return=None, final_return=final[r] if r < len(final) else None)
            row["diverged"] = diverged.get(r)
        data["verdicts"] = rows
        return data

    from mitlc.monitor.offline import monitor

    data["spec_source"] = spec.source or ""
    data["reward"] = str(agent.rs.reward)
    x0 = agent.evaluation_states()
    ro = agent.rollout(x0)
    res = monitor(spec, ro.states, ro.dt, spec.monitor_formula)
    state_names = tuple(agent.runtime.state_names)
    markings = rollout_markings(agent.rs, state_names, ro.states, ro.dt)
    if metrics.get("satisfied") is not None and [bool(v) for v in res.satisfied] != list(metrics["satisfied"]):
        data["notes"].append(
            "the verdicts below differ from metrics.json's: the rollouts were judged again on today's mitlc"
        )
    net = agent.rs.net
    truth = agent.runtime.truth(ro.states.reshape(-1, ro.states.shape[2]))
    R, K, _ = ro.states.shape
    actions = ro.actions if ro.actions.ndim == 3 else ro.actions[:, :, None]
    data["net_svg"], why = _net_svg(agent.rs)
    if why:
        data["notes"].append(why)
    lo, hi = agent.plant.input_box(agent.params)
    data["rollout"] = {
        "dt": _num(ro.dt, 12),
        "steps": K - 1,
        "places": [p.name for p in net.places],
        "kinds": [p.kind for p in net.places],
        "state_names": list(state_names),
        "input_names": list(agent.plant.input_names),
        "input_box": [[_num(a), _num(b)] for a, b in zip(np.ravel(lo), np.ravel(hi), strict=True)],
        "props": [{"name": a, "pred": str(spec.prop(a).pred)} for a in agent.runtime.atoms],
        "runs": [
            {
                "x0": _nums(x0[r]),
                "states": [_nums(ro.states[r, :, j]) for j in range(ro.states.shape[2])],
                "inputs": [_nums(actions[r, :, j]) for j in range(actions.shape[2])],
                "truth": {a: "".join("1" if v else "0" for v in truth[a].reshape(R, K)[r]) for a in truth},
                "marks": _marks(markings[r]),
            }
            for r in range(R)
        ],
    }
    data["verdicts"] = [
        {
            "verdict": bool(res.satisfied[r]),
            "robustness": _num(res.robustness[r]),
            "robustness_text": None if math.isfinite(res.robustness[r]) else f"{res.robustness[r]:+}",
            "violation_time": _num(res.violation_time[r]),
            "failing": res.failing[r],
            "greedy_return": _num(ro.returns[r], 6),
            "final_return": final[r] if r < len(final) else None,
            "diverged": diverged.get(r),
        }
        for r in range(R)
    ]
    return data


def _final_returns(returns: np.ndarray, last: int = 10) -> np.ndarray:
    """Per run, the mean of the last ``last`` trials' finite returns (as mitlc train prints the final mean)."""
    tail = returns[:, -last:]
    ok = np.isfinite(tail)
    sums = np.where(ok, tail, 0.0).sum(axis=1)
    counts = ok.sum(axis=1)
    out = np.full(returns.shape[0], np.nan)
    np.divide(sums, counts, out=out, where=counts > 0)
    return out


def progress_data(folder: Path, title: str, returns: np.ndarray, total: int, reload_s: int) -> dict[str, Any]:
    """The page of a training in progress (:mod:`mitlc.cli.reports.live`): its learning curves so far,
    ``returns`` ``(R, trials done)``, out of ``total`` trials; the page reloads every ``reload_s`` seconds."""
    R, T = returns.shape
    return {
        "kind": "training",
        "title": title,
        "folder": Path(folder).name,
        "summary": {
            "learner": "sacpn",
            "runs": R,
            "trials": f"{T} of {total}",
            "seed": None,
            "success_rate": None,
            "wall_s": None,
            "interrupted": False,
        },
        "formula": None,
        "check": None,
        "options": {},
        "settings": {},
        "race": None,
        "manifest": {},
        "curves": _curves(returns),
        "versions": _versions(),
        "notes": [
            f"training in progress: trial {T} of {total}. This page reloads every {reload_s} s; when the training "
            "ends, the full report replaces it. curves.csv in the folder holds the returns so far."
        ],
        "net_svg": None,
        "rollout": None,
        "verdicts": [],
        "reload_s": int(reload_s),
    }
