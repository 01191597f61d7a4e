"""Train every task of the suite at the product's defaults and write docs/suite.md.

The suite (bench/suite/, its README) is a set of specs on several plants, each with a
witness: a fixed controller the monitor accepts from starts spread over the spec's init
box, so every task is known to be satisfiable. This script trains each task as
``mitlc train --spec TASK --seed S`` does (the same settings, compile options, runs and
trials: whatever the defaults are when it runs) for each seed, and records per training:

* **success**: the fraction of runs whose final greedy policy the monitor accepts from the
  run's evaluation start, the number ``mitlc train`` prints;
* **fresh**: the same policies judged from ``FRESH`` starts each, drawn over the init box
  (a policy that works from one start only is not what a user wants);
* **curve**: the success from fixed starts every tenth of the trials, from which the page
  gives the trials to reach 0.8 (the first tenth at which the seeds' mean reaches it);
* the training's wall time, and the witness's verdicts (accepted starts / starts).

It is also the tool defaults are chosen with: ``--set NAME=VALUE`` (any SACPN setting),
``--option NAME=VALUE`` (a compile option: reward, violations, clock, conjunction) and
``--trials N`` train every task with that change, ``--half tuning`` restricts to the tuning
half, and ``--results FILE`` keeps such trials away from the docs page. Trainings are kept
under ``bench/suite/.cache/`` (by the code's digest, the task, the seed and the change): a
stopped run resumes where it stopped, and a second run of the same command trains nothing.

    python bench/suite.py                        # every task, 3 seeds: docs/suite.md and .json, README's block
    python bench/suite.py --task cart_out_and_home --seeds 1
    python bench/suite.py --half tuning --set rbf_width=0.5 --results /tmp/width.json
    python bench/suite.py --render               # the page again from docs/suite.json
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "docs"))  # results_stats: the docs scripts' interval and machine line

from results_stats import code_digest, interval, machine, run_cached  # noqa: E402

from bench.suite import load_tasks, rollout  # noqa: E402  (the package bench/suite/, beside this script)
from mitlc.fileio import atomic_write, json_text, write_block  # noqa: E402

SPLIT = ROOT / "bench" / "suite" / "split.json"


def halves() -> dict[str, list[str]]:
    """The tuning and check halves, as bench/suite/split.json recorded the draw."""
    split = json.loads(SPLIT.read_text(encoding="utf-8"))
    return {"tuning": list(split["tuning"]), "check": list(split["check"])}


COMMAND = "python bench/suite.py"
SEEDS = (0, 1, 2)
FRESH = 5
"""Fresh starts per run for the ``fresh`` success."""
CURVE_POINTS = 10
PAGE = ROOT / "docs" / "suite.md"
DATA = ROOT / "docs" / "suite.json"
CACHE = ROOT / "bench" / "suite" / ".cache"
TARGET = 0.8
"""The success the page counts trials to."""


def default_trials() -> int:
    """``mitlc train``'s default trial count for SACPN (the learner the suite trains by default)."""
    from mitlc.cli.train import TRIALS

    return TRIALS


def default_runs() -> int:
    from mitlc.cli.train import train

    return int(next(p.default for p in train.params if p.name == "runs"))


def _fresh_starts(agent, n: int, seed: int) -> np.ndarray:
    """``n`` starts per run (rows ``b`` use run ``b % R``), from the init box or the environment's
    resets, on a stream of their own (the training's streams are left alone)."""
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence([seed, 31]).spawn(n * agent.runs)]
    return agent.sample_init(rngs)


