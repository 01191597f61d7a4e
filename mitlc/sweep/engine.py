"""Sweeps: train one spec over a grid of trainer settings, spec weights and compile options.

A sweep is a set of **tasks**, one per configuration of the grid and seed.  A
task is a pure function of ``(spec text, configuration, seed, runs, trials)``:
:func:`run_task` parses the spec, rewrites its weights, compiles it, trains
``runs`` SACPN runs for ``trials`` trials and judges the final greedy policies
with the monitor.  The same task gives the same metrics on any backend.

Grid axes (``NAME=V1,V2,...``, see :func:`parse_grid`):

* a field of :class:`mitlc.learn.sacpn.SacpnSettings`: ``sigma=1,2,3``, ``alpha_a=0.05,0.1``,
  ``mask=current,next``, ``rbf=8x8,10x10``, ``trial_s=none,5``;
* a weight of the spec's formula: ``weight.psi=1,3,10`` (names from :func:`weight_sites`);
* a compile option: ``option.violations=off,permanent``, ``option.conjunction=literal,active``.

Weights are named after the propositions of the weighted subformula, so the
user can tell which one a name belongs to; a numeric suffix tells apart
weights whose subformulas use the same propositions:

>>> from mitlc.spec.parse import parse_formula
>>> for s in weight_sites(parse_formula("2 * !kappa U(1,2] (3 * kappa U(2,inf) G !kappa) & 5 * G psi")):
...     print(s.axis, format_value(s.value), "|", s.text)
weight.kappa.1 2 | 2 * !kappa
weight.kappa.2 3 | 3 * kappa
weight.psi 5 | 5 * G psi
>>> print(set_weights(parse_formula("F G kappa & 10 * G !psi"), {0: 2.5}))
F G kappa & 2.5 * G !psi

Results go to a directory through :class:`ResultStore`: ``results.json`` (the
authoritative record) and ``results.csv``, both rewritten atomically after
every finished task, keyed by the task's configuration and seed so a re-run
skips what is done and never counts a task twice.  Backends:
:class:`LocalBackend` (a process pool, no extra dependency) and
:class:`RayBackend` (``pip install 'mitlc[ray]'``).
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import itertools
import json
import os
import socket
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

from mitlc.spec import ast as A
from mitlc.errors import InputError, MitlError, TrainingError
from mitlc.fileio import atomic_write
from mitlc.spec.model import OPTIONS, Spec
from mitlc.learn.settings import parse_finite, setting_parsers

__all__ = [
    "WeightSite",
    "weight_sites",
    "set_weights",
    "with_weights",
    "Axis",
    "parse_grid",
    "sweepable_settings",
    "Task",
    "SweepPlan",
    "plan_sweep",
    "run_task",
    "ResultStore",
    "LocalBackend",
    "RayBackend",
    "WorkerLost",
    "SweepOutcome",
    "run_sweep",
    "summarize",
    "format_table",
    "heatmap_grid",
    "heatmap_figure",
    "format_value",
    "default_workers",
]

RESULTS_JSON = "results.json"
RESULTS_CSV = "results.csv"
LOCK_FILE = ".sweep.lock"
WRITE_BUDGET = 0.1
"""Largest fraction of a sweep's time spent rewriting the result files (see :func:`run_sweep`)."""
FINAL_TRIALS = 10
"""The final mean return is the mean over runs of the last this many trials (as ``mitlc train`` prints)."""


# ---------------------------------------------------------------- weights


@dataclass(frozen=True)
class WeightSite:
    """One ``w * phi`` node of a formula.

    ``index`` is its position among the formula's weighted nodes in pre-order
    (parents before children, left before right): the order in which they
    appear in the text.
    """

    name: str
    """``psi`` for ``10 * G !psi``: the propositions of ``phi`` joined by ``_``, in order of
    appearance (``const`` if it has none), with ``.1``, ``.2``... when several weighted
    subformulas share those propositions."""

    index: int
    value: float
    text: str
    """The weighted subformula as MITL text, e.g. ``10 * G !psi``."""

    @property
    def axis(self) -> str:
        """The grid axis name: ``weight.<name>``."""
        return f"weight.{self.name}"


def _weighted_nodes(f: A.Formula) -> list[A.Weighted]:
    return [n for n in A.walk(f) if isinstance(n, A.Weighted)]


def weight_sites(f: A.Formula | None) -> tuple[WeightSite, ...]:
    """Every weight of ``f`` with its name, in the order they appear in the text."""
    if f is None:
        return ()
    nodes = _weighted_nodes(f)
    bases = ["_".join(A.atoms(n.child)) or "const" for n in nodes]
    counts = Counter(bases)
    seen: Counter[str] = Counter()
    sites = []
    for i, (n, base) in enumerate(zip(nodes, bases)):
        seen[base] += 1
        name = f"{base}.{seen[base]}" if counts[base] > 1 else base
        sites.append(WeightSite(name, i, n.weight, str(n)))
    return tuple(sites)


