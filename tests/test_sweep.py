"""``mitlc sweep``: weight names, grid parsing, tasks, the result store, backends, resuming, the CLI."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli import main
from mitlc.errors import InputError
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.monitor.offline import monitor
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.spec.parse import load_spec, parse_formula, parse_spec
from mitlc.sweep import (
    LocalBackend,
    RayBackend,
    ResultStore,
    format_table,
    format_value,
    heatmap_figure,
    heatmap_grid,
    parse_grid,
    plan_sweep,
    run_sweep,
    run_task,
    set_weights,
    summarize,
    sweepable_settings,
    weight_sites,
    with_weights,
)

ROOT = Path(__file__).resolve().parent.parent
P2 = ROOT / "specs" / "pendulum" / "p2_avoid.mitl"

GRID_2X2 = ("sigma=1,3", "weight.psi=1,10")
METRICS = ("success_rate", "final_return", "greedy_return", "error")


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def csv_rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


# ---------------------------------------------------------------- weight names


@pytest.mark.parametrize(
    "spec_file, expected",
    [
        ("p1_swing_up.mitl", []),
        ("p2_avoid.mitl", [("psi", 10.0, "10 * G !psi")]),
        ("p3_avoid_speed_limit.mitl", [("psi", 10.0, "10 * G !psi"), ("upsilon", 10.0, "10 * G upsilon")]),
        (
            "p4_alternate.mitl",
            [("kappa", 5.0, "5 * G F kappa"), ("upsilon", 5.0, "5 * G F upsilon"), ("psi", 25.0, "25 * G !psi")],
        ),
        ("p5_timed_visit.mitl", [("kappa.1", 2.0, "2 * !kappa"), ("kappa.2", 3.0, "3 * kappa")]),
    ],
)
def test_weight_names_of_the_thesis_specs(spec_file, expected):
    sites = weight_sites(load_spec(ROOT / "specs" / "pendulum" / spec_file).formula)
    assert [(s.name, s.value, s.text) for s in sites] == expected
    assert [s.index for s in sites] == list(range(len(expected)))
    assert [s.axis for s in sites] == [f"weight.{n}" for n, _, _ in expected]


def test_weight_names_nested_and_constant():
    f = parse_formula("2 * (F a & 3 * G b) | 4 * G (a & b) | 0.5 * true")
    assert [(s.name, s.value) for s in weight_sites(f)] == [("a_b.1", 2.0), ("b", 3.0), ("a_b.2", 4.0), ("const", 0.5)]


def test_set_weights_rebuilds_only_the_path_to_the_weight():
    f = parse_formula("F G kappa & 10 * G !psi & 2 * G upsilon")
    g = set_weights(f, {1: 0.25})
    assert str(g) == "F G kappa & 10 * G !psi & 0.25 * G upsilon"
    assert str(f) == "F G kappa & 10 * G !psi & 2 * G upsilon"  # the original is untouched
    assert parse_formula(str(g)) == g
    assert g.left is f.left  # the untouched subtree is shared, not copied
    assert g.right.child is f.right.child
    assert set_weights(f, {0: 10.0}) is f  # same value: nothing rebuilt


def test_with_weights_equals_editing_the_spec_text():
    spec = load_spec(P2)
    edited = parse_spec(P2.read_text().replace("10 * G !psi", "3 * G !psi"))
    swept = with_weights(spec, {"psi": 3})
    assert swept.formula == edited.formula
    assert str(compile_spec(swept).reward) == str(compile_spec(edited).reward)
    assert "3 * (1 + " in str(compile_spec(swept).reward)
    with pytest.raises(InputError, match="no weight 'kappa'"):
        with_weights(spec, {"kappa": 2})


# ---------------------------------------------------------------- grid parsing


def test_grid_values_of_every_kind():
    spec = load_spec(P2)
    axes = parse_grid(
        [
            "sigma=1,2.5",
            "rbf=8x8,10x10",
            "trial_s=none,2",
            "bootstrap_timeout=true,false",
            "feature_bounds=qdot:-20:20,qdot:-30:30+q:-3:3",
            "mask=current,next",
            "weight.psi=1,3",
            "option.violations=off,permanent",
            "option.conjunction=active",
        ],
        spec,
    )
    got = {a.name: (a.kind, a.key, a.values, a.labels) for a in axes}
    assert got["sigma"] == ("setting", "sigma", (1.0, 2.5), ("1", "2.5"))
    assert got["rbf"][2:] == (((8, 8), (10, 10)), ("8x8", "10x10"))
    assert got["trial_s"][2:] == ((None, 2.0), ("none", "2"))
    assert got["bootstrap_timeout"][2] == (True, False)
    assert got["feature_bounds"][2] == ((("qdot", -20.0, 20.0),), (("qdot", -30.0, 30.0), ("q", -3.0, 3.0)))
    assert got["feature_bounds"][3] == ("qdot:-20:20", "qdot:-30:30+q:-3:3")
    assert got["weight.psi"] == ("weight", "psi", (1.0, 3.0), ("1", "3"))
    assert got["option.violations"] == ("option", "violations", ("off", "permanent"), ("off", "permanent"))
    assert [a.swept for a in axes][-1] is False


def test_every_trainer_setting_can_be_swept_and_its_default_round_trips():
    fields = dataclasses.fields(SacpnSettings)
    parsers = sweepable_settings()
    assert list(parsers) == [f.name for f in fields]
    defaults = SacpnSettings()
    for f in fields:
        value = getattr(defaults, f.name)
        assert parsers[f.name](format_value(value)) == value, f.name


@pytest.mark.parametrize(
    "item, message",
    [
        ("sigm=1,2", "unknown grid name 'sigm'"),
        ("sigma", "'sigma' is not NAME=VALUE"),
        ("sigma=1,,2", "empty value"),
        ("sigma=1,1.0", "sigma: value 1 is given twice"),
        ("sigma=one", "sigma=one: 'one' is not a number"),
        ("sigma=nan", "'nan' is not a finite number"),
        ("sigma=-1", "sigma=-1: must be non-negative"),
        ("gamma=1.5", "gamma=1.5: gamma must be in [0, 1]"),
        ("mask=sideways", "mask=sideways: unknown mask 'sideways'"),
        ("rbf=3x3x3", "rbf=3x3x3: rbf has 3 entries, the plant has 2 state variables"),
        ("rbf=ten", "'ten' is not a grid size"),
        ("bootstrap_timeout=maybe", "'maybe' is not true or false"),
        ("feature_bounds=qdot:-20", "'qdot:-20' is not a range"),
        ("weight.kappa=1", "the formula has no weight 'weight.kappa' (weights: weight.psi)"),
        ("weight.psi=0", "weight.psi=0: a weight must be positive"),
        ("option.colour=red", "unknown option 'option.colour'"),
        ("option.violations=sometimes", "must be one of off, permanent, counted"),
    ],
)
def test_bad_grid_items_name_the_option(item, message):
    with pytest.raises(InputError) as err:
        plan_sweep(load_spec(P2), [item], [0], runs=1, trials=1)
    assert err.value.file == "--grid"
    assert message in err.value.message


def test_ambiguous_weight_and_repeated_axis():
    spec = load_spec(ROOT / "specs" / "pendulum" / "p5_timed_visit.mitl")
    with pytest.raises(InputError, match="'weight.kappa' is ambiguous: use one of weight.kappa.1, weight.kappa.2"):
        parse_grid(["weight.kappa=1"], spec)
    assert parse_grid(["weight.kappa.2=1,6"], spec)[0].key == "kappa.2"
    with pytest.raises(InputError, match="'sigma' is given twice"):
        parse_grid(["sigma=1", "sigma=2"], spec)


def test_option_that_cannot_compile_is_a_grid_error():
    spec = parse_spec("plant pendulum\nprop k = abs(q) < 0.3\nformula G k")  # no horizon
    with pytest.raises(InputError) as err:
        plan_sweep(spec, ["option.violations=off,permanent"], [0], runs=1, trials=1)
    assert err.value.file == "--grid" and err.value.message.startswith("option.violations=permanent: ")


# ---------------------------------------------------------------- the plan and one task


def test_plan_lists_every_configuration_and_seed_seed_major(short_spec):
    plan = plan_sweep(load_spec(short_spec), GRID_2X2, [0, 1, 2], runs=2, trials=3)
    assert len(plan.tasks) == 12 and plan.n_configs == 4
    assert [t.seed for t in plan.tasks] == [0] * 4 + [1] * 4 + [2] * 4
    assert [t.labels for t in plan.tasks[:4]] == [("1", "1"), ("1", "10"), ("3", "1"), ("3", "10")]
    assert len({t.key for t in plan.tasks}) == 12
    p = plan.tasks[1].payload
    assert p["settings"]["sigma"] == 1.0 and p["weights"] == {"psi": 10.0}
    assert p["options"] == {"conjunction": "literal", "violations": "off", "clock": "standard", "reward": "net"}


def test_task_key_depends_on_the_configuration_not_on_how_the_grid_is_written(short_spec):
    spec = load_spec(short_spec)
    a = plan_sweep(spec, ["sigma=3"], [0], 2, 3).tasks[0].key
    assert plan_sweep(spec, ["sigma=3.0", "weight.psi=10"], [0], 2, 3).tasks[0].key == a
    assert plan_sweep(spec, ["sigma=3", "option.violations=off"], [0], 2, 3).tasks[0].key == a
    assert plan_sweep(spec, ["sigma=3"], [1], 2, 3).tasks[0].key != a
    assert plan_sweep(spec, ["sigma=3", "weight.psi=9"], [0], 2, 3).tasks[0].key != a


def test_run_task_is_the_trainer_and_the_monitor(short_spec):
    """A task equals training by hand on the spec with its weight edited in the text."""
    plan = plan_sweep(
        load_spec(short_spec), ["sigma=2", "weight.psi=3", "option.violations=permanent"], [5], runs=3, trials=6
    )
    record = run_task(plan.tasks[0].payload)
    spec = parse_spec(short_spec.read_text().replace("10 * G !psi", "3 * G !psi"))
    agent = Sacpn(compile_spec(spec, CompileOptions(violations="permanent")), SacpnSettings(sigma=2.0), runs=3, seed=5)
    agent.train(6)
    ro = agent.rollout(agent.evaluation_states())
    assert record["final_return"] == agent.returns[:, -10:].mean()
    assert record["greedy_return"] == ro.returns.mean()
    verdict = monitor(spec, ro.states, ro.dt)
    assert record["success_rate"] == verdict.satisfied.mean()
    assert sum(record["failing"].values()) == 3 - verdict.satisfied.sum()
    assert record["failing"] == {f: verdict.failing.count(f) for f in set(verdict.failing) - {None}}
    assert record["error"] is None and record["seed"] == 5 and record["task"] == plan.tasks[0].key
    assert record["final_return"] < 0  # 6 trials do not learn to avoid the penalty
    again = run_task(plan.tasks[0].payload)
    assert all(again[m] == record[m] for m in METRICS)


def test_diverging_training_is_a_result_not_a_crash(short_spec):
    plan = plan_sweep(load_spec(short_spec), ["alpha_c=1e6"], [0], runs=2, trials=5)
    record = run_task(plan.tasks[0].payload)
    assert record["error"] == "the parameters of every run diverged (NaN or inf), the last in trial 3"
    assert record["success_rate"] is None and record["wall_s"] > 0


# ---------------------------------------------------------------- the store, summary and heat map


def test_store_never_counts_a_task_twice_and_refuses_another_sweep(short_spec, tmp_path):
    plan = plan_sweep(load_spec(short_spec), ["sigma=1,3"], [0], 2, 3)
    rec = {
        "task": plan.tasks[0].key,
        "seed": 0,
        **{k: plan.tasks[0].payload[k] for k in ("settings", "weights", "options")},
        "success_rate": 0.5,
        "final_return": -1.0,
        "greedy_return": -2.0,
        "error": None,
        "wall_s": 0.1,
        "host": "h",
    }
    with ResultStore(tmp_path / "o", plan.header, plan.axes) as store:
        assert store.add(rec) is True
        assert store.add({**rec, "success_rate": 1.0}) is False
        with (
            pytest.raises(InputError, match="another sweep is writing to"),
            ResultStore(tmp_path / "o", plan.header, plan.axes),
        ):
            pass
    rows = csv_rows(tmp_path / "o" / "results.csv")
    assert [(r["task"], r["sigma"], r["success_rate"]) for r in rows] == [(rec["task"], "1", "0.5")]
    other = plan_sweep(load_spec(short_spec), ["sigma=1,3"], [0], 2, 4)
    with pytest.raises(InputError, match="holds a sweep with trials 3, not 4") as err:
        ResultStore(tmp_path / "o", other.header, other.axes)
    assert err.value.file == "--out"


def test_summary_and_heat_map_average_over_seeds(short_spec):
    plan = plan_sweep(load_spec(short_spec), ["sigma=1,3", "weight.psi=1,10,20", "mask=current,next"], [0, 1], 2, 3)
    rates = {}
    for i, t in enumerate(plan.tasks):
        rates[t.key] = {
            "success_rate": (i % 5) / 4,
            "final_return": float(i),
            "wall_s": 1.0,
            "error": None,
            "failing": {"!psi": i % 3, "F G kappa": 1},
        }
    missing = plan.tasks[-1]
    del rates[missing.key]
    rows = summarize(plan, rates)
    assert len(rows) == 12
    first = rows[0]  # sigma 1, psi 1, mask current: tasks 0 and 12
    assert (first["sigma"], first["weight.psi"], first["mask"], first["seeds"]) == ("1", "1", "current", 2)
    assert first["success_rate"] == pytest.approx((0 / 4 + 2 / 4) / 2) and first["final_return"] == 6.0
    assert rows[-1]["seeds"] == 1
    assert first["failing"] == {"F G kappa": 2}  # tasks 0 and 12: i % 3 == 0, no !psi
    assert rows[1]["failing"] == {"!psi": 1 + 1, "F G kappa": 2}  # tasks 1 and 13
    text = format_table(plan, rows)
    assert text.splitlines()[1].split()[:8] == ["1", "1", "current", "2/2", "0.25", "0.00-0.50", "6.0", "1.0"]
    x, y, mean, count = heatmap_grid(plan, rates)
    assert (x.name, y.name, mean.shape) == ("sigma", "weight.psi", (3, 2))
    # cell sigma=1, psi=1 averages mask current and next over both seeds: tasks 0, 1, 12, 13
    assert mean[0, 0] == pytest.approx(np.mean([0 / 4, 1 / 4, 2 / 4, 3 / 4])) and count[0, 0] == 4
    assert count[2, 1] == 3  # the missing task
    assert heatmap_figure(plan, rates).axes[0].get_xlabel() == "sigma"
    assert heatmap_grid(plan_sweep(load_spec(short_spec), ["sigma=1"], [0], 2, 3), {}) is None


class _InstantBackend:
    """Results at once, without training (fake metrics), then optionally an interrupt."""

    def __init__(self, interrupt_after: int | None = None) -> None:
        self.interrupt_after = interrupt_after

    def run(self, payloads):
        for i, p in enumerate(payloads):
            if i == self.interrupt_after:
                raise KeyboardInterrupt
            yield (
                p,
                {
                    "task": p["key"],
                    "seed": p["seed"],
                    "settings": p["settings"],
                    "weights": p["weights"],
                    "options": p["options"],
                    "success_rate": i / 1000,
                    "final_return": -1.0,
                    "greedy_return": -1.0,
                    "failing": {},
                    "error": None,
                    "wall_s": 0.0,
                    "cpu_s": 0.0,
                    "host": "h",
                },
            )


def test_rewrites_are_coalesced_when_results_come_faster_than_the_files_are_written(short_spec, tmp_path, monkeypatch):
    import mitlc.sweep.run as sweep_mod

    plan = plan_sweep(load_spec(short_spec), ["weight.psi=" + ",".join(str(w) for w in range(1, 201))], [0], 2, 3)
    writes = []
    real_write = ResultStore.write
    monkeypatch.setattr(ResultStore, "write", lambda self: (writes.append(len(self.records)), real_write(self)))
    run_sweep(plan, tmp_path / "a", _InstantBackend())
    assert writes[:2] == [0, 1] and len(writes) < 50 and writes[-1] == 200  # not 201 rewrites
    monkeypatch.setattr(sweep_mod, "WRITE_BUDGET", 1e-12)  # a write "costs" forever: only the first and last
    writes.clear()
    with pytest.raises(KeyboardInterrupt):
        run_sweep(plan, tmp_path / "b", _InstantBackend(interrupt_after=150))
    assert writes == [0, 1, 150]  # the 149 results that waited are written on the way out
    assert len(csv_rows(tmp_path / "b" / "results.csv")) == 150


# ---------------------------------------------------------------- backends


def _records_by_key(out: Path) -> dict:
    return {r["task"]: r for r in json.loads((out / "results.json").read_text())["results"]}


def test_local_and_ray_give_identical_metrics(short_spec, tmp_path):
    ray = pytest.importorskip("ray", reason="Ray is not installed: pip install '.[test-extra]' to run this test")
    plan = plan_sweep(load_spec(short_spec), GRID_2X2, [0], runs=2, trials=4)
    local = run_sweep(plan, tmp_path / "local", LocalBackend(workers=2))
    assert ray.is_initialized() is False
    remote = run_sweep(plan, tmp_path / "ray", RayBackend(workers=2))
    assert ray.is_initialized() is False  # the Ray started for the sweep is stopped again
    assert local.finished == remote.finished == 4 and not local.failed and not remote.failed
    a, b = _records_by_key(tmp_path / "local"), _records_by_key(tmp_path / "ray")
    assert set(a) == set(b) == {t.key for t in plan.tasks}
    for t in plan.tasks:  # the same on both backends, and in this process
        here = run_task(t.payload)
        assert {m: a[t.key][m] for m in METRICS} == {m: b[t.key][m] for m in METRICS} == {m: here[m] for m in METRICS}
    returns = {t.labels: a[t.key]["final_return"] for t in plan.tasks}
    assert all(math.isfinite(v) and v < 0 for v in returns.values())
    # 33 samples at reward -1 outside kappa; with sigma 3 some runs enter psi, where the weight counts
    assert returns[("1", "1")] == returns[("1", "10")] == -33.0
    assert returns[("3", "10")] < returns[("3", "1")] < -33.0
    assert len(csv_rows(tmp_path / "ray" / "results.csv")) == 4


def test_ray_address_joins_a_running_cluster(short_spec, tmp_path):
    ray = pytest.importorskip("ray", reason="Ray is not installed: pip install '.[test-extra]' to run this test")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="WARNING")
    try:
        address = ray.get_runtime_context().gcs_address
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "mitlc",
                "sweep",
                str(short_spec),
                "--grid",
                "sigma=1,3",
                "--seeds",
                "1",
                "--runs",
                "2",
                "--trials",
                "4",
                "--backend",
                "ray",
                "--address",
                address,
                "--out",
                str(tmp_path / "o"),
                "-q",
                "--no-plot",
            ],
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert ray.is_initialized()  # the sweep disconnected; the cluster it joined is still up
    finally:
        ray.shutdown()
    assert proc.returncode == 0, proc.stderr
    assert f"running on ray at {address}" in proc.stderr
    plan = plan_sweep(load_spec(short_spec), ["sigma=1,3"], [0], runs=2, trials=4)
    got = _records_by_key(tmp_path / "o")
    for t in plan.tasks:
        assert {m: got[t.key][m] for m in METRICS} == {m: run_task(t.payload)[m] for m in METRICS}


def test_ray_backend_missing_is_a_clear_error(short_spec, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    res = run(
        "sweep",
        short_spec,
        "--grid",
        "sigma=1,3",
        "--backend",
        "ray",
        "--runs",
        1,
        "--trials",
        1,
        "--out",
        tmp_path / "o",
    )
    assert res.exit_code == 2
    assert "--backend: error: the ray backend needs Ray" in res.output
    assert "pip install 'mitlc[ray]'" in res.output
    assert not (tmp_path / "o").exists()


# ---------------------------------------------------------------- killing and resuming


def _sweep_process(spec: Path, out: Path, *extra: str) -> subprocess.Popen:
    cmd = [
        sys.executable,
        "-m",
        "mitlc",
        "sweep",
        str(spec),
        "--grid",
        "sigma=1,3",
        "--grid",
        "weight.psi=1,10",
        "--seeds",
        "1",
        "--workers",
        "1",
        "--out",
        str(out),
        "-q",
        "--no-plot",
        *extra,
    ]
    return subprocess.Popen(
        cmd,
        start_new_session=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_default_sigint,
    )


def _default_sigint() -> None:
    """A child as a shell starts it: Ctrl-C not ignored, whatever this test process inherited or set."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _n_results(out: Path) -> int:
    try:
        return len(json.loads((out / "results.json").read_text())["results"])
    except (OSError, ValueError):
        return 0