def train_task(job: tuple) -> dict:
    """One training of one task, as ``mitlc train`` builds it; the record the page reads."""
    name, spec_path, seed, runs, trials, sets, options, *more = job
    workers = int(more[1]) if len(more) > 1 else 1  # processes a search's runs are trained in (the same numbers)
    if more and more[0] == "sac":
        return train_sac_task(job)
    if more and more[0] == "search":
        return train_search_task(job)
    from mitlc.cli.train import _judge, _monitor_judge
    from mitlc.learn.sacpn import SacpnSettings
    from mitlc.learn.search import SearchRuns, SearchSettings
    from mitlc.learn.settings import parse_assignments
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.spec.parse import load_spec
    from mitlc.sweep.race import greedy_verdicts, race, search_designs_for, search_generations
    from mitlc.sweep.task import sacpn_learner

    spec = load_spec(spec_path)
    settings = SacpnSettings(**parse_assignments(SacpnSettings, list(sets)))
    compile_options = CompileOptions.from_spec(spec, **dict(options))
    rs = compile_spec(spec, compile_options)

    def build(st: SacpnSettings, r: int, s: int):  # as mitlc train builds one
        return sacpn_learner(rs, st, r, s)

    def searcher(
        r: int, changes: dict
    ):  # as mitlc train races the policy search: runs 0 .. r - 1 of the training's seed
        return SearchRuns(rs, r, seed, SearchSettings(**changes), _monitor_judge(spec), workers=workers)

    t0 = time.perf_counter()
    given = {a.split("=", 1)[0] for a in sets}
    can_search = not sets  # as mitlc train: no SACPN setting given
    raced = race(
        build,
        greedy_verdicts,
        settings,
        runs,
        trials,
        seed,
        given=given,
        search=searcher if can_search else None,
        generations=search_generations(trials),
        search_designs=search_designs_for(spec.monitor_formula),
        workers=workers,
    )  # as mitlc train
    race_s = time.perf_counter() - t0
    if raced is not None and raced.learner == "search":
        return _search_won(name, spec, raced, runs, trials, seed, sets, options, t0, race_s)
    if raced is not None:
        settings = raced.settings
    agent = build(settings, runs, seed)
    every = max(1, trials // CURVE_POINTS)
    curve: list[tuple[int, float]] = []
    spent = [0.0]

    def judge_now(trial: int, _returns: np.ndarray) -> None:
        if trial % every == 0 or trial == trials:
            t0 = time.perf_counter()
            # the curve's starts: one per run, the same each time (drawn again just before the rollout:
            # an environment rolls out from the states its last reset returned)
            ok = _judge(spec, agent.rollout(_fresh_starts(agent, 1, seed + 1000))).satisfied
            curve.append((trial, float(np.mean(ok))))
            spent[0] += time.perf_counter() - t0

    agent.train(trials, callback=judge_now, total=trials)
    wall = time.perf_counter() - t0 - spent[0]  # the race included
    judged = _judge(spec, agent.rollout(agent.evaluation_states()))  # as mitlc train judges
    final = judged.satisfied
    failing = [str(f) for f in judged.failing if f is not None]  # the part each failed run broke
    fresh = _judge(spec, agent.rollout(_fresh_starts(agent, FRESH, seed))).satisfied
    return {
        "job": f"{name} seed {seed}",
        "task": name,
        "seed": seed,
        "runs": runs,
        "trials": trials,
        "sets": list(sets),
        "options": dict(options),
        "kernel": agent.kernel,
        "success": float(np.mean(final)),
        "fresh": float(np.mean(fresh)),
        "curve": curve,
        "wall_s": round(wall, 2),
        "diverged": int(np.sum(agent.diverged >= 0)),
        "race": raced.record() if raced is not None else None,
        "failing": {f: failing.count(f) for f in sorted(set(failing))},
        "race_s": round(race_s, 2),
    }


def _search_won(name, spec, raced, runs, trials, seed, sets, options, t0, race_s) -> dict:
    """The rest of a training whose race the policy search won, as ``mitlc train`` goes on: the race's
    search runs kept, the others searched and joined to them; the record the page reads."""
    from mitlc.cli.train import _judge
    from mitlc.learn.search import SearchRuns

    kept = raced.searched
    agent = kept
    if runs > kept.runs:
        rest = SearchRuns(
            kept.rs, runs - kept.runs, seed, kept.settings, kept.judge, first=kept.runs, workers=kept.workers
        )
        rest.train(raced.generations)
        agent = kept.joined(rest)
    agent.restart_failed(raced.generations)  # as mitlc train: the runs that fail their check searched again
    wall = time.perf_counter() - t0
    judged = _judge(spec, agent.rollout(agent.evaluation_states()))
    failing = [str(f) for f in judged.failing if f is not None]
    fresh = _judge(spec, agent.rollout(_draw_fresh(agent, seed))).satisfied
    return {
        "job": f"{name} seed {seed}",
        "task": name,
        "seed": seed,
        "runs": runs,
        "trials": trials,
        "learner": "search",
        "generations": raced.generations,
        "sets": list(sets),
        "options": dict(options),
        "kernel": False,
        "success": float(np.mean(judged.satisfied)),
        "fresh": float(np.mean(fresh)),
        "curve": [],
        "wall_s": round(wall, 2),
        "diverged": 0,
        "race": raced.record(),
        "failing": {f: failing.count(f) for f in sorted(set(failing))},
        "race_s": round(race_s, 2),
        "restarted": {"runs": agent.restarted, "kept": agent.kept_restarts},
    }


def _draw_fresh(agent, seed: int) -> np.ndarray:
    """:data:`FRESH` starts per run from the init box for a search (as the SAC and search records draw them);
    an environment's resets where the search ran on one."""
    from mitlc.cli.train import _draw_starts

    if not agent.settable:
        return _fresh_starts(agent, FRESH, seed)

    return _draw_starts(agent.init_ranges, FRESH * agent.runs, seed + 31)


def train_sac_task(job: tuple) -> dict:
    """One training of one task as ``mitlc train --learner sac`` trains it (SAC run by run, no race;
    ``trials`` None: its default of about 20,000 samples per run); the record the page reads."""
    name, spec_path, seed, runs, trials, sets, options, *_ = job
    from mitlc.cli.train import _draw_starts, _judge
    from mitlc.gym.sac import SacRuns, SacSettings, default_trials
    from mitlc.learn.settings import parse_assignments
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.spec.parse import load_spec

    spec = load_spec(spec_path)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, **dict(options)))
    agent = SacRuns(rs, runs, seed, SacSettings(**parse_assignments(SacSettings, list(sets))))
    trials = trials or default_trials(agent.n_steps)
    t0 = time.perf_counter()
    agent.train(trials)
    wall = time.perf_counter() - t0
    judged = _judge(spec, agent.rollout(agent.evaluation_states()))
    failing = [str(f) for f in judged.failing if f is not None]
    fresh = _judge(spec, agent.rollout(_draw_starts(agent.init_ranges, FRESH * runs, seed + 31))).satisfied
    return {
        "job": f"{name} seed {seed}",
        "task": name,
        "seed": seed,
        "runs": runs,
        "trials": trials,
        "learner": "sac",
        "sets": list(sets),
        "options": dict(options),
        "kernel": False,
        "success": float(np.mean(judged.satisfied)),
        "fresh": float(np.mean(fresh)),
        "curve": [],
        "wall_s": round(wall, 2),
        "diverged": 0,
        "race": None,
        "failing": {f: failing.count(f) for f in sorted(set(failing))},
        "race_s": 0.0,
    }