def set_weights(f: A.Formula, values: Mapping[int, float]) -> A.Formula:
    """A copy of ``f`` with the weighted node number ``i`` (pre-order) given weight ``values[i]``.

    The tree is immutable: the nodes on the way to each changed weight are
    rebuilt, everything else is shared.
    """
    counter = itertools.count()

    def rebuild(node: A.Formula) -> A.Formula:
        new_weight = None
        if isinstance(node, A.Weighted):
            i = next(counter)
            if i in values:
                new_weight = float(values[i])
        if not node.children:
            return node
        changes: dict[str, Any] = {}
        for fld in dataclasses.fields(node):  # type: ignore[arg-type]
            child = getattr(node, fld.name)
            if isinstance(child, A.Formula):
                new = rebuild(child)
                if new is not child:
                    changes[fld.name] = new
        if new_weight is not None and new_weight != node.weight:  # type: ignore[attr-defined]
            changes["weight"] = new_weight
        return dataclasses.replace(node, **changes) if changes else node  # type: ignore[type-var]

    return rebuild(f)


def with_weights(spec: Spec, weights: Mapping[str, float]) -> Spec:
    """``spec`` with the named weights (names of :func:`weight_sites`, without ``weight.``) changed."""
    if not weights:
        return spec
    sites = {s.name: s for s in weight_sites(spec.formula)}
    values = {}
    for name, value in weights.items():
        if name not in sites:
            raise InputError(f"the formula has no weight '{name}' (it has: {', '.join(sites) or 'none'})",
                             file=spec.path)
        values[sites[name].index] = float(value)
    return dataclasses.replace(spec, formula=set_weights(spec.formula, values))  # type: ignore[arg-type]


# ---------------------------------------------------------------- values


def format_value(v: Any) -> str:
    """How a grid value prints (and parses back): ``1``, ``0.5``, ``none``, ``true``, ``10x10``, ``qdot:-20:20``.

    >>> format_value(2.0), format_value(None), format_value((10, 10)), format_value([["qdot", -20.0, 20.0]])
    ('2', 'none', '10x10', 'qdot:-20:20')
    """
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return A.fmt_number(float(v))
    if isinstance(v, (list, tuple)):
        if all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
            return "x".join(A.fmt_number(float(x)) for x in v)
        return "+".join(":".join(format_value(x) for x in b) for b in v)
    return str(v)


def sweepable_settings() -> dict[str, Callable[[str], Any]]:
    """Every :class:`SacpnSettings` field and the parser of its grid values."""
    from mitlc.learn.sacpn import SacpnSettings

    return setting_parsers(SacpnSettings)


def _check_setting(name: str, value: Any) -> None:
    """Checks :meth:`SacpnSettings.check` leaves to the trainer's constructor."""
    if name in ("sigma",) and value is not None and value < 0:
        raise ValueError("must be non-negative")
    if name in ("trial_s", "dt") and value is not None and value <= 0:
        raise ValueError("must be positive")


# ---------------------------------------------------------------- the grid


@dataclass(frozen=True)
class Axis:
    """One ``--grid`` axis: its name, what it changes, and its values (parsed and as printed)."""

    name: str
    """As the user writes it: ``sigma``, ``weight.psi``, ``option.violations``."""
    kind: str
    """``setting``, ``weight`` or ``option``."""
    key: str
    """The settings field, the weight's name (without ``weight.``) or the option's name."""
    values: tuple
    labels: tuple[str, ...]

    @property
    def swept(self) -> bool:
        return len(self.values) > 1

    def lookup(self, resolved: Mapping[str, Mapping[str, Any]]) -> str:
        """This axis's value (as printed) in a resolved configuration (see :func:`plan_sweep`)."""
        table = {"setting": "settings", "weight": "weights", "option": "options"}[self.kind]
        return format_value(resolved[table].get(self.key))


def _axis_error(message: str, hint: str | None = None) -> InputError:
    return InputError(message, file="--grid", hint=hint)