def _wait(cond, timeout: float = 90.0, what: str = "") -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def test_killed_sweep_resumes_with_every_task_exactly_once(tmp_path):
    out = tmp_path / "o"
    proc = _sweep_process(P2, out, "--runs", "5", "--trials", "150")
    try:
        _wait(lambda: _n_results(out) >= 1 or proc.poll() is not None, what="the first result")
        os.killpg(proc.pid, signal.SIGKILL)  # the sweep and its worker, at once
    finally:
        proc.wait()
    first = _records_by_key(out)
    assert 1 <= len(first) < 4, "the sweep finished before it could be killed"
    res = run(
        "sweep",
        P2,
        "--grid",
        "sigma=1,3",
        "--grid",
        "weight.psi=1,10",
        "--seeds",
        1,
        "--workers",
        1,
        "--runs",
        5,
        "--trials",
        150,
        "--out",
        out,
        "-q",
        "--no-plot",
    )
    assert res.exit_code == 0, res.output
    assert f"{4 - len(first)} tasks run" in res.output and f"{len(first)} done earlier" in res.output
    rows = csv_rows(out / "results.csv")
    assert sorted(r["task"] for r in rows) == sorted(_records_by_key(out))
    assert len(rows) == 4 and len({r["task"] for r in rows}) == 4
    assert {(r["sigma"], r["weight.psi"]) for r in rows} == {("1", "1"), ("1", "10"), ("3", "1"), ("3", "10")}
    after = _records_by_key(out)
    for key, rec in first.items():
        assert after[key] == rec  # kept, not run again (the wall time would differ)


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(c) for c in text.split()]