def train_search_task(job: tuple) -> dict:
    """One training of one task by :mod:`mitlc.learn.search` (CMA-ES over a time-varying linear
    feedback, judged by the monitor; ``trials`` None: its default generations); the record the page reads."""
    name, spec_path, seed, runs, trials, sets, options, *more = job
    workers = int(more[1]) if len(more) > 1 else 1
    from mitlc.cli.train import _judge, _monitor_judge
    from mitlc.learn.search import SearchRuns, SearchSettings, default_generations
    from mitlc.learn.settings import parse_assignments
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.spec.parse import load_spec

    spec = load_spec(spec_path)
    rs = compile_spec(spec, CompileOptions.from_spec(spec, **dict(options)))

    settings = SearchSettings(**parse_assignments(SearchSettings, list(sets)))
    agent = SearchRuns(rs, runs, seed, settings, _monitor_judge(spec), workers=workers)  # as mitlc train judges
    trials = trials or default_generations(agent.n_steps)
    t0 = time.perf_counter()
    agent.train(trials)
    agent.restart_failed(trials)
    wall = time.perf_counter() - t0
    judged = _judge(spec, agent.rollout(agent.evaluation_states()))
    failing = [str(f) for f in judged.failing if f is not None]
    fresh = _judge(spec, agent.rollout(_draw_fresh(agent, seed))).satisfied
    return {
        "job": f"{name} seed {seed}",
        "task": name,
        "seed": seed,
        "runs": runs,
        "trials": trials,
        "learner": "search",
        "sets": list(sets),
        "options": dict(options),
        "kernel": False,
        "success": float(np.mean(judged.satisfied)),
        "fresh": float(np.mean(fresh)),
        "curve": [],
        "wall_s": round(wall, 2),
        "diverged": 0,
        "race": None,
        "failing": {f: failing.count(f) for f in sorted(set(failing))},
        "race_s": 0.0,
        "restarted": {"runs": agent.restarted, "kept": agent.kept_restarts},
    }


def _trials(data: dict) -> str:
    """The trials of a run's trainings (None: each learner's own default; a search's are generations)."""
    if data["trials"] is None:
        return f"the {data.get('learner', 'sacpn')} learner's default trials"
    return f"{data['trials']} {'generations' if data.get('learner') == 'search' else 'trials'}"


