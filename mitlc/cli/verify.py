"""``mitlc verify``: a trained policy against its spec, by sampling and by falsification.

Sampling rolls the policy out from ``--samples`` scenarios drawn uniformly (seeded) from the
spec's ``init`` box, the ``--vary`` parameter ranges and the ``--disturb`` bounds, judges each
rollout by the monitor, and reports the satisfied fraction with its exact one-sided
Clopper-Pearson lower bound (:mod:`mitlc.verify.stats`) and the least robust rollout.
Falsification spends ``--budget`` more rollouts searching the same scenarios for the least
robust one (:mod:`mitlc.verify.falsify`). The violating rollouts found (the ``--keep`` least
robust) are written under ``--out`` as traces ``mitlc check`` reads, with a figure each, and
``report.html`` shows the whole verification as one page (:mod:`mitlc.cli.reports.verification`;
``--no-report`` skips it).

Exit status: 0 when nothing violated the spec and the bound meets ``--require``; 1 when a
rollout violated it or the bound falls short; 2 on bad input (one line). docs/verify.md.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import click
import numpy as np

from mitlc.cli.common import handle_errors, plant_file_option
from mitlc.errors import InputError, MitlError

__all__ = ["verify"]

REPORT = "report.json"
STARTS = "counterexamples.npz"
SPEC_COPY = "spec.mitl"


def _load_policy(folder: str, spec_path: str | None) -> Any:
    """The policy a ``mitlc train`` folder holds (SACPN, HyRL, or ``--learner sac`` where
    Stable-Baselines3 is installed), or a Stable-Baselines3 model ``.zip`` on ``--spec``; any
    failure one line naming ``--policy``."""
    if Path(folder).is_file():
        return _load_sb3(folder, spec_path)
    load: Any
    try:
        from mitlc.gym import load_policy as load
    except ImportError:  # no Gymnasium: SACPN and HyRL folders still load
        from mitlc.learn.policy import load_policy as load
    try:
        return load(folder)
    except MitlError as exc:
        raise exc.located(f"--policy {folder}") from None


def _load_sb3(path: str, spec_path: str | None) -> Any:
    """A Stable-Baselines3 model trained on a mitlc environment, as ``mitlc simulate`` loads it."""
    if Path(path).suffix.lower() != ".zip":
        raise InputError(
            "a policy is a directory written by 'mitlc train' or a Stable-Baselines3 model .zip",
            file=f"--policy {path}",
        )
    if spec_path is None:
        raise InputError(
            "a Stable-Baselines3 model does not record its spec: give the one it was trained on", file="--spec"
        )
    try:
        from mitlc.gym import load_sb3
    except ImportError:  # no Gymnasium
        raise InputError(
            "loading a Stable-Baselines3 model needs Stable-Baselines3: pip install 'mitlc[sb3]'", file=path
        ) from None
    from mitlc.spec.parse import load_spec

    try:
        return load_sb3(path, load_spec(spec_path))
    except MitlError as exc:
        raise exc.located(f"--policy {path}") from None


def _steps(policy: Any, spec: Any) -> int:
    """Samples per rollout: the judging spec's horizon, else the policy's trial length, else 3 s."""
    from mitlc.limits import check_steps

    trainer = getattr(policy, "agent", None) or getattr(policy, "learner", None)
    trained_steps = getattr(trainer, "n_steps", None)
    if spec.horizon is None and trained_steps:
        return int(trained_steps)
    try:
        return check_steps(float(spec.horizon or 3.0), float(policy.dt), "a rollout")
    except ValueError as exc:
        raise InputError(str(exc), file=spec.path) from None


def _judging_spec(policy: Any, spec_path: str | None) -> Any:
    """The spec the rollouts are judged by: ``--spec`` (the same plant as the policy's, else one
    line), or the one the policy was trained on."""
    trained = policy.spec
    if spec_path is None:
        spec = trained
    else:
        from mitlc.spec.parse import load_spec

        spec = load_spec(spec_path)
        a, b = trained.plant, spec.plant
        if b is None or a is None or a.name != b.name or a.state_names != b.state_names:
            raise InputError(
                f"the policy was trained for plant '{a.name if a else None}' ({trained.path or 'its spec'}); "
                f"this spec's plant is '{b.name if b else None}': a policy folder for another spec",
                file=f"--spec {spec_path}",
            )
    if spec.monitor_formula is None:
        raise InputError(
            "the spec has no 'formula' nor 'check' line for the monitor to judge rollouts by "
            "(a spec of require lines only): give one with --spec",
            file=spec_path and f"--spec {spec_path}" or "--policy",
        )
    if spec.plant is None:
        raise InputError("the spec names no plant", file=spec.path)
    return spec


def _scenario_text(space: Any, z: np.ndarray) -> str:
    """``q=0.612, qdot=0.498, M=0.55, u[0]=+0.20``: the free coordinates of one scenario."""
    sc = space.decode(z[None, :])
    parts = [f"run {int(sc.run[0])}"] if space.runs > 1 else []
    parts += [f"{space.state_names[i]}={sc.x0[0, i]:.4g}" for i in space.free]
    parts += [f"{n}={sc.params[n][0]:.4g}" for n, _, _ in space.vary]
    for name, _ in space.disturb:
        d = space.disturbance_of(sc, name)[0]
        parts += [f"d_{name}[{p}]={d[p]:+.4g}" for p in range(space.pieces)]
    return ", ".join(parts) if parts else "the one scenario (one start, one run)"


def _scenario_record(space: Any, z: np.ndarray) -> dict:
    sc = space.decode(z[None, :])
    return {
        "run": int(sc.run[0]),
        "start": {n: float(sc.x0[0, i]) for i, n in enumerate(space.state_names)},
        "params": {n: float(v[0]) for n, v in sc.params.items()},
        "disturbance": {n: [float(v) for v in space.disturbance_of(sc, n)[0]] for n, _ in space.disturb},
    }


def _prepare_out(out: str) -> Path:
    """``--out``: a folder (made if missing); its old counterexample files go (they were another
    verification's). Refused, one line, when it is a file or cannot be written."""
    from mitlc.fileio import check_writable

    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise InputError("not a folder", file=f"--out {out}")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot make the folder: {exc.strerror}", file=f"--out {out}") from None
    check_writable(folder / REPORT, f"--out {out}")
    return folder


def _write_counterexamples(folder: Path, spec: Any, space: Any, judged: Any, order: np.ndarray) -> list[dict]:
    """Each chosen rollout as ``cex_NNN.npz`` (a trace ``mitlc check`` reads, with its inputs, start,
    parameters and disturbance) and ``cex_NNN.png``; the scenarios together in counterexamples.npz."""
    from mitlc.fileio import atomic_write, save_npz
    from mitlc.monitor.trace import write_trace
    from mitlc.verify.plots import counterexample_png

    plant = spec.plant
    (folder / REPORT).unlink(missing_ok=True)  # written last, anew: until then the folder reads as unfinished
    from mitlc.cli.reports.verification import is_verification_page

    if is_verification_page(folder / "report.html"):  # an earlier verification's page, rewritten at the end
        (folder / "report.html").unlink(missing_ok=True)
    for old in sorted(folder.iterdir()):  # a previous verification's: they would read as this one's
        if re.fullmatch(r"cex_\d{3,}\.(npz|png)", old.name) and old.is_file():
            old.unlink(missing_ok=True)
    records = []
    t = np.arange(judged.states.shape[1]) * judged.dt
    sc = space.decode(judged.z[order]) if len(order) else None
    for k, i in enumerate(order):
        name = f"cex_{k:03d}"
        acts = judged.actions[i]
        cols = acts[:, None] if acts.ndim == 1 else acts
        extra: dict[str, np.ndarray] = {}
        if plant.inputs is None:
            extra["u"] = acts
        else:
            extra.update({f"u_{n}": cols[:, j] for j, n in enumerate(plant.input_names)})
        assert sc is not None
        extra.update({f"param_{n}": np.array(v[k]) for n, v in sc.params.items()})
        extra.update({f"start_{n}": np.array(sc.x0[k, j]) for j, n in enumerate(space.state_names)})
        extra["run"] = np.array(sc.run[k])
        for n, _ in space.disturb:
            extra[f"disturbance_{n}"] = space.disturbance_of(sc, n)[k]
        columns = {n: judged.states[i, :, j] for j, n in enumerate(plant.state_names)}
        write_trace(folder / f"{name}.npz", t, columns, extra)
        res = judged.result
        vt = float(res.violation_time[i])
        title = (
            f"{name}: robustness {res.robustness[i]:+.4g}, violated at t={vt:.2f} s ({res.failing[i]})\n"
            + _scenario_text(space, judged.z[i])
        )
        periodic = [v.name for v in plant.state if v.periodic]
        png = counterexample_png(
            judged.states[i], acts, judged.dt, plant.state_names, plant.input_names, title, vt, periodic
        )
        atomic_write(folder / f"{name}.png", png)
        records.append(
            {
                "trace": f"{name}.npz",
                "plot": f"{name}.png",
                "robustness": float(res.robustness[i]),
                "violation_time": vt,
                "failing": res.failing[i],
                **_scenario_record(space, judged.z[i]),
            }
        )
    chosen = judged.z[order] if len(order) else np.zeros((0, space.dim))
    sc_all = space.decode(chosen) if len(order) else None
    arrays: dict[str, np.ndarray] = {
        "z": chosen,
        "coordinates": np.array(space.names, dtype=str),
        "state_names": np.array(space.state_names, dtype=str),
        "x0": sc_all.x0 if sc_all is not None else np.zeros((0, len(space.state_names))),
        "run": sc_all.run if sc_all is not None else np.zeros(0, dtype=np.int64),
        "robustness": judged.result.robustness[order],
    }
    for n, _, _ in space.vary:
        arrays[f"param_{n}"] = sc_all.params[n] if sc_all is not None else np.zeros(0)
    for n, _ in space.disturb:
        arrays[f"disturbance_{n}"] = (
            space.disturbance_of(sc_all, n) if sc_all is not None else np.zeros((0, space.pieces))
        )
    save_npz(folder / STARTS, arrays)
    return records


def _check_method(method: str) -> None:
    """``--method de`` needs scipy and ``cma`` the cma package: one line saying how to install them."""
    import importlib.util

    needed = {"de": "scipy", "cma": "cma"}[method]
    if importlib.util.find_spec(needed) is None:
        raise InputError(
            f"--method {method} needs the {needed} package: pip install 'mitlc[verify]' (or --method uniform)",
            file="--method",
        )


@click.command("verify")
@click.option(
    "--policy",
    "policy_dir",
    type=click.Path(exists=True),
    metavar="DIR|MODEL.zip",
    required=True,
    help="Directory written by 'mitlc train' (SACPN, HyRL, or --learner sac where Stable-Baselines3 is "
    "installed), or a Stable-Baselines3 model .zip trained on a mitlc environment (with --spec).",
)
@click.option(
    "--spec",
    "spec_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Judge by this spec (file or shipped name; the same plant as the policy's), and sample its init box "
    "(default: the spec the policy was trained on).",
)
@click.option(
    "--samples",
    type=click.IntRange(1, 10**7),
    default=1000,
    show_default=True,
    help="Scenarios drawn uniformly for the statistical bound.",
)
@click.option(
    "--budget",
    type=click.IntRange(0, 10**7),
    default=1000,
    show_default=True,
    help="Rollouts the falsifier may spend searching for a violation (0: no falsification).",
)
@click.option(
    "--method",
    type=click.Choice(["de", "cma", "uniform"]),
    default="de",
    show_default=True,
    help="The falsifier: de, scipy's differential evolution (the surest on a planted weakness, mitlc docs "
    "verify); cma, CMA-ES (the cma package); uniform, more uniform samples.",
)
@click.option(
    "--vary",
    multiple=True,
    metavar="NAME=LO:HI",
    help="Draw plant parameter NAME from [LO, HI] per rollout (repeat for more), e.g. M=0.4:0.6.",
)
@click.option(
    "--disturb",
    multiple=True,
    metavar="NAME=EPS",
    help="Add a disturbance in [-EPS, EPS] to input NAME (u, or a declared input's name), or to the rate of "
    "state variable NAME, constant over each of --pieces spans of the horizon (repeat for more).",
)
@click.option(
    "--pieces",
    type=click.IntRange(1, 100),
    default=1,
    show_default=True,
    help="Spans of the horizon a disturbance is constant over.",
)
@click.option(
    "--require",
    type=click.FloatRange(0.0, 1.0, min_open=True),
    default=None,
    help="Exit 1 unless the lower bound on the satisfied probability is at least this (e.g. 0.99).",
)
@click.option(
    "--confidence",
    type=click.FloatRange(0.0, 1.0, min_open=True, max_open=True),
    default=0.95,
    show_default=True,
    help="Confidence of the one-sided Clopper-Pearson lower bound.",
)
@click.option(
    "--seed",
    type=click.IntRange(0, 2**63 - 1),
    default=0,
    show_default=True,
    help="Seed of the samples and of the falsifier.",
)
@click.option(
    "--keep",
    type=click.IntRange(0, 1000),
    default=3,
    show_default=True,
    help="Counterexamples written to --out: the least robust violating rollouts.",
)
@click.option(
    "--out",
    type=click.Path(),
    default=None,
    metavar="DIR",
    help="Folder for report.json, counterexamples.npz, the counterexamples' traces (cex_NNN.npz, read by "
    "'mitlc check OUT/spec.mitl OUT/cex_000.npz') and figures; without it nothing is written.",
)
@click.option(
    "--no-report",
    is_flag=True,
    help="Skip OUT/report.html, the verification as one HTML page (mitlc docs report).",
)
@plant_file_option
@handle_errors
def verify(
    policy_dir,
    spec_path,
    samples,
    budget,
    method,
    vary,
    disturb,
    pieces,
    require,
    confidence,
    seed,
    keep,
    out,
    no_report,
) -> None:
    """Check a trained policy against its spec: a sampled bound and a search for counterexamples.

    Rolls the policy out from --samples scenarios drawn from the spec's init box (and the --vary
    and --disturb ranges), judges each by the monitor, and reports the satisfied fraction with its
    exact one-sided Clopper-Pearson lower bound; then --budget rollouts search for the least robust
    scenario. Exit 0: nothing violated and the bound meets --require; 1: a counterexample, or the
    bound falls short; 2: bad input."""
    from mitlc.cli.memory import keep_freed_memory
    from mitlc.fileio import atomic_write, json_text
    from mitlc.verify import SearchSpace, parse_disturb, parse_vary
    from mitlc.verify.rollout import base_params, check_batched_params, check_plant
    from mitlc.verify.run import verify_policy

    keep_freed_memory()
    policy = _load_policy(policy_dir, spec_path)
    spec = _judging_spec(policy, spec_path)
    plant = spec.plant
    check_plant(plant)
    runs = int(getattr(policy, "runs", 1))
    space = SearchSpace.of(spec, parse_vary(vary, spec), parse_disturb(disturb, spec), pieces, runs)
    check_batched_params(plant, base_params(spec, policy.dt), space.vary)
    steps = _steps(policy, spec)
    if method != "uniform" and budget > 0:  # the falsifier's package, before any rollout
        _check_method(method)
    if out is not None and Path(out).resolve() == Path(policy_dir).resolve():
        raise InputError("the policy's own folder: give the verification a folder of its own", file=f"--out {out}")
    folder = _prepare_out(out) if out is not None else None  # the input is sound: only now is anything made
    outcome = verify_policy(policy, spec, space, steps, samples, budget, method, seed, keep, confidence)
    sampled, search = outcome.sampled, outcome.search
    k, bound = sampled.satisfied, sampled.lower_bound
    formula = spec.monitor_formula
    extra = []
    if space.vary:
        extra.append("parameters " + ", ".join(f"{n} in [{lo:g}, {hi:g}]" for n, lo, hi in space.vary))
    if space.disturb:
        extra.append("disturbance " + ", ".join(f"|d_{n}| <= {e:g}" for n, e in space.disturb))
    drawn = "scenarios drawn from the init box" + (f" with {'; '.join(extra)}" if extra else "") + f", seed {seed}"
    click.echo(
        f"sampled: {k}/{samples} rollouts satisfy {formula} ({drawn}); {k / samples:.1%} satisfied, "
        f"{confidence:.0%} lower bound {bound:.4f} (Clopper-Pearson, one-sided)"
    )
    click.echo(
        f"least robust sample: robustness {sampled.least_robustness:+.4g} at {_scenario_text(space, sampled.least_z)}"
    )
    if search is not None and search.rollouts:
        least = int(np.argmin(np.nan_to_num(search.robustness, nan=-np.inf)))
        where = f"robustness {search.robustness[least]:+.4g} at {_scenario_text(space, search.z[least])}"
        took = f"(searched in {outcome.search_seconds:.1f} s)"
        if search.found:
            click.echo(
                f"falsified ({method}, from the least robust sample): the first counterexample after "
                f"{search.first} of {search.rollouts} rollouts; the least robust: {where} {took}"
            )
        else:
            click.echo(
                f"not falsified ({method}, from the least robust sample): no counterexample in "
                f"{search.rollouts} rollouts; the least robust: {where} {took}"
            )

    violated = outcome.counterexamples
    order = np.arange(0 if violated is None else violated.z.shape[0])
    falsified = outcome.violations > 0
    short = require is not None and bound < require
    status = 1 if falsified or short else 0
    reasons = []
    if falsified:
        n = outcome.violations
        reasons.append(f"{n} rollout{'s' if n != 1 else ''} violated the spec")
    if short:
        reasons.append(f"the lower bound {bound:.4f} is below --require {require:g}")
    if require is not None and not short:
        reasons.append(f"the lower bound {bound:.4f} meets --require {require:g}")

    if folder is not None:
        records = (
            _write_counterexamples(folder, spec, space, violated, order)
            if violated is not None
            else _write_counterexamples(folder, spec, space, _empty(space, steps, policy.dt, plant), order)
        )
        atomic_write(folder / SPEC_COPY, spec.source or str(formula) + "\n")
        report = {
            "format": "mitlc-verify",
            "policy": str(policy_dir),
            "spec": spec.path,
            "formula": str(formula),
            "seed": seed,
            "space": {
                "coordinates": list(space.names),
                "init": {
                    n: [lo, hi] for n, lo, hi in zip(space.state_names, space.init_lo, space.init_hi, strict=True)
                },
                "vary": {n: [lo, hi] for n, lo, hi in space.vary},
                "disturb": {n: e for n, e in space.disturb},
                "pieces": space.pieces,
            },
            "steps": steps,
            "dt": float(policy.dt),
            "sampling": {
                "samples": samples,
                "satisfied": k,
                "fraction": k / samples,
                "confidence": confidence,
                "lower_bound": bound,
                "least_robust": {
                    "robustness": sampled.least_robustness,
                    **_scenario_record(space, sampled.least_z),
                },
                "seconds": round(sampled.seconds, 3),
            },
            "falsification": None
            if search is None
            else {
                "method": method,
                "budget": budget,
                "rollouts": search.rollouts,
                "found": search.found,
                "first_counterexample_after": search.first,
                "least_robustness": float(np.min(search.robustness)) if search.rollouts else None,
                "seconds": round(outcome.search_seconds, 3),
            },
            "require": require,
            "violating_rollouts": outcome.violations,
            "counterexamples": records,
            "exit_status": status,
        }
        atomic_write(folder / REPORT, json_text(report, indent=1))
        if records:
            click.echo(
                f"wrote {len(records)} counterexample{'s' if len(records) != 1 else ''} to {folder} "
                f"(mitlc check {folder / SPEC_COPY} {folder / records[0]['trace']})"
            )
        from mitlc.cli.report import after_verification

        after_verification(folder, not no_report)
    verdict = "FAILED" if status else "passed"
    click.echo(f"verify: {verdict}" + (f": {'; '.join(reasons)}" if reasons else ""))
    if status:
        click.get_current_context().exit(1)


def _empty(space: Any, steps: int, dt: float, plant: Any) -> Any:
    """No rollout: what :func:`_write_counterexamples` writes when nothing was violated (an empty
    counterexamples.npz, and the old traces cleared)."""
    from mitlc.monitor.offline import MonitorResult
    from mitlc.verify.rollout import Judged

    m = plant.n_inputs
    n = len(space.state_names)
    empty = MonitorResult(np.zeros(0, bool), np.zeros(0), np.zeros(0), ())
    return Judged(
        np.zeros((0, space.dim)),
        np.zeros((0, steps + 1, n)),
        np.zeros((0, steps) if m == 1 else (0, steps, m)),
        dt,
        empty,
    )