def _spawned_workers(pid: int) -> list[int]:
    out = []
    for c in _children(pid):
        try:
            cmdline = Path(f"/proc/{c}/cmdline").read_bytes()
        except OSError:
            continue
        if b"spawn_main" in cmdline:
            out.append(c)
    return out


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc to find the worker process")
def test_killed_worker_task_is_retried(tmp_path):
    out = tmp_path / "o"
    # tasks of a second or more: with the kernel loaded from the cache a shorter one may end
    # before the kill lands
    proc = _sweep_process(P2, out, "--runs", "5", "--trials", "2000")
    try:
        _wait(lambda: _spawned_workers(proc.pid) or proc.poll() is not None, what="the worker")
        workers = _spawned_workers(proc.pid)
        assert workers, "the sweep ended before its worker started"
        time.sleep(1.5)  # into its first task (the worker imports numpy and mitlc first)
        os.kill(workers[0], signal.SIGKILL)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 0, stderr
    assert "a worker died; running task" in stderr and "(attempt 2 of 4)" in stderr
    rows = csv_rows(out / "results.csv")
    assert len(rows) == 4 and len({r["task"] for r in rows}) == 4
    assert all(r["success_rate"] != "" for r in rows)


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc to find the worker process")
def test_interrupt_stops_the_workers_at_once_and_exits_130(tmp_path):
    out = tmp_path / "o"
    proc = _sweep_process(P2, out, "--runs", "5", "--trials", "2000")  # tasks of several seconds
    try:
        _wait(lambda: _spawned_workers(proc.pid) or proc.poll() is not None, what="the worker")
        workers = _spawned_workers(proc.pid)
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)  # to the sweep alone, not to its worker
        start = time.monotonic()
        stdout, stderr = proc.communicate(timeout=60)
        waited = time.monotonic() - start
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130
    assert "interrupted; finished tasks are in" in stderr and "Traceback" not in stderr
    assert waited < 3.0  # the running task was not waited for
    assert workers and not any(Path(f"/proc/{w}").exists() for w in workers)
    assert _n_results(out) == 0