def _change_key(sets: tuple[str, ...], options: tuple[tuple[str, str], ...], trials: int | None) -> str:
    text = json.dumps({"sets": sorted(sets), "options": sorted(options), "trials": trials})
    return hashlib.sha256(text.encode()).hexdigest()[:10]


def run(args: argparse.Namespace) -> dict:
    chosen = list(load_tasks())
    if args.task:
        known = {t.name for t in chosen}
        unknown = [n for n in args.task if n not in known]
        if unknown:
            raise SystemExit(f"bench/suite.py: unknown task {', '.join(unknown)} (known: {', '.join(sorted(known))})")
        chosen = [t for t in chosen if t.name in args.task]
    split = halves()
    if args.half:
        chosen = [t for t in chosen if t.name in split[args.half]]
    sets = tuple(args.set)
    options = tuple(tuple(o.split("=", 1)) for o in args.option)
    runs = args.runs or default_runs()
    trials = args.trials or default_trials()
    seeds = tuple(range(args.seeds)) if args.seeds else SEEDS
    if args.learner in ("sac", "search"):
        trials = args.trials  # None: the learner's own default, per task
    if args.learner == "search":  # candidates roll out from chosen starts: not a self-resetting environment
        skipped = [t.name for t in chosen if t.spec.plant is not None and t.spec.plant.stepped]
        if skipped:
            print(f"--learner search: skipping {', '.join(skipped)} (Gymnasium environments)", flush=True)
        chosen = [t for t in chosen if t.name not in skipped]
    jobs = [
        (t.name, str(t.spec_path), s, runs, trials, sets, options, args.learner, args.workers)
        for t in chosen
        for s in seeds
    ]
    digest = code_digest(__file__)[:12]
    key = _change_key(sets, options, args.trials) + ("" if args.learner == "sacpn" else f"-{args.learner}")
    key += f"-w{args.workers}" if args.workers > 1 else ""  # the same numbers, other wall times
    records, kept = run_cached(
        train_task,
        jobs,
        args.jobs,
        CACHE,
        lambda job: f"{digest}-{key}-{job[0]}-r{job[3]}-t{job[4]}-s{job[2]}.json",
    )
    print(f"{len(records)} trainings ({kept} kept from earlier runs)", flush=True)
    witness = {}
    for t in chosen:  # the witness from starts spread over the init box (bench/suite/tasks.py)
        verdicts = rollout(t).judge().satisfied
        witness[t.name] = [int(verdicts.sum()), int(verdicts.size)]
    return {
        "command": " ".join([COMMAND, *sys.argv[1:]]),
        "machine": machine("numba", "gymnasium"),
        "code": digest,
        "runs": runs,
        "trials": trials,
        "learner": args.learner,
        "seeds": list(seeds),
        "sets": list(sets),
        "options": dict(options),
        "halves": split,
        "tasks": {
            t.name: {
                "plant": t.spec.plant_name,
                "description": t.description,
                "families": list(t.families),
                "nested": t.nested,
                "witness": witness[t.name],
                "records": [r for r in records if r["task"] == t.name],
            }
            for t in chosen
        },
    }


# ---------------------------------------------------------------- the page


def _pm(values: list[float]) -> str:
    m, h = interval(values)
    return f"{m:.2f}" if math.isnan(h) else f"{m:.2f} ± {h:.2f}"


def _trials_to(records: list[dict], target: float = TARGET) -> str:
    """The first curve point at which the seeds' mean success reaches ``target``, or '-'."""
    if not records:
        return "-"
    points = sorted({k for r in records for k, _ in r["curve"]})
    for k in points:
        at = [dict(map(tuple, r["curve"])).get(k) for r in records]
        if all(v is not None for v in at) and float(np.mean(at)) >= target:
            return str(k)
    return "-"


def summary(data: dict, names: list[str]) -> dict:
    means = [float(np.mean([r["success"] for r in data["tasks"][n]["records"]])) for n in names]
    return {
        "tasks": len(names),
        "mean": float(np.mean(means)) if means else math.nan,
        "at_least_0.9": sum(m >= 0.9 for m in means),
        "below_0.5": [n for n, m in zip(names, means, strict=True) if m < 0.5],
    }