def parse_grid(items: Sequence[str], spec: Spec) -> tuple[Axis, ...]:
    """Parse ``--grid NAME=V1,V2,...`` items against ``spec``.

    Raises :class:`InputError` (file ``--grid``) for an unknown name, a
    repeated axis, a malformed or repeated value, or a value the setting,
    weight or option does not accept.

    >>> from mitlc.spec.parse import parse_spec
    >>> spec = parse_spec("prop a = abs(q) < 1\\nformula F a & 3 * G a")
    >>> [(a.name, a.values) for a in parse_grid(["sigma=1,2", "weight.a=1,10", "option.conjunction=active"], spec)]
    [('sigma', (1.0, 2.0)), ('weight.a', (1.0, 10.0)), ('option.conjunction', ('active',))]
    """
    settings = sweepable_settings()
    sites = weight_sites(spec.formula)
    by_name = {s.name: s for s in sites}
    weight_names = ", ".join(s.axis for s in sites) or "none (write 'w * phi' in the formula to make a weight)"
    axes: list[Axis] = []
    for item in items:
        name, eq, raw = item.partition("=")
        name = name.strip()
        if not eq or not name:
            raise _axis_error(f"'{item}' is not NAME=VALUE[,VALUE...]", hint="e.g. --grid sigma=1,2,3")
        if any(a.name == name for a in axes):
            raise _axis_error(f"'{name}' is given twice")
        texts = [t.strip() for t in raw.split(",")]
        if any(not t for t in texts):
            raise _axis_error(f"'{item}': empty value")
        if name.startswith("weight."):
            wname = name[len("weight."):]
            site = by_name.get(wname)
            if site is None:
                numbered = [s.axis for s in sites if s.name.rsplit(".", 1)[0] == wname]
                if numbered:
                    raise _axis_error(f"'{name}' is ambiguous: use one of {', '.join(numbered)}",
                                      hint="mitlc sweep SPEC --list shows each weight's subformula")
                raise _axis_error(f"the formula has no weight '{name}' (weights: {weight_names})",
                                  hint="mitlc sweep SPEC --list shows each weight's subformula")
            kind, key, parse = "weight", wname, parse_finite
        elif name.startswith("option."):
            key = name[len("option."):]
            if key not in OPTIONS:
                raise _axis_error(f"unknown option '{name}' (options: "
                                  f"{', '.join('option.' + o for o in OPTIONS)})")
            kind, parse = "option", str
        elif name in settings:
            kind, key, parse = "setting", name, settings[name]
        else:
            raise _axis_error(
                f"unknown grid name '{name}' (trainer settings: {', '.join(settings)}; "
                f"weights: {weight_names}; options: {', '.join('option.' + o for o in OPTIONS)})")
        values = []
        for t in texts:
            try:
                v = parse(t)
                if kind == "setting":
                    _check_setting(key, v)
            except ValueError as exc:
                raise _axis_error(f"{name}={t}: {exc}") from None
            if kind == "weight" and v <= 0:
                raise _axis_error(f"{name}={t}: a weight must be positive")
            if kind == "option" and v not in OPTIONS[key]:
                raise _axis_error(f"{name}={t}: must be one of {', '.join(OPTIONS[key])}")
            values.append(v)
        labels = tuple(format_value(v) for v in values)
        dup = [lab for lab, n in Counter(labels).items() if n > 1]
        if dup:
            raise _axis_error(f"{name}: value {dup[0]} is given twice")
        axes.append(Axis(name, kind, key, tuple(values), labels))
    return tuple(axes)


# ---------------------------------------------------------------- the plan


@dataclass(frozen=True)
class Task:
    """One configuration and seed: everything :func:`run_task` needs, as plain data."""

    key: str
    """Identity of the task: a hash of the resolved configuration and the seed."""
    seed: int
    labels: tuple[str, ...]
    """The value of each grid axis, as printed."""
    payload: dict = field(compare=False, repr=False)


@dataclass(frozen=True)
class SweepPlan:
    """A checked sweep: the spec, the axes, and every task (seed-major, then the grid in order)."""

    spec_text: str
    spec_path: str | None
    spec_sha256: str
    runs: int
    trials: int
    seeds: tuple[int, ...]
    axes: tuple[Axis, ...]
    tasks: tuple[Task, ...]

    @property
    def header(self) -> dict:
        """What every result in one output directory must share."""
        return {"spec": self.spec_path, "spec_sha256": self.spec_sha256, "runs": self.runs, "trials": self.trials}

    @property
    def n_configs(self) -> int:
        return len(self.tasks) // max(1, len(self.seeds))


