"""A short race between designs before a training: ``mitlc train``'s default.

No one exploration serves every spec (docs/suite.md): a small input noise (``sigma_frac``
0.3 of the input's half-range, Table 4-4's) learns the pendulum's swing-ups and fails to find
a far goal on a heavy cart; a large one (1.0) finds the cart's bay and shakes the pendulum
past its obstacle; only the smallest (0.1) carries the mass-damper across under a speed
limit. Narrow Gaussians (``rbf_width`` 0.5 of the centre spacing) learn the
pendulum's obstacle-avoiding swing-up that width 1 misses, and width 1 holds it up with a
speed limit better. And no SACPN design learns the cart-pole's tasks, the cart's dock or the
unicycle's corridor, which the policy search (:mod:`mitlc.learn.search`) learns; its linear
design misses the swing-ups, which its quadratic one learns. So ``mitlc train`` first trains each
search design of :data:`SEARCH_DESIGNS` on :data:`RACE_RUNS` runs for :func:`search_generations`, then
each SACPN design of :data:`DESIGNS` on the same number of runs for :data:`RACE_SHARE` of the trials,
judges each design's final greedy policies with the monitor (the fraction that satisfy the spec from
their evaluation starts, ties broken by those rollouts' mean return), and trains the full runs with
the winner: after a SACPN design, exactly ``mitlc train --learner sacpn --set sigma_frac=S --set
rbf_width=W`` of the winner (same seed, same numbers); after a search, exactly ``mitlc train
--learner search`` with the design's settings (its race runs are runs ``0 .. r - 1`` of the
training's seed, kept). The first design whose every race run satisfies the spec wins at once, when
there are :data:`EARLY_WIN_RUNS` race runs: the designs after it are not raced (they could at best tie
it), which saves most of the race on the tasks a design masters. metrics.json records the race: each
design's success, the mean return of its greedy rollouts and its wall time (``wall_s``: where a race's
time went).

Settings the user gives are not raced (:func:`designs`), and the search races only when no SACPN
setting is given; ``--no-race`` trains SACPN's defaults straight away.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from mitlc.errors import InputError, TrainingError

__all__ = [
    "DESIGNS",
    "EARLY_WIN_RUNS",
    "RACE_RUNS",
    "RACE_SHARE",
    "Entry",
    "Race",
    "designs",
    "greedy_verdicts",
    "race",
    "race_seed",
    "raced",
    "search_generations",
    "SEARCH",
    "SEARCH_DESIGNS",
    "RESPONSE_DESIGN",
    "search_designs_for",
]

DESIGNS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("sigma_frac=0.3 rbf_width=0.5", {"sigma_frac": 0.3, "rbf_width": 0.5}),
    ("sigma_frac=1 rbf_width=0.5", {"sigma_frac": 1.0, "rbf_width": 0.5}),
    ("sigma_frac=0.3 rbf_width=1", {"sigma_frac": 0.3, "rbf_width": 1.0}),
    ("sigma_frac=1 rbf_width=1", {"sigma_frac": 1.0, "rbf_width": 1.0}),
    ("sigma_frac=0.1 rbf_width=0.5", {"sigma_frac": 0.1, "rbf_width": 0.5}),
)
"""The designs raced: name and the settings each changes (chosen on the task suite's tuning half:
the exploration and the Gaussians' width are where no one value served every task; the fifth,
the smallest noise, learns a carry under a speed limit that every larger noise breaks while it
explores: bench/suite/tuning/6-race-sigma-frac-0.1.json)."""

RACE_RUNS = 8
"""Runs per design in the race at most: a quarter of the training's runs, rounded up, so that the
race costs about two thirds of the training itself whatever the runs (8 for 30 runs, 1 for 2)."""

EARLY_WIN_RUNS = RACE_RUNS
"""Race runs a design must all satisfy the spec on to win at once: with fewer (a training of under 29
runs), a clean sweep says too little (2 of 2 comes 64 % of the time to a design that satisfies 80 %
of its runs), so every design races."""

MIN_FORKED_RUNS = 4
"""The fewest race runs a design races on in a process of its own (``workers`` above 1): a race of fewer
(a training of under 13 runs) is short, and starting processes for it costs more than it saves."""

RACE_SHARE = 0.5
"""The race's trials as a share of the training's."""

SEARCH = "search"
"""The race's name for the policy search (:mod:`mitlc.learn.search`): its designs are judged as
SACPN's are, raced when no SACPN setting was given (on a Gymnasium environment too: a start is a seed)."""