def _won(records: list[dict]) -> str:
    """The race's winners over the seeds: ``sigma_frac=1 rbf_width=0.5 x2, ...``, or '-' without a race."""
    names = [r["race"]["winner"] for r in records if r.get("race")]
    if not names:
        return "-"
    return ", ".join(f"{n} x{names.count(n)}" for n in sorted(set(names), key=lambda n: (-names.count(n), n)))


def _misses(data: dict, names: list[str]) -> list[str]:
    """Per task under 0.9: the parts of the formula its failed controllers broke (the monitor's
    smallest failing subformula, counted over every seed's runs) and the race's winners."""
    out = []
    for n in names:
        recs = data["tasks"][n]["records"]
        if float(np.mean([r["success"] for r in recs])) >= 0.9:
            continue
        counts: dict[str, int] = {}
        for r in recs:
            for part, k in (r.get("failing") or {}).items():
                counts[part] = counts.get(part, 0) + k
        failed = sum(counts.values())
        parts = ", ".join(f"`{p}` {k}" for p, k in sorted(counts.items(), key=lambda kv: -kv[1])[:3])
        races = [r["race"]["designs"] for r in recs if r.get("race")]
        if races and all([e["name"] for e in d] == [e["name"] for e in races[0]] for d in races):
            names = ", ".join(e["name"] for e in races[0])
            race = " / ".join(" ".join(f"{e['success']:.2f}" for e in d) for d in races)
            race = f"; race success per design by seed ({names}): {race}"
        elif races:  # a seed's race stopped at a design that satisfied on every race run
            each = (", ".join(f"{e['name']} {e['success']:.2f}" for e in d) for d in races)
            race = "; race success by seed: " + " / ".join(each)
        else:
            race = ""
        broke = parts or "nothing the monitor names"
        out.append(f"- `{n}`: {failed} failed runs over {len(recs)} seeds broke {broke}{race}")
    if out:
        out = ["", "Where it misses (under 0.9), measured:", "", *out]
    return out


README_BEGIN, README_END = "<!-- suite:begin -->", "<!-- suite:end -->"


def readme_block(data: dict) -> str:
    """README.md's lines on the suite, between its markers: each half's summary, from the page's data."""
    present = set(data["tasks"])
    parts = []
    for half in ("tuning", "check"):
        names = [n for n in data["halves"][half] if n in present]
        if names:
            s = summary(data, names)
            parts.append(
                f"the {half} half {s['mean']:.2f} mean success, "
                f"{s['at_least_0.9']} of {s['tasks']} tasks at 0.9 or more"
            )
    return (
        f"{README_BEGIN}\n"
        f"At these defaults, {data['runs']} runs x {data['trials']} trials over seeds "
        f"{', '.join(map(str, data['seeds']))}: {'; '.join(parts)} "
        f"(`{data['command']}`; [docs/suite.md](docs/suite.md) has every task, and which miss and why).\n"
        f"{README_END}\n"
    )