def task_key(resolved: Mapping[str, Any], seed: int) -> str:
    """16 hex digits of SHA-256 over the canonical JSON of the resolved configuration and seed."""
    text = json.dumps({**resolved, "seed": int(seed)}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _validate_values(spec: Spec, axes: Sequence[Axis]) -> None:
    """Try each axis value on its own (the others at their defaults); raise InputError naming it."""
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.learn.sacpn import Sacpn, SacpnSettings

    base_opts = CompileOptions.from_spec(spec)
    try:
        base_rs = compile_spec(spec, base_opts)
    except MitlError as exc:
        raise exc.located(spec.path, spec.source)
    for axis in axes:
        for v, label in zip(axis.values, axis.labels):
            try:
                if axis.kind == "setting":
                    Sacpn(base_rs, dataclasses.replace(SacpnSettings(), **{axis.key: v}), runs=1, seed=0)
                elif axis.kind == "option":
                    compile_spec(spec, dataclasses.replace(base_opts, **{axis.key: v}))
            except MitlError as exc:
                raise _axis_error(f"{axis.name}={label}: {exc.message}", hint=exc.hint) from None


def plan_sweep(spec: Spec, grid: Sequence[str], seeds: Sequence[int], runs: int, trials: int) -> SweepPlan:
    """Parse and check the grid and list every task.

    A configuration is *resolved* to the full trainer settings, every weight
    of the formula and both compile options, so a task's key does not depend
    on how the grid was written.
    """
    from mitlc.learn.sacpn import SacpnSettings

    if spec.formula is None:
        raise InputError("the spec has no formula to train on (a 'require' spec trains with hyrl)", file=spec.path)
    if runs < 1 or trials < 1:
        raise InputError("runs and trials must be at least 1", file="--runs" if runs < 1 else "--trials")
    if not seeds:
        raise InputError("at least one seed is needed", file="--seeds")
    axes = parse_grid(grid, spec)
    _validate_values(spec, axes)
    text = spec.source or ""
    base_weights = {s.name: s.value for s in weight_sites(spec.formula)}
    base_options = {k: spec.option(k) for k in OPTIONS}
    configs = []
    for combo in itertools.product(*(range(len(a.values)) for a in axes)):
        overrides: dict[str, dict[str, Any]] = {"setting": {}, "weight": {}, "option": {}}
        for axis, i in zip(axes, combo):
            overrides[axis.kind][axis.key] = axis.values[i]
        settings = dataclasses.replace(SacpnSettings(), **overrides["setting"]).to_dict()
        resolved = {
            "settings": settings,
            "weights": {**base_weights, **{k: float(v) for k, v in overrides["weight"].items()}},
            "options": {**base_options, **overrides["option"]},
        }
        configs.append((tuple(a.labels[i] for a, i in zip(axes, combo)), resolved))
    tasks = []
    for seed in seeds:
        for labels, resolved in configs:
            key = task_key(resolved, seed)
            payload = {"key": key, "spec_text": text, "spec_path": spec.path, "runs": int(runs),
                       "trials": int(trials), "seed": int(seed), **resolved}
            tasks.append(Task(key, int(seed), labels, payload))
    if len({t.key for t in tasks}) != len(tasks):
        raise _axis_error("two configurations of the grid are the same task")
    return SweepPlan(text, spec.path, hashlib.sha256(text.encode("utf-8")).hexdigest(), int(runs), int(trials),
                     tuple(int(s) for s in seeds), axes, tuple(tasks))


# ---------------------------------------------------------------- one task


def run_task(payload: Mapping[str, Any]) -> dict:
    """Train and judge one configuration and seed; a pure function of ``payload`` (bar the times and ``host``).

    Returns the result record: the resolved configuration, ``seed``,
    ``success_rate`` (fraction of runs whose final greedy rollout satisfies the
    spec by :mod:`mitlc.monitor.offline`), ``final_return`` (mean over runs of the last
    10 trials' returns), ``greedy_return`` (mean return of those rollouts),
    ``failing`` (for the runs that fail, how many fail by each subformula,
    the monitor's blame), ``wall_s`` and ``cpu_s`` (the task's wall and CPU seconds: a wall time well
    above the CPU time means the worker waited for a core) and ``host``.  Training that diverges is a result too: the
    metrics are None and ``error`` says why.
    """
    import numpy as np

    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.monitor.offline import monitor
    from mitlc.spec.parse import parse_spec
    from mitlc.learn.sacpn import Sacpn, SacpnSettings

    start, cpu_start = time.perf_counter(), time.process_time()
    spec = with_weights(parse_spec(payload["spec_text"], payload.get("spec_path")), payload["weights"])
    rs = compile_spec(spec, CompileOptions(**payload["options"]))
    agent = Sacpn(rs, SacpnSettings.from_dict(payload["settings"]), runs=int(payload["runs"]),
                  seed=int(payload["seed"]))
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
    try:
        agent.train(int(payload["trials"]))
    except TrainingError as exc:
        record["error"] = exc.message
    else:
        ro = agent.rollout(agent.evaluation_states())
        verdict = monitor(spec, ro.states, ro.dt, spec.monitor_formula)
        record["success_rate"] = float(np.mean(verdict.satisfied))
        record["final_return"] = float(agent.returns[:, -FINAL_TRIALS:].mean())
        record["greedy_return"] = float(ro.returns.mean())
        record["failing"] = dict(sorted(Counter(f for f in verdict.failing if f is not None).items()))
    record["wall_s"] = round(time.perf_counter() - start, 3)
    record["cpu_s"] = round(time.process_time() - cpu_start, 3)
    record["host"] = socket.gethostname()
    return record


# ---------------------------------------------------------------- results on disk
# (atomic_write: mitlc.fileio, temp file + fsync + rename)


CSV_METRICS = ("success_rate", "final_return", "greedy_return", "failing", "wall_s", "cpu_s", "error", "host")


def _csv_cell(v: Any) -> Any:
    """A metric as a CSV cell: floats in full (``repr``), a blame count as ``G !psi: 3; F G kappa: 1``."""
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, dict):
        return "; ".join(f"{k}: {n}" for k, n in v.items())
    return v