SEARCH_DESIGNS: tuple[tuple[str, dict[str, Any]], ...] = (
    (SEARCH, {}),
    (f"{SEARCH} harmonics=2", {"harmonics": 2}),
    (f"{SEARCH} products=true popsize=32", {"products": True, "popsize": 32}),
    (f"{SEARCH} products=true popsize=32 score=mean", {"products": True, "popsize": 32, "score": "mean"}),
)
"""The policy search's designs in the race, in the order raced: name and the
:class:`mitlc.learn.search.SearchSettings` each changes. Two periodic terms in time learn the cart's
patrol (0.33 -> 0.90 on the tuning half, seed 0) and cost the dock (0.97 -> 0.67); four cost more
than they gain (bench/suite/tuning/10-search-harmonics-2.json, 11-search-harmonics-4.json). Their
period is the spec's, the smallest deadline a ``G`` repeats, where it has one (records 19 and 20). Quadratic
state features with 32 candidates a generation learn the three pendulum tasks of the tuning half that
the linear search misses (0.07, 0.53, 0.00 -> 1.00 each, seed 0) and the unicycle's corridor
(0.90 -> 1.00), and miss the cart's patrol (bench/suite/tuning/17-products-popsize-32.json against
14-search-spec-scale.json); the linear search with 32 candidates alone gains less
(16-popsize-32.json). The last scores a violation by the averaged robustness (``score=mean``): it
learns Gymnasium's pendulum swing-ups, whose robustness is flat (the quadratic search 0.12 -> 1.00 on
the tuning half's gym_pendulum_swing_up_rest, 8 runs), and as every search's score it cost the tasks
the others learn (the cart's patrol 0.98 -> 0.91, the cart-pole's lean response 1.00 -> 0.96 over the
first seeds), so it is raced last, where only tasks no design above sweeps reach it. Each design has
the search's defaults otherwise."""

RESPONSE_DESIGN: tuple[str, dict[str, Any]] = (
    f"{SEARCH} products=true popsize=32 score=credit trigger_starts=0.5",
    {"products": True, "popsize": 32, "score": "credit", "trigger_starts": 0.5},
)
"""The search design raced last, after :data:`SEARCH_DESIGNS`, where the formula asks for a response
(:func:`search_designs_for`): a violated rollout scored by its credit (each response met 1, missed 0, not
asked for one half) and its non-vacuous robustness, which scores ``a -> F[0,d] b`` by ``b`` wherever ``a``
holds (:func:`mitlc.monitor.offline.credit_score`), and half of each generation's training starts drawn
where a response's trigger holds. The robustness and the violation time pay a search for grazing ``a`` late
and never going on to ``b``: on the unicycle's patrol every other design learns 0 runs of 90, this one 0.39
alone (bench/suite/tuning/24-race-fifth-search-credit-trigger-starts.json) and 0.66 with the restarts
of :data:`mitlc.learn.search.RESTART_SHARE` (35-response-design-restart-share.json: 0.80, 0.63, 0.53
at seeds 0-2); no other task of the suite changed where it races."""


def search_designs_for(formula: Any) -> tuple[tuple[str, dict[str, Any]], ...]:
    """The search designs raced on ``formula`` (the one the monitor judges), in order: :data:`SEARCH_DESIGNS`,
    then :data:`RESPONSE_DESIGN` where the formula asks for a response, an implication ``a -> phi`` with a
    propositional trigger ``a`` and a temporal ``phi`` (a bounded response ``G (a -> F[0,d] b)``:
    :func:`mitlc.learn.search.responses`).

    >>> from mitlc.spec.parse import parse_formula
    >>> len(search_designs_for(parse_formula("G (fast -> F[0,1] !fast) & F G up"))) - len(SEARCH_DESIGNS)
    1
    >>> len(search_designs_for(parse_formula("G (a -> b) & F[0,2] G c"))) - len(SEARCH_DESIGNS)
    0
    """
    from mitlc.learn.search import responses

    return (*SEARCH_DESIGNS, RESPONSE_DESIGN) if responses(formula) else SEARCH_DESIGNS


SEARCH_SHARE = 0.2
"""The search's generations per SACPN trial: a training of the default 500 trials races and trains
the search for 100 generations (the generations the search was chosen at: bench/suite/tuning/9-policy-search.json),
one of 20 trials for 4."""

ALIASES = {"sigma": "sigma_frac"}


def search_generations(trials: int) -> int:
    """The policy search's generations for a training of ``trials`` SACPN trials (:data:`SEARCH_SHARE`).

    >>> search_generations(500), search_generations(20), search_generations(1)
    (100, 4, 1)
    """
    return max(1, int(round(trials * SEARCH_SHARE)))


