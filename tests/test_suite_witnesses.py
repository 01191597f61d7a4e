"""The task suite of bench/suite/: every task is satisfiable, shown by its witness.

Each task's witness, rolled out on mitlc's own simulator from starts spread over the spec's
``init`` box, is accepted by the monitor from every start; one witness rollout per task, written
as a CSV trace, is accepted by ``python -m mitlc check`` (exit 0); doing nothing is not enough
for any task; the families each spec claims are in its formula; the split is the recorded draw.
"""

from __future__ import annotations

import dataclasses
import doctest
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.suite.split import SPLIT, problems
from bench.suite.tasks import FAMILIES, init_box, input_shape, load_tasks, params_of, rollout, task, zero_input
from mitlc.monitor.trace import write_trace
from mitlc.spec import ast as A
from mitlc.spec import predicates as P

ROOT = Path(__file__).resolve().parent.parent
TASKS = [t.name for t in load_tasks()]
GYM = {t.name for t in load_tasks() if t.plant.startswith("gym:")}


def _needs(name: str) -> None:
    if name in GYM:
        pytest.importorskip("gymnasium")


def test_the_suite_covers_what_it_promises() -> None:
    suite = load_tasks()
    assert len(suite) >= 24
    assert {f for t in suite for f in t.families} == set(FAMILIES)
    assert sum(t.nested for t in suite) >= 10
    plants = {t.plant for t in suite}
    assert {"pendulum", "mass-damper", "rail-cart", "cartpole", "unicycle"} <= plants
    assert len({p for p in plants if p.startswith("gym:")}) >= 2
    for t in suite:
        text = t.spec_path.read_text().splitlines()
        assert text[0].startswith("# task: ") and text[1].startswith("# families: "), t.name
        assert t.spec.formula is not None and t.spec.horizon is not None and t.spec.init, t.name


@pytest.mark.parametrize("name", TASKS)
def test_the_witness_is_accepted_from_every_start(name: str) -> None:
    _needs(name)
    t = task(name)
    ro = rollout(t)
    res = ro.judge()
    starts = ro.starts
    assert len(starts) >= 16
    bad = [(starts[r].round(3).tolist(), res.failing[r]) for r in np.flatnonzero(~res.satisfied)]
    assert not bad, f"{name}: the witness fails from {bad}"
    assert (res.robustness > 0).all()
    # the starts lie in the init box and spread over it: its corners (ODE plants), most of each range (Gymnasium)
    plant = t.spec.plant
    assert plant is not None
    for i, (lo, hi) in enumerate(init_box(t.spec)):
        col = starts[:, i]
        if plant.state[i].periodic:
            col = np.where(col < lo - 1e-9, col + 2 * np.pi, col)
        tol = 1e-6 * max(1.0, abs(lo), abs(hi))
        assert (col >= lo - tol).all() and (col <= hi + tol).all()
        if name in GYM:
            assert col.max() - col.min() >= 0.8 * (hi - lo)
        else:
            assert col.min() == pytest.approx(lo) and col.max() == pytest.approx(hi)
    # what was applied stays within each input's box, and has the plant's shape
    lo, hi = plant.input_box(params_of(t.spec))
    assert ro.inputs.shape[2:] == (() if plant.n_inputs == 1 else (plant.n_inputs,))
    assert (ro.inputs >= lo).all() and (ro.inputs <= hi).all()


@pytest.mark.parametrize("name", TASKS)
def test_the_witness_keeps_to_the_input_bound(name: str) -> None:
    """A witness clips its own output to each input's box and returns the plant's shape (``(R,)``, or
    ``(R, m)`` for ``m`` inputs): states drawn over the plant's bounds, at times over the horizon."""
    t = task(name)
    plant = t.spec.plant
    assert plant is not None and t.spec.horizon is not None
    p = params_of(t.spec)
    x = np.random.default_rng(0).uniform(
        [v.lo for v in plant.state], [v.hi for v in plant.state], (64, len(plant.state))
    )
    lo, hi = plant.input_box(p)
    for time in np.linspace(0.0, t.spec.horizon, 7):
        u = np.asarray(t.witness(x, float(time), p))
        assert u.shape == input_shape(plant, 64) and np.isfinite(u).all()
        assert (u >= lo).all() and (u <= hi).all()


