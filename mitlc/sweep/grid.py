"""The grid of a sweep: its axes, the spec weights they may set, and the plan of tasks.

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
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from mitlc.errors import InputError, MitlError
from mitlc.learn.settings import close_names, parse_finite, setting_parsers
from mitlc.plants.gym_env import GYM_MODULES
from mitlc.plants.user import SOURCES as PLANT_SOURCES
from mitlc.spec import ast as A
from mitlc.spec.model import OPTIONS, Spec

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
    for i, (n, base) in enumerate(zip(nodes, bases, strict=True)):
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
            raise InputError(
                f"the formula has no weight '{name}' (it has: {', '.join(sites) or 'none'})", file=spec.path
            )
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
        if not v:  # no entries (feature_bounds): parses back as none
            return "none"
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
        parse: Callable[[str], Any]
        if name.startswith("weight."):
            wname = name[len("weight.") :]
            site = by_name.get(wname)
            if site is None:
                numbered = [s.axis for s in sites if s.name.rsplit(".", 1)[0] == wname]
                if numbered:
                    raise _axis_error(
                        f"'{name}' is ambiguous: use one of {', '.join(numbered)}",
                        hint="mitlc sweep SPEC --list shows each weight's subformula",
                    )
                raise _axis_error(
                    f"the formula has no weight '{name}' (weights: {weight_names})",
                    hint="mitlc sweep SPEC --list shows each weight's subformula",
                )
            kind, key, parse = "weight", wname, parse_finite
        elif name.startswith("option."):
            key = name[len("option.") :]
            if key not in OPTIONS:
                raise _axis_error(f"unknown option '{name}' (options: {', '.join('option.' + o for o in OPTIONS)})")
            kind, parse = "option", str
        elif name in settings:
            kind, key, parse = "setting", name, settings[name]
        else:
            close = close_names(name, [*settings, *(s.axis for s in sites), *("option." + o for o in OPTIONS)])
            if close:
                raise _axis_error(f"unknown grid name '{name}' (did you mean {close}?)")
            raise _axis_error(
                f"unknown grid name '{name}' (trainer settings: {', '.join(settings)}; "
                f"weights: {weight_names}; options: {', '.join('option.' + o for o in OPTIONS)})"
            )
        values = []
        for t in texts:
            try:
                v = parse(t)
                if kind == "setting":
                    _check_setting(key, v)
            except ValueError as exc:
                raise _axis_error(f"{name}={t}: {exc}") from None
            if kind == "weight" and float(v) <= 0:
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
    from mitlc.learn.sacpn import Sacpn, SacpnSettings
    from mitlc.petri.compile import CompileOptions, compile_spec

    base_opts = CompileOptions.from_spec(spec)
    try:
        base_rs = compile_spec(spec, base_opts)
    except MitlError as exc:
        raise exc.located(spec.path, spec.source) from None
    for axis in axes:
        for v, label in zip(axis.values, axis.labels, strict=True):
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
        for axis, i in zip(axes, combo, strict=True):
            overrides[axis.kind][axis.key] = axis.values[i]
        chosen = dataclasses.replace(SacpnSettings(), **overrides["setting"])
        settings = (chosen if spec.plant is None else chosen.resolved(spec.plant)).to_dict()  # rbf: this plant's
        resolved = {
            "settings": settings,
            "weights": {**base_weights, **{k: float(v) for k, v in overrides["weight"].items()}},
            "options": {**base_options, **overrides["option"]},
        }
        configs.append((tuple(a.labels[i] for a, i in zip(axes, combo, strict=True)), resolved))
    tasks = []
    for seed in seeds:
        for labels, resolved in configs:
            key = task_key(resolved, seed)
            payload = {
                "key": key,
                "spec_text": text,
                "spec_path": spec.path,
                "plant_sources": list(PLANT_SOURCES),  # the user's plants, loaded again in each worker
                "gym_modules": list(GYM_MODULES),  # and the --gym-module modules, imported again
                "runs": int(runs),
                "trials": int(trials),
                "seed": int(seed),
                **resolved,
            }
            tasks.append(Task(key, int(seed), labels, payload))
    if len({t.key for t in tasks}) != len(tasks):
        raise _axis_error("two configurations of the grid are the same task")
    return SweepPlan(
        text,
        spec.path,
        hashlib.sha256(text.encode("utf-8")).hexdigest(),
        int(runs),
        int(trials),
        tuple(int(s) for s in seeds),
        axes,
        tuple(tasks),
    )