"""A given setting that fixes a raced one (an explicit ``sigma`` is the exploration)."""


def designs(given: set[str]) -> tuple[tuple[str, dict[str, Any]], ...]:
    """The designs left to race when the user gave the settings ``given``: each design less
    what was given, the duplicates dropped (one left: nothing to race).

    >>> [name for name, _ in designs({"sigma_frac"})]
    ['rbf_width=0.5', 'rbf_width=1']
    >>> designs({"sigma", "rbf_width"})
    (('', {}),)
    """
    fixed = set(given) | {ALIASES[g] for g in given if g in ALIASES}
    out: dict[tuple, tuple[str, dict[str, Any]]] = {}
    for _, changes in DESIGNS:
        left = {k: v for k, v in changes.items() if k not in fixed}
        key = tuple(sorted(left.items()))
        if key not in out:
            out[key] = (" ".join(f"{k}={v:g}" for k, v in left.items()), left)
    return tuple(out.values())


@dataclass(frozen=True)
class Entry:
    """One design's result in the race."""

    name: str
    success: float
    """Fraction of its race runs whose final greedy policy the monitor accepts."""
    mean_return: float
    """Mean return of its final greedy rollouts (the tie-break: the exploration's noise left out,
    so designs that explore differently compare on the same footing)."""
    wall_s: float = field(default=0.0, compare=False)
    """Seconds its training and judging took (in its own process where the race forked one): where a
    race's time goes. Not part of the result: races in one process and in several compare equal."""


@dataclass(frozen=True)
class Race:
    winner: str
    settings: Any
    """The base settings with the winner's changes: what the training runs with (SACPN's; the base
    settings unchanged when the search won)."""
    entries: tuple[Entry, ...]
    runs: int
    trials: int
    generations: int = 0
    """The search's generations in the race (0: the search did not race)."""
    searched: Any = field(default=None, compare=False, repr=False)
    """The search's runs as the race trained them (runs ``0 .. runs - 1`` of the training's own seed:
    the training keeps them when the search wins), None when it did not race."""
    skipped: int = 0
    """Designs not raced: a design before them satisfied the spec on every race run."""

    @property
    def learner(self) -> str:
        """Which learner won: ``"search"`` or ``"sacpn"``."""
        return SEARCH if self.winner.split()[0] == SEARCH else "sacpn"

    def record(self) -> dict[str, Any]:
        """The race as metrics.json keeps it."""
        return {
            "winner": self.winner,
            "learner": self.learner,
            "runs": self.runs,
            "trials": self.trials,
            **({"generations": self.generations} if self.generations else {}),
            **({"skipped": self.skipped} if self.skipped else {}),
            "designs": [
                {
                    "name": e.name,
                    "success": e.success,
                    "mean_return": round(e.mean_return, 6),
                    "wall_s": round(e.wall_s, 2),
                }
                for e in self.entries
            ],
        }

    def line(self) -> str:
        table = ", ".join(f"{e.name} {e.success:.2f}" for e in self.entries)
        each = f"{self.trials} trials" + (f" or {self.generations} generations" if self.generations else "")
        rest = f" (every race run satisfied: {self.skipped} more not raced)" if self.skipped else ""
        return f"race ({self.runs} runs x {each} each, success by the monitor): {table}; {self.winner} won{rest}"


def race_seed(seed: int, i: int) -> int:
    """The race's seed for design ``i``: apart from the training's own streams."""
    return int(np.random.SeedSequence([seed, 7919, i]).generate_state(1)[0] % (2**31))