@pytest.mark.parametrize("name", TASKS)
def test_doing_nothing_is_not_enough(name: str) -> None:
    """Zero input is accepted from at most one start in ten (the starts at rest at an equilibrium the
    task asks for: the upright pendulum, the centred cart-pole)."""
    _needs(name)
    zero = rollout(task(name), zero_input).judge()
    assert zero.satisfied.mean() <= 0.1, f"{name}: zero input satisfies it from {int(zero.satisfied.sum())} starts"


@pytest.mark.parametrize("name", ["pendulum_alternate", "unicycle_two_waypoints"])
def test_a_controller_of_the_wrong_shape_is_one_clear_error(name: str) -> None:
    """A controller returning inputs of another shape than the plant takes is a ValueError naming the
    task and both shapes, not a broadcast deep in the simulator."""
    t = task(name)
    plant = t.spec.plant
    assert plant is not None
    m = plant.n_inputs
    R = rollout(t, count=1).states.shape[0]
    wrong = [(R, 1), (R, 3)] if m == 1 else [(R,), (R, 1), (R, m + 1), (m, R)]
    for shape in wrong:
        with pytest.raises(ValueError) as err:
            rollout(t, lambda x, time, p, shape=shape: np.zeros(shape), count=1)
        msg = str(err.value)
        assert msg.startswith(f"task {name}: the controller returned inputs of shape {shape}; "), msg
        assert f"expected {input_shape(plant, R)}" in msg, msg
    # a witness of the wrong shape says so
    bad = dataclasses.replace(t, witness=lambda x, time, p: np.zeros(x.shape[0] + 1))
    with pytest.raises(ValueError, match=rf"^task {name}: its witness returned inputs of shape \({R + 1},\); expected"):
        rollout(bad, count=1)


def test_each_input_is_clipped_to_its_own_box() -> None:
    """A unicycle controller asking for more than the boxes give is clipped per input (v to +-1,
    omega to +-2), the recorded inputs what was applied; a one-input plant is clipped to +-u_max."""
    t = task("unicycle_goal_around_rock")
    ro = rollout(t, lambda x, time, p: np.tile([5.0, -7.0], (x.shape[0], 1)), count=1)
    R, N = ro.states.shape[0], ro.states.shape[1] - 1
    assert ro.inputs.shape == (R, N, 2)
    assert (ro.inputs == [1.0, -2.0]).all()
    p = params_of(t.spec)
    x1 = t.spec.plant.step(ro.states[:, 0].copy(), np.tile([1.0, -2.0], (R, 1)), p)  # type: ignore[union-attr]
    assert np.allclose(ro.states[:, 1], x1)
    t = task("pendulum_alternate")
    ro = rollout(t, lambda x, time, p: np.full(x.shape[0], 1e3), count=1)
    assert (ro.inputs == params_of(t.spec)["u_max"]).all()
    # zero input is every input's zero
    assert (rollout(task("unicycle_patrol_pillar"), zero_input, count=1).inputs == 0).all()