class ResultStore:
    """The results of one sweep directory: ``results.json`` (authoritative) and ``results.csv``.

    Records are keyed by task; :meth:`add` ignores a task already recorded, so
    a result is never counted twice, and rewrites both files atomically, so a
    crash at any moment leaves every finished task's result on disk.  While
    open, the directory is locked against a second sweep writing to it.
    """

    def __init__(self, out_dir: str | Path, header: Mapping[str, Any], axes: Sequence[Axis]) -> None:
        self.dir = Path(out_dir)
        self.header = dict(header)
        self.records: dict[str, dict] = {}
        self.axes: list[Axis] = list(axes)
        self._lock_fh: Any = None
        self._load()

    # the directory lock
    def __enter__(self) -> "ResultStore":
        self.dir.mkdir(parents=True, exist_ok=True)
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX: no lock
            return self
        fh = open(self.dir / LOCK_FILE, "a")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            raise InputError(f"another sweep is writing to {self.dir}", file="--out") from None
        self._lock_fh = fh
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._lock_fh is not None:
            self._lock_fh.close()
            self._lock_fh = None

    def _load(self) -> None:
        path = self.dir / RESULTS_JSON
        if not path.is_file():
            return
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            header, records = data["header"], data["results"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise InputError(f"cannot read earlier results: {exc}", file=str(path)) from None
        for k, v in self.header.items():
            if header.get(k) != v:
                what = ("another spec text" if k == "spec_sha256" else
                        f"{k} {header.get(k)}, not {v}" if k in ("runs", "trials") else
                        f"spec {header.get(k)}, not {v}")
                raise InputError(
                    f"{self.dir} holds a sweep with {what}",
                    file="--out", hint="choose another --out directory, or use the same spec, --runs and --trials")
        for r in records:
            self.records.setdefault(r["task"], r)
        known = {a.name for a in self.axes}
        for name, spec in data.get("axes", {}).items():
            if name not in known:
                self.axes.append(Axis(name, spec["kind"], spec["key"], (), ()))
                known.add(name)

    def __contains__(self, key: str) -> bool:
        return key in self.records

    def __len__(self) -> int:
        return len(self.records)

    def add(self, record: Mapping[str, Any], write: bool = True) -> bool:
        """Record a finished task and (unless ``write`` is False) rewrite the files.

        Returns False, and changes nothing, if the task was already recorded.
        """
        if record["task"] in self.records:
            return False
        self.records[record["task"]] = dict(record)
        self.dirty = True
        if write:
            self.write()
        return True

    dirty = False
    """Records were added since the files were last written."""

    def json_text(self) -> str:
        """``results.json``: the header and axes, then one compact line per result."""
        axes = {a.name: {"kind": a.kind, "key": a.key} for a in self.axes}
        rows = ",\n".join("  " + json.dumps(r, separators=(",", ":")) for r in self.records.values())
        return (f'{{"header": {json.dumps(self.header)},\n "axes": {json.dumps(axes)},\n'
                f' "results": [\n{rows}\n ]}}\n' if rows else
                f'{{"header": {json.dumps(self.header)},\n "axes": {json.dumps(axes)},\n "results": []}}\n')

    def write(self) -> None:
        """Rewrite ``results.json``, then ``results.csv``, each atomically."""
        self.dir.mkdir(parents=True, exist_ok=True)
        atomic_write(self.dir / RESULTS_JSON, self.json_text())
        atomic_write(self.dir / RESULTS_CSV, self.csv_text())
        self.dirty = False

    def csv_text(self) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["task", "seed", *(a.name for a in self.axes), *CSV_METRICS])
        for r in self.records.values():
            metrics = [_csv_cell(r.get(m)) for m in CSV_METRICS]
            w.writerow([r["task"], r["seed"], *(a.lookup(r) for a in self.axes), *metrics])
        return buf.getvalue()


# ---------------------------------------------------------------- backends


class WorkerLost(RuntimeError):
    """A task's worker died more often than the retries allow."""