def render(data: dict) -> str:
    lines = [
        "# The task suite: specs nobody tuned for, trained at the defaults",
        "",
        "<!-- written by bench/suite.py; edit the script, not this page -->",
        "",
        "Each task is a spec on one of the shipped plants (or a Gymnasium environment) with a",
        "*witness*, a fixed controller that the monitor accepts from starts spread over the spec's",
        "initial set: every task is known to be satisfiable. `bench/suite.py` trains each one as",
        "`mitlc train --spec TASK --seed S` does, at whatever the defaults are, and judges the",
        "final greedy policies with the monitor. The tasks were split once, by a seeded draw",
        "(`bench/suite/split.json`), into a **tuning** half, on which defaults are chosen, and a",
        "**check** half, which only reports.",
        "",
        f"Made by `{data['command']}` on {data['machine']} (code {data['code']}): "
        f"{data['runs']} runs x {_trials(data)} per training, seeds {', '.join(map(str, data['seeds']))}"
        + (f"; settings changed: {', '.join(data['sets'])}" if data["sets"] else "")
        + (f"; options: {', '.join(f'{k}={v}' for k, v in data['options'].items())}" if data["options"] else "")
        + ".",
        "",
        "**success**: the fraction of runs whose final greedy policy satisfies the spec from the run's",
        "evaluation start (what `mitlc train` prints), the mean over seeds with its 95 % interval;",
        f"**fresh**: the same policies from {FRESH} starts each drawn over the initial set; **trials",
        f"to {TARGET}**: the first tenth of a SACPN training at which the seeds' mean success (from fixed",
        "starts) reaches it (`-` too where the policy search won a seed's race: it is judged at its",
        "end only); **s**: a training's wall time, the race included; **witness**: starts its",
        "rollouts satisfy; **race won by**: the design `mitlc train`'s race chose, per seed: one of",
        "SACPN's exploration designs or `search`, the policy search (docs/training.md, the race).",
        "",
        "| half | tasks | mean success | tasks >= 0.9 | tasks < 0.5 |",
        "| --- | ---: | ---: | ---: | --- |",
    ]
    present = set(data["tasks"])
    for half in ("tuning", "check"):
        names = [n for n in data["halves"][half] if n in present]
        if not names:
            continue
        s = summary(data, names)
        lines.append(
            f"| {half} | {s['tasks']} | {s['mean']:.2f} | {s['at_least_0.9']} of {s['tasks']} | "
            f"{', '.join(s['below_0.5']) or 'none'} |"
        )
    for half in ("tuning", "check"):
        names = [n for n in data["halves"][half] if n in present]
        if not names:
            continue
        lines += [
            "",
            f"## The {half} half",
            "",
            f"| task | plant | families | success | fresh | trials to {TARGET} | s | witness | race won by |",
            "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- |",
        ]
        for n in names:
            t = data["tasks"][n]
            recs = t["records"]
            fam = ", ".join(t["families"]) + (" (nested)" if t["nested"] else "")
            ok, total = t["witness"]
            wall = float(np.mean([r["wall_s"] for r in recs]))
            lines.append(
                f"| `{n}` | {t['plant']} | {fam} | {_pm([r['success'] for r in recs])} | "
                f"{_pm([r['fresh'] for r in recs])} | {_trials_to(recs)} | {wall:.0f} | {ok}/{total} | {_won(recs)} |"
            )
        lines += ["", "What each task asks:", ""]
        lines += [f"- `{n}`: {data['tasks'][n]['description']}" for n in names]
        lines += _misses(data, names)
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    from mitlc.cli.memory import keep_freed_memory

    keep_freed_memory()  # as mitlc train does: the trainings' wall times are the command's
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", action="append", default=[], help="train this task only (repeat for more)")
    ap.add_argument("--half", choices=("tuning", "check"), help="train one half only")
    ap.add_argument("--seeds", type=int, help=f"seeds 0..N-1 (default {len(SEEDS)})")
    ap.add_argument("--runs", type=int, help="runs per training (default: mitlc train's)")
    ap.add_argument("--trials", type=int, help="trials per run (default: mitlc train's)")
    ap.add_argument("--set", action="append", default=[], help="a SACPN setting NAME=VALUE (repeat)")
    ap.add_argument("--option", action="append", default=[], help="a compile option NAME=VALUE (repeat)")
    ap.add_argument(
        "--learner",
        choices=("sacpn", "sac", "search"),
        default="sacpn",
        help="sac: train as mitlc train --learner sac does; search: mitlc.learn.search's CMA-ES policy search",
    )
    ap.add_argument("--jobs", type=int, default=2, help="trainings at once (default 2)")
    ap.add_argument(
        "--workers",
        type=int,
        default=1,
        help="processes a training's policy search runs in, as mitlc train --workers (default 1: the page's "
        "wall times are a training's on one core beside another; --jobs 1 --workers 2 times each alone on 2 cores)",
    )
    ap.add_argument("--results", type=Path, help="write the results here, not docs/suite.json and the page")
    ap.add_argument("--render", action="store_true", help="write the page again from docs/suite.json")
    args = ap.parse_args(argv)
    if args.render:
        data = json.loads(DATA.read_text(encoding="utf-8"))
        atomic_write(PAGE, render(data))
        write_block(ROOT / "README.md", README_BEGIN, README_END, readme_block(data))
        print(f"wrote {PAGE} and README.md's block")
        return 0
    data = run(args)
    page = render(data)
    if args.results is not None:
        atomic_write(args.results, json_text(data))
        print(page)
        print(f"wrote {args.results}")
        return 0
    if (
        args.task
        or args.half
        or args.set
        or args.option
        or args.trials
        or args.runs
        or args.seeds
        or args.learner != "sacpn"
    ):
        print(page)
        print("(a partial or changed run: docs/suite.md comes from the full default run only; --results keeps it)")
        return 0
    atomic_write(DATA, json_text(data))
    atomic_write(PAGE, page)
    write_block(ROOT / "README.md", README_BEGIN, README_END, readme_block(data))
    print(f"wrote {PAGE}, {DATA} and README.md's block")
    return 0


if __name__ == "__main__":
    sys.exit(main())