@pytest.mark.parametrize("name", TASKS)
def test_a_witness_trace_passes_mitlc_check(name: str, tmp_path: Path) -> None:
    _needs(name)
    t = task(name)
    ro = rollout(t, count=1)
    trace = tmp_path / f"{name}.csv"
    write_trace(trace, ro.t, ro.columns(ro.states.shape[0] - 1))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run(
        [sys.executable, "-m", "mitlc", "check", str(t.spec_path), str(trace)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout.startswith(f"{trace}: satisfied")


def _nodes(f: A.Formula) -> list[A.Formula]:
    return list(A.walk(f))


def _temporal(f: A.Formula) -> bool:
    return isinstance(f, A.Eventually | A.Globally | A.Until | A.Release | A.WeakUntil)


def _state_formula(f: A.Formula) -> bool:
    return not any(_temporal(n) for n in _nodes(f))


def _bounded(f: A.Formula) -> bool:
    return not f.interval.is_unbounded  # type: ignore[attr-defined]


VELOCITIES = {"qdot", "xdot", "thetadot", "w", "v"}

SHAPES = {
    "reach-by-deadline": lambda f, s: any(isinstance(n, A.Eventually | A.Until) and _bounded(n) for n in _nodes(f)),
    "reach-and-stay": lambda f, s: any(
        isinstance(n, A.Eventually) and any(isinstance(m, A.Globally) for m in _nodes(n.child)) for n in _nodes(f)
    ),
    "avoid": lambda f, s: any(isinstance(n, A.Globally) and _state_formula(n.child) for n in _nodes(f)),
    "sequence": lambda f, s: any(
        isinstance(n, A.Eventually) and any(isinstance(m, A.Eventually) and _bounded(m) for m in _nodes(n.child))
        for n in _nodes(f)
    ),
    "recurrence": lambda f, s: any(isinstance(n, A.Globally) and isinstance(n.child, A.Eventually) for n in _nodes(f)),
    "bounded-response": lambda f, s: any(
        isinstance(n, A.Globally)
        and isinstance(n.child, A.Implies)
        and isinstance(n.child.right, A.Eventually)
        and _bounded(n.child.right)
        for n in _nodes(f)
    ),
    "until": lambda f, s: any(isinstance(n, A.Until) and _bounded(n) for n in _nodes(f)),
    "timed-window": lambda f, s: any(_temporal(n) and n.interval.lo > 0 for n in _nodes(f)),  # type: ignore[attr-defined]
    "disjunction": lambda f, s: any(isinstance(n, A.Or) for n in _nodes(f)),
    "rate-limit": lambda f, s: any(
        isinstance(n, A.Atom) and VELOCITIES & {v.name for v in P.variables(s.prop(n.name).pred)} for n in _nodes(f)
    ),
}


@pytest.mark.parametrize("name", TASKS)
def test_the_families_are_in_the_formula(name: str) -> None:
    """Each family a spec names has its shape somewhere in the formula (a light check of the labels)."""
    t = task(name)
    f = t.spec.monitor_formula
    assert f is not None
    assert set(SHAPES) == set(FAMILIES)
    missing = [fam for fam in t.families if not SHAPES[fam](f, t.spec)]
    assert not missing, f"{name} names {missing}, which its formula {f} does not show"


def test_the_split_is_the_recorded_draw() -> None:
    record = json.loads(SPLIT.read_text())
    assert problems(record) == []
    assert record["command"] == "python -m bench.suite.split" and record["seed"] == 31
    suite = {t.name: t for t in load_tasks()}
    tuning, check = record["tuning"], record["check"]
    assert abs(len(tuning) - len(check)) <= 1
    # the tasks added after the draw are recorded, each in the half it is in
    added = record.get("added", {}).get("tasks", {})
    assert set(added) == set(suite) - set(record["drawn"])
    assert all(n in record[half] for n, half in added.items()), added
    for half in (tuning, check):
        assert any(suite[n].nested for n in half)
        plants = {suite[n].plant for n in half}
        assert plants == {t.plant for t in suite.values() if sum(u.plant == t.plant for u in suite.values()) >= 2}
    # a broken record is found out
    swapped = {**record, "tuning": [*tuning[1:], check[0]], "check": [*check[1:], tuning[0]]}
    assert problems(swapped) and problems({**record, "check": check[1:]})


@pytest.mark.parametrize("module", ["bench.suite.tasks", "bench.suite.split"])
def test_the_doctests_of_the_suite(module: str) -> None:
    res = doctest.testmod(importlib.import_module(module))
    assert res.attempted > 0 and res.failed == 0