def default_workers() -> int:
    """``min(2, cores)``: the local backend's default number of processes."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    return max(1, min(2, cores))


Outcome = tuple[dict, "dict | BaseException"]


class LocalBackend:
    """A pool of ``workers`` processes on this machine (``concurrent.futures``, spawned interpreters).

    At most ``workers`` tasks are in flight.  When a worker dies (killed, out
    of memory) the pool breaks; the tasks that were in flight are run again in
    a new pool, each at most ``max_retries`` more times.
    """

    name = "local"

    def __init__(self, workers: int | None = None, max_retries: int = 3,
                 on_retry: Callable[[dict, int], None] | None = None) -> None:
        self.workers = int(workers or default_workers())
        self.max_retries = int(max_retries)
        self.on_retry = on_retry
        """Called with the payload and the attempt about to start when a lost task is run again."""
        if self.workers < 1:
            raise InputError("--workers must be at least 1", file="--workers")

    def describe(self) -> str:
        return f"local, {self.workers} worker{'s' if self.workers != 1 else ''}"

    def run(self, payloads: Sequence[dict]) -> Iterator[Outcome]:
        import multiprocessing
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool

        queue = deque(payloads)
        losses: Counter[str] = Counter()
        ctx = multiprocessing.get_context("spawn")
        pool: ProcessPoolExecutor | None = None
        running: dict = {}
        try:
            while queue or running:
                if pool is None:
                    pool = ProcessPoolExecutor(self.workers, mp_context=ctx)
                broken = False
                while queue and len(running) < self.workers and not broken:
                    p = queue.popleft()
                    try:
                        running[pool.submit(run_task, p)] = p
                    except BrokenProcessPool:
                        queue.appendleft(p)
                        broken = True
                if not broken:
                    done, _ = wait(running, return_when=FIRST_COMPLETED)
                    broken = any(isinstance(f.exception(), BrokenProcessPool) for f in done)
                if broken:  # every task in flight is lost with the pool: wait until all say so
                    wait(running)
                    done = set(running)
                outcomes: list[Outcome] = []
                for fut in done:
                    p = running.pop(fut)
                    exc = fut.exception()
                    if isinstance(exc, BrokenProcessPool):
                        losses[p["key"]] += 1
                        if losses[p["key"]] > self.max_retries:
                            outcomes.append((p, WorkerLost(f"its worker died {losses[p['key']]} times")))
                        else:
                            queue.appendleft(p)
                            if self.on_retry is not None:
                                self.on_retry(p, losses[p["key"]] + 1)
                    else:
                        outcomes.append((p, exc if exc is not None else fut.result()))
                if broken:
                    pool.shutdown(wait=True, cancel_futures=True)
                    pool = None
                else:  # give the idle workers their next tasks before the results are written
                    while queue and len(running) < self.workers:
                        p = queue.popleft()
                        try:
                            running[pool.submit(run_task, p)] = p
                        except BrokenProcessPool:
                            queue.appendleft(p)
                            break
                yield from outcomes
        finally:
            if pool is not None:
                if running:  # stopped early (an interrupt): do not let the workers finish their tasks
                    _terminate_workers(pool)
                pool.shutdown(wait=False, cancel_futures=True)


def _terminate_workers(pool: Any) -> None:
    """End a process pool's workers now (``terminate_workers`` from Python 3.14; before, its process table)."""
    if hasattr(pool, "terminate_workers"):
        pool.terminate_workers()
        return
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            proc.terminate()
        except (OSError, ValueError):  # already gone
            pass


class RayBackend:
    """Ray tasks (``pip install 'mitlc[ray]'``) on a cluster or on a Ray started for the sweep.

    ``address``: a running cluster (``auto``, ``HOST:6379`` or ``ray://HOST:10001``);
    without it, ``RAY_ADDRESS`` if set, else a new local Ray with ``workers``
    CPUs is started (even if a ``ray start`` cluster runs on this machine) and
    stopped again at the end.  Each task asks for one CPU and
    is retried up to ``max_retries`` times if its worker or node dies.
    """

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None, max_retries: int = 3) -> None:
        self.address = address or os.environ.get("RAY_ADDRESS") or None
        self.workers = int(workers or default_workers())
        self.max_retries = int(max_retries)

    def describe(self) -> str:
        return f"ray at {self.address}" if self.address else f"ray, local, {self.workers} CPUs"

    @staticmethod
    def _import():
        try:
            import ray
        except ImportError:
            raise InputError("the ray backend needs Ray", file="--backend",
                             hint="pip install 'mitlc[ray]' (or use --backend local)") from None
        return ray

    def run(self, payloads: Sequence[dict]) -> Iterator[Outcome]:
        import logging

        ray = self._import()
        connected_here = False
        if not ray.is_initialized():
            try:
                if self.address:
                    ray.init(address=self.address, logging_level=logging.WARNING, log_to_driver=False)
                else:
                    # "local": a new Ray for this sweep, even if a `ray start` cluster runs on this machine
                    ray.init(address="local", num_cpus=self.workers, include_dashboard=False,
                             logging_level=logging.WARNING, log_to_driver=False)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                raise InputError(f"cannot start or reach Ray: {exc}", file="--address") from None
            connected_here = True
        remote = ray.remote(num_cpus=1, max_retries=self.max_retries, retry_exceptions=False)(run_task)
        refs = {}
        try:
            refs = {remote.remote(p): p for p in payloads}
            while refs:
                done, _ = ray.wait(list(refs), num_returns=1)
                for ref in done:
                    p = refs.pop(ref)
                    try:
                        yield p, ray.get(ref)
                    except ray.exceptions.RayTaskError as exc:
                        yield p, exc.cause if isinstance(exc.cause, BaseException) else exc
                    except ray.exceptions.RayError as exc:
                        yield p, exc
        finally:
            for ref in refs:
                try:
                    ray.cancel(ref, force=True)
                except Exception:  # noqa: BLE001 - best effort while stopping
                    pass
            if connected_here:
                ray.shutdown()