def race(
    build: Callable[[Any, int, int], Any],
    judge: Callable[[Any], tuple[np.ndarray, np.ndarray]],
    settings: Any,
    runs: int,
    trials: int,
    seed: int,
    progress: Callable[[int, int, str], None] | None = None,
    given: set[str] | frozenset[str] = frozenset(),
    search: Callable[[int, dict[str, Any]], Any] | None = None,
    generations: int = 0,
    workers: int = 1,
    tick: Callable[[], None] | None = None,
    search_designs: tuple[tuple[str, dict[str, Any]], ...] = SEARCH_DESIGNS,
) -> Race | None:
    """Race :data:`DESIGNS` (less the settings ``given``: :func:`designs`) on ``settings``, and the
    policy search when ``search`` is given, None when one design is left: ``build(settings, runs, seed)``
    makes a SACPN learner, ``search(runs, changes)`` an untrained search of runs ``0 .. runs - 1`` on
    the training's seed with each of ``search_designs``'s changes (trained for ``generations``; the
    command line's: :func:`search_designs_for` of the spec's formula),
    ``judge(learner)`` says which of its runs' final greedy policies satisfy the spec, and their greedy
    rollouts' returns.

    With ``workers`` above 1, at least :data:`MIN_FORKED_RUNS` race runs (a training of 13 runs or more)
    and ``fork`` (not on Windows), the first design races here as ever (a
    search's runs split over its own processes) and, unless it wins at once, the designs after it race
    ``workers`` at a time in forked processes, in order, each alone (a search's runs in its one process):
    the same entries, winner and numbers as one process gives (each design draws only from its own
    seeds), in about ``1 / workers`` of the time where no design wins at once.

    ``tick()``, when given, is called after each trial or generation of a design raced in this process
    (the command line's raises a Ctrl-C that Python dropped while modules loaded: a race's design
    trains for minutes with no other check)."""
    r = max(1, min(RACE_RUNS, -(-runs // 4)))
    t = max(1, int(round(trials * RACE_SHARE)))
    todo = designs(set(given))
    searches = search_designs if search is not None else ()
    n = len(todo) + len(searches)
    if n < 2:
        return None
    entries: list[Entry] = []
    searched: dict[int, Any] = {}  # the search designs raced, by index: the winner's runs are kept

    # the searches first (they won 38 of the tuning half's 39 trainings on plants they can drive,
    # record 18), then SACPN's designs; with EARLY_WIN_RUNS race runs, the first design whose every
    # race run satisfies the spec wins and the rest are not raced (they could at best tie it)
    def won_early() -> bool:  # an early winner is the only entry at 1.0: the choice below picks it
        return r >= EARLY_WIN_RUNS and entries[-1].success >= 1.0

    raced_in_order = (*searches, *todo)  # design k: a search while k < len(searches)

    def label(k: int) -> str:
        each = f"{generations} generations" if k < len(searches) else f"{t} trials"
        return f"{raced_in_order[k][0]} ({r} runs x {each})"

    def learner(k: int) -> Any:  # design k's learner, untrained; a plant SACPN cannot drive fails here
        if k < len(searches):
            return search(r, searches[k][1])  # type: ignore[misc]
        i = k - len(searches)
        return build(replace(settings, **todo[i][1]), r, race_seed(seed, i))

    def one(k: int, alone: bool = False) -> tuple[Entry, Any]:
        """Design ``k`` raced: its entry, and its learner if a search (``alone``: in a race process of
        its own, a search's runs trained in it, not split over more)."""
        agent, is_search = learner(k), k < len(searches)
        if alone and is_search:
            agent.workers = 1
        entry = _run(agent, raced_in_order[k][0], generations if is_search else t, judge, tick)
        return entry, (agent if is_search else None)

    from mitlc.learn.search import _fork_context

    if workers > 1 and r >= MIN_FORKED_RUNS and _fork_context() is not None:
        raced = _raced_in_processes(one, learner, n, workers, progress, label)
    else:
        raced = _raced_here(one, n, progress, label)
    try:
        for k, (entry, agent) in raced:
            entries.append(entry)
            if agent is not None:
                searched[k] = agent
            if won_early():
                break
    finally:
        raced.close()  # the race processes still running are stopped
    # an exact tie goes to SACPN's designs in their order, then the searches' (the order they raced in
    # before the searches went first: a tie is decided as it was)
    tied = [len(todo) + j for j in range(len(searches))] + list(range(len(entries) - len(searches)))
    best = max(range(len(entries)), key=lambda i: (entries[i].success, entries[i].mean_return, -tied[i]))
    skipped = n - len(entries)
    g = generations if search else 0
    if best < len(searches):  # a search won
        won = searches[best][0]
        return Race(won, settings, tuple(entries), r, t, generations, searched[best], skipped=skipped)
    k = best - len(searches)
    return Race(todo[k][0], replace(settings, **todo[k][1]), tuple(entries), r, t, g, skipped=skipped)


def _raced_here(
    one: Callable[..., tuple[Entry, Any]], n: int, progress: Callable[[int, int, str], None] | None, label: Callable
) -> Generator[tuple[int, tuple[Entry, Any]], None, None]:
    """Designs ``0 .. n - 1`` raced one after the other in this process, yielded as ``(k, one(k))``."""
    for k in range(n):
        if progress is not None:  # design k of n starts
            progress(k, n, label(k))
        yield k, one(k)


_RACING: Any = None
"""The race a forked race process trains a design of (:func:`_raced_in_processes`), inherited by fork."""


def _raced_in_processes(
    one: Callable[..., tuple[Entry, Any]],
    learner: Callable[[int], Any],
    n: int,
    workers: int,
    progress: Callable[[int, int, str], None] | None,
    label: Callable[[int], str],
) -> Generator[tuple[int, tuple[Entry, Any]], None, None]:
    """Designs ``0 .. n - 1`` raced, yielded in order as ``(k, (entry, learner))``: the first in this
    process, the rest ``workers`` at a time in forked processes (``one(k, alone=True)``), a search's
    learner rebuilt here (``learner(k)``) with the trained state its process sends back. Closing the
    generator (a design won at once, an error, an interrupt) stops the processes still racing."""
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    from mitlc.learn.search import _fork_context, _stop, forked_child, raise_again

    if progress is not None:
        progress(0, n, label(0))
    yield 0, one(0)
    global _RACING
    _RACING = one
    pool = ProcessPoolExecutor(
        min(workers, n - 1),
        mp_context=_fork_context(),
        initializer=forked_child,
    )
    try:
        futures = {k: pool.submit(_race_design, k) for k in range(1, n)}
        for k in range(1, n):
            if progress is not None:  # design k of n is next (its process may have started it already)
                progress(k, n, label(k))
            try:
                (entry, state), warned = futures[k].result()
            except BrokenProcessPool:
                raise TrainingError(
                    "a process racing the designs died (killed, or out of memory)",
                    hint="--workers 1 races them in this process",
                ) from None
            raise_again(warned)
            agent = None
            if state is not None:  # a search: its runs as its process trained them
                agent = learner(k)
                agent.restore_trained_state(state)
            yield k, (entry, agent)
    finally:
        _RACING = None
        _stop(pool)


def _race_design(k: int) -> tuple[tuple[Entry, Any], list]:
    """In a forked process: design ``k`` of :data:`_RACING` raced; its entry and, a search's, its trained
    state, and the warnings it raised (:func:`mitlc.learn.search.caught`)."""
    from mitlc.learn.search import caught

    def one() -> tuple[Entry, Any]:
        entry, agent = _RACING(k, alone=True)
        return entry, (None if agent is None else agent.trained_state())

    return caught(one)


def _run(
    agent: Any,
    name: str,
    trials: int,
    judge: Callable[[Any], tuple[np.ndarray, np.ndarray]],
    tick: Callable[[], None] | None = None,
) -> Entry:
    """Train one design's ``agent`` for ``trials`` (``tick()`` after each trial or generation) and judge it."""
    t0 = time.perf_counter()
    try:
        if tick is None:
            agent.train(trials)
        else:
            agent.train(trials, lambda *_: tick())
    except TrainingError:  # every run of the design diverged: it loses (the training says so if it wins)
        return Entry(name, 0.0, float("-inf"), time.perf_counter() - t0)
    ok, returns = judge(agent)
    finite = np.asarray(returns, dtype=float)
    finite = finite[np.isfinite(finite)]
    mean = float(finite.mean()) if finite.size else float("-inf")
    return Entry(name, float(np.mean(np.asarray(ok, dtype=bool))), mean, time.perf_counter() - t0)


def greedy_verdicts(agent: Any) -> tuple[np.ndarray, np.ndarray]:
    """A learner's final greedy policies from their evaluation starts: the monitor's verdicts on the
    spec's monitor formula, and the rollouts' returns (the race's judge)."""
    from mitlc.monitor.offline import monitor

    spec = agent.spec
    ro = agent.rollout(agent.evaluation_states())
    try:
        verdicts = monitor(spec, ro.states, ro.dt, spec.monitor_formula).satisfied
    except InputError as exc:  # the states the rollouts reached (a plant that blew up): say so, not "<spec>"
        raise exc.located("the rollouts") from None
    return verdicts, ro.returns


def raced(
    build: Callable[[Any, int, int], Any],
    settings: Any,
    runs: int,
    trials: int,
    seed: int,
    given: set[str] | frozenset[str] = frozenset(),
) -> tuple[Any, Race | None]:
    """The learner ``mitlc train`` would train with ``settings`` (the ones given by the user named in
    ``given``): the race's winner's, built for ``runs`` runs and ``seed``, untrained; and the race."""
    result = race(build, greedy_verdicts, settings, runs, trials, seed, given=given)
    return build(result.settings if result is not None else settings, runs, seed), result