# ---------------------------------------------------------------- the command


def test_cli_sweep_writes_results_summary_and_heat_map_and_resumes(short_spec, tmp_path):
    out = tmp_path / "o"
    args = (
        "sweep",
        short_spec,
        "--grid",
        GRID_2X2[0],
        "--grid",
        GRID_2X2[1],
        "--seeds",
        2,
        "--runs",
        2,
        "--trials",
        4,
        "--workers",
        1,
        "--out",
        out,
        "-q",
    )
    res = run(*args)
    assert res.exit_code == 0, res.output
    assert "8 tasks (4 configurations x 2 seeds, 2 runs x 4 trials each); 0 already in" in res.output
    assert "sigma  weight.psi  seeds  success (mean)" in res.output
    assert "8 tasks run in" in res.output
    rows = csv_rows(out / "results.csv")
    assert len(rows) == 8
    assert list(rows[0]) == [
        "task",
        "seed",
        "sigma",
        "weight.psi",
        "success_rate",
        "final_return",
        "greedy_return",
        "failing",
        "wall_s",
        "cpu_s",
        "error",
        "host",
    ]
    data = json.loads((out / "results.json").read_text())
    assert data["header"]["runs"] == 2 and data["header"]["trials"] == 4
    assert (out / "sweep.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p for p in out.iterdir() if p.name.startswith(".results")]  # no temporary files left
    before = (out / "results.csv").read_text()
    again = run(*args)
    assert again.exit_code == 0 and "0 tasks run" in again.output and "8 done earlier" in again.output
    assert (out / "results.csv").read_text() == before
    # a bigger grid in the same directory runs only the new configurations
    more = run(*args[:3], "sigma=1,3,5", *args[4:])
    assert more.exit_code == 0 and "4 tasks run" in more.output and "8 done earlier" in more.output
    assert len(csv_rows(out / "results.csv")) == 12


def test_cli_list_shows_every_weight_option_and_setting():
    res = run("sweep", ROOT / "specs" / "pendulum" / "p5_timed_visit.mitl", "--list")
    assert res.exit_code == 0
    lines = [line.split() for line in res.output.splitlines()]
    assert ["weight.kappa.1", "2:", "2", "*", "!kappa"] in lines
    assert ["weight.kappa.2", "3:", "3", "*", "kappa"] in lines
    assert ["option.violations", "off:", "off,", "permanent,", "counted"] in lines
    assert ["sigma", "none", "(sigma_frac", "x", "u_max:", "3)"] in lines
    assert ["rbf", "10x10"] in lines


@pytest.mark.parametrize(
    "args, message",
    [
        (("--grid", "sigm=1"), "--grid: error: unknown grid name 'sigm' (did you mean 'sigma'?)"),
        (("--grid", "gama=0.9"), "--grid: error: unknown grid name 'gama' (did you mean 'gamma'?)"),
        (("--grid", "zzz=1"), "--grid: error: unknown grid name 'zzz' (trainer settings: "),
        (("--grid", "weight.psi=-2"), "--grid: error: weight.psi=-2: a weight must be positive"),
        (("--address", "auto"), "--address: error: --address is for --backend ray"),
    ],
)
def test_cli_bad_input_is_one_line_and_exit_2(short_spec, tmp_path, args, message):
    res = run("sweep", short_spec, *args, "--out", tmp_path / "o")
    assert res.exit_code == 2
    assert res.output.splitlines()[0] == message or res.output.splitlines()[0].startswith(message)
    assert "Traceback" not in res.output


def test_cli_refuses_an_output_directory_of_another_sweep(short_spec, tmp_path):
    out = tmp_path / "o"
    assert (
        run(
            "sweep",
            short_spec,
            "--grid",
            "sigma=1",
            "--seeds",
            1,
            "--runs",
            2,
            "--trials",
            2,
            "--workers",
            1,
            "--out",
            out,
            "-q",
            "--no-plot",
        ).exit_code
        == 0
    )
    res = run("sweep", short_spec, "--grid", "sigma=1", "--seeds", 1, "--runs", 3, "--trials", 2, "--out", out)
    assert res.exit_code == 2
    assert f"--out: error: {out} holds a sweep with runs 2, not 3" in res.output