# ---------------------------------------------------------------- the sweep


@dataclass
class SweepOutcome:
    """What :func:`run_sweep` did."""

    total: int
    skipped: int
    """Tasks found already finished in the output directory."""
    finished: int
    """Tasks finished by this call."""
    failed: list[tuple[Task, BaseException]]
    records: dict[str, dict]
    """Every record of the plan's tasks, by task key."""
    wall_s: float


def run_sweep(plan: SweepPlan, out_dir: str | Path, backend: LocalBackend | RayBackend | None = None,
              on_result: Callable[[Task, dict], None] | None = None,
              on_start: Callable[[int, int], None] | None = None) -> SweepOutcome:
    """Run every task of ``plan`` not yet recorded in ``out_dir``, recording each result as it arrives.

    ``on_start(total, already_done)`` is called once before any task runs,
    ``on_result(task, record)`` after each new record.  The files are
    rewritten after each new record, except that rewriting never takes more
    than :data:`WRITE_BUDGET` of the time: when results arrive faster than the
    files can be rewritten (thousands of records on a cluster), the records
    that arrive while waiting go into the next rewrite together, and any left
    are written before returning (also on an interrupt).  A task that raises
    (other than a diverging trainer, which is a result) is reported in
    ``failed`` and not recorded; running the sweep again retries it.
    """
    backend = backend or LocalBackend()
    by_key = {t.key: t for t in plan.tasks}
    start = time.perf_counter()
    with ResultStore(out_dir, plan.header, plan.axes) as store:
        store.write()  # the CSV follows the JSON even if an earlier sweep died between the two
        todo = [t for t in plan.tasks if t.key not in store]
        skipped = len(plan.tasks) - len(todo)
        if on_start is not None:
            on_start(len(plan.tasks), skipped)
        finished = 0
        failed: list[tuple[Task, BaseException]] = []
        next_write, cost = 0.0, 0.0
        try:
            if todo:
                for payload, result in backend.run([t.payload for t in todo]):
                    task = by_key[payload["key"]]
                    if isinstance(result, BaseException):
                        failed.append((task, result))
                        continue
                    if not store.add(result, write=False):
                        continue
                    finished += 1
                    now = time.monotonic()
                    if now >= next_write:
                        store.write()
                        cost = time.monotonic() - now
                        next_write = now + cost / WRITE_BUDGET
                    if on_result is not None:
                        on_result(task, result)
        finally:
            if store.dirty:
                store.write()
        records = {k: store.records[k] for k in by_key if k in store}
    return SweepOutcome(len(plan.tasks), skipped, finished, failed, records, time.perf_counter() - start)


# ---------------------------------------------------------------- summaries and the heat map


def summarize(plan: SweepPlan, records: Mapping[str, Mapping[str, Any]]) -> list[dict]:
    """One row per configuration (in grid order): the axis values, means over the finished seeds, and
    ``failing``: how many runs (summed over seeds) the monitor blames on each subformula."""
    import numpy as np

    groups: dict[tuple[str, ...], list[Mapping[str, Any]]] = {}
    for t in plan.tasks:
        groups.setdefault(t.labels, [])
        if t.key in records:
            groups[t.labels].append(records[t.key])
    rows = []
    for labels, recs in groups.items():
        ok = [r for r in recs if r.get("error") is None]

        def mean(m: str) -> float | None:
            return float(np.mean([r[m] for r in ok])) if ok else None

        rows.append({
            **dict(zip((a.name for a in plan.axes), labels)),
            "seeds": len(recs),
            "errors": len(recs) - len(ok),
            "success_rate": mean("success_rate"),
            "success_min": min((r["success_rate"] for r in ok), default=None),
            "success_max": max((r["success_rate"] for r in ok), default=None),
            "final_return": mean("final_return"),
            "failing": dict(sum((Counter(r.get("failing") or {}) for r in ok), Counter())),
            "wall_s": float(np.mean([r["wall_s"] for r in recs])) if recs else None,
        })
    return rows


def format_table(plan: SweepPlan, rows: Sequence[Mapping[str, Any]], markdown: bool = False) -> str:
    """The summary as an aligned text table (or a Markdown table)."""

    def num(v: float | None, fmt: str) -> str:
        return "-" if v is None else format(v, fmt)

    head = [a.name for a in plan.axes] + ["seeds", "success (mean)", "min-max", "final return", "wall s",
                                          "failing runs, by blame"]
    body = []
    for r in rows:
        seeds = f"{r['seeds']}/{len(plan.seeds)}" + (f" ({r['errors']} diverged)" if r["errors"] else "")
        body.append([str(r[a.name]) for a in plan.axes] + [
            seeds, num(r["success_rate"], ".2f"),
            "-" if r["success_min"] is None else f"{r['success_min']:.2f}-{r['success_max']:.2f}",
            num(r["final_return"], ".1f"), num(r["wall_s"], ".1f"),
            ", ".join(f"{k}: {n}" for k, n in sorted(r["failing"].items(), key=lambda kv: -kv[1])) or "-"])
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "|".join(" --- " for _ in head) + "|"]
        lines += ["| " + " | ".join(row) + " |" for row in body]
        return "\n".join(lines)
    widths = [max(len(h), *(len(row[i]) for row in body)) if body else len(h) for i, h in enumerate(head)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(head, widths)).rstrip()]
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in body]
    return "\n".join(lines)


def heatmap_axes(plan: SweepPlan) -> tuple[Axis, ...]:
    """The first two axes with more than one value (the heat map's x and y)."""
    return tuple(a for a in plan.axes if a.swept)[:2]


def heatmap_grid(plan: SweepPlan, records: Mapping[str, Mapping[str, Any]]):
    """``(x_axis, y_axis or None, mean, count)``: success rate over the first two swept axes.

    ``mean[y, x]`` is the mean over seeds (and over any further axes) of the
    finished tasks' success rates, NaN where none finished; ``count[y, x]``
    how many tasks it averages.  None when nothing is swept.
    """
    import numpy as np

    shown = heatmap_axes(plan)
    if not shown:
        return None
    x_axis = shown[0]
    y_axis = shown[1] if len(shown) > 1 else None
    idx = {a.name: i for i, a in enumerate(plan.axes)}
    ny = len(y_axis.labels) if y_axis else 1
    sums = np.zeros((ny, len(x_axis.labels)))
    counts = np.zeros((ny, len(x_axis.labels)), dtype=int)
    for t in plan.tasks:
        r = records.get(t.key)
        if r is None or r.get("success_rate") is None:
            continue
        xi = x_axis.labels.index(t.labels[idx[x_axis.name]])
        yi = y_axis.labels.index(t.labels[idx[y_axis.name]]) if y_axis else 0
        sums[yi, xi] += r["success_rate"]
        counts[yi, xi] += 1
    mean = np.full(sums.shape, np.nan)
    np.divide(sums, counts, out=mean, where=counts > 0)
    return x_axis, y_axis, mean, counts


def heatmap_figure(plan: SweepPlan, records: Mapping[str, Mapping[str, Any]], title: str = ""):
    """The heat map of :func:`heatmap_grid` as a matplotlib Figure (None when nothing is swept).

    Each cell shows the mean and, in brackets, how many tasks it averages;
    cells with no finished task are left blank.
    """
    import numpy as np
    from matplotlib.figure import Figure

    hm = heatmap_grid(plan, records)
    if hm is None:
        return None
    x_axis, y_axis, grid, counts = hm
    ny = grid.shape[0]
    fig = Figure(figsize=(1.2 + 1.0 * len(x_axis.labels), 1.3 + 0.7 * ny))
    ax = fig.add_subplot(1, 1, 1)
    im = ax.imshow(np.ma.masked_invalid(grid), cmap="viridis", vmin=0.0, vmax=1.0, aspect="auto", origin="lower")
    ax.set_xticks(range(len(x_axis.labels)), x_axis.labels)
    ax.set_xlabel(x_axis.name)
    if y_axis:
        ax.set_yticks(range(ny), y_axis.labels)
        ax.set_ylabel(y_axis.name)
    else:
        ax.set_yticks([])
    for yi in range(ny):
        for xi in range(len(x_axis.labels)):
            if counts[yi, xi]:
                v = grid[yi, xi]
                ax.text(xi, yi, f"{v:.2f}\n({counts[yi, xi]})", ha="center", va="center", fontsize=8,
                        color="black" if v > 0.6 else "white")
    others = [a.name for a in plan.axes if a.swept and a not in (x_axis, y_axis)]
    over = "seeds" + (" and " + ", ".join(others) if others else "")
    ax.set_title(title or f"success rate, mean over {over} (n per cell)", fontsize=9)
    fig.colorbar(im, ax=ax, label="success rate")
    return fig
