"""The race's rules on stand-in learners whose race success is set: which designs race, in which
order, when it stops and who wins (mitlc.sweep.race; the CLI's race is tested in test_train_cli.py
and test_search.py)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from mitlc.learn.sacpn import SacpnSettings
from mitlc.sweep.race import DESIGNS, EARLY_WIN_RUNS, RESPONSE_DESIGN, SEARCH_DESIGNS, race, search_designs_for


@dataclass
class Stand:
    """A learner that trains instantly and whose runs satisfy as ``ok`` says, with greedy returns ``ret``."""

    name: str
    ok: tuple[bool, ...]
    ret: float
    trained: int = 0
    workers: int = 1

    def train(self, trials: int) -> None:
        self.trained = trials

    def trained_state(self) -> int:  # what a race process sends back for a search
        return self.trained

    def restore_trained_state(self, state: int) -> None:
        self.trained = state


def _race(
    success: dict[str, tuple[bool, ...]],
    returns: dict[str, float] | None = None,
    searching: bool = True,
    runs: int = 30,
    workers: int = 1,
    searches: tuple = SEARCH_DESIGNS,
):
    returns = returns or {}
    made: list[Stand] = []
    sacpn_names = {tuple(sorted(c.items())): n for n, c in DESIGNS}
    search_names = {tuple(sorted(c.items())): n for n, c in searches}

    def stand(name: str, runs: int) -> Stand:
        ok = success.get(name, (False,) * runs)[:runs]
        assert len(ok) == runs
        made.append(Stand(name, ok, returns.get(name, 0.0)))
        return made[-1]

    def build(settings: SacpnSettings, runs: int, seed: int) -> Stand:
        for changes, name in sacpn_names.items():
            if all(getattr(settings, k) == v for k, v in changes):
                return stand(name, runs)
        raise AssertionError(settings)

    def search(runs: int, changes: dict) -> Stand:
        return stand(search_names[tuple(sorted(changes.items()))], runs)

    def judge(agent: Stand) -> tuple[np.ndarray, np.ndarray]:
        return np.array(agent.ok), np.full(len(agent.ok), agent.ret)

    result = race(
        build,
        judge,
        SacpnSettings(),
        runs,
        500,
        0,
        search=search if searching else None,
        generations=100,
        workers=workers,
        search_designs=searches,
    )
    if workers > 1:  # the designs after the first were built in processes of their own: the entries say which raced
        return result, [e.name for e in result.entries]
    return result, [s.name for s in made]


def test_the_searches_race_first_and_the_first_to_satisfy_every_run_wins_at_once() -> None:
    second = SEARCH_DESIGNS[1][0]
    result, raced = _race({second: (True,) * 8, DESIGNS[0][0]: (True,) * 8})
    assert raced == [SEARCH_DESIGNS[0][0], second]  # the searches after it and every SACPN design not raced
    left = len(DESIGNS) + len(SEARCH_DESIGNS) - 2
    assert (result.winner, result.learner, result.skipped) == (second, "search", left)
    assert result.searched.name == second and result.record()["skipped"] == left
    assert "not raced" in result.line()


def test_without_a_design_that_satisfies_every_run_all_race_and_the_best_wins() -> None:
    half, most = (True,) * 4 + (False,) * 4, (True,) * 7 + (False,)
    result, raced = _race(
        {SEARCH_DESIGNS[0][0]: half, DESIGNS[2][0]: most, DESIGNS[3][0]: most}, returns={DESIGNS[3][0]: 1.0}
    )
    assert raced == [n for n, _ in SEARCH_DESIGNS] + [n for n, _ in DESIGNS]
    assert (result.winner, result.learner, result.skipped) == (DESIGNS[3][0], "sacpn", 0)  # the tie: the return
    assert (result.settings.sigma_frac, result.settings.rbf_width) == (1.0, 1.0)
    assert "skipped" not in result.record()


@pytest.mark.parametrize("k", range(len(DESIGNS)))
def test_a_sacpn_design_that_satisfies_every_run_stops_the_race(k: int) -> None:
    name = DESIGNS[k][0]
    result, raced = _race({name: (True,) * 8}, searching=False)
    assert raced == [n for n, _ in DESIGNS[: k + 1]] and result.winner == name
    assert result.skipped == len(DESIGNS) - k - 1 and result.generations == 0


@pytest.mark.parametrize("runs", [8, 10, 28])
def test_with_fewer_race_runs_every_design_races(runs: int) -> None:
    """A training of under 29 runs races on fewer than EARLY_WIN_RUNS: a clean sweep there wins no early
    race, and the tie between two clean sweeps goes to the higher greedy return."""
    r = -(-runs // 4)
    assert r < EARLY_WIN_RUNS
    first, last = SEARCH_DESIGNS[0][0], DESIGNS[-1][0]
    result, raced = _race({first: (True,) * 8, last: (True,) * 8}, returns={last: 5.0}, runs=runs)
    assert raced == [n for n, _ in SEARCH_DESIGNS] + [n for n, _ in DESIGNS]
    assert (result.runs, result.winner, result.skipped) == (r, last, 0)


def test_an_exact_tie_goes_to_sacpns_first_design_then_the_searches() -> None:
    """With every design at the same success and return (a short training where none learns), SACPN's
    first design wins, as when the searches raced after SACPN's designs."""
    result, raced = _race({}, runs=8)
    assert len(raced) == len(SEARCH_DESIGNS) + len(DESIGNS) and result.winner == DESIGNS[0][0]
    result, _ = _race({}, runs=8, returns={SEARCH_DESIGNS[2][0]: 1.0, DESIGNS[4][0]: 1.0})
    assert result.winner == DESIGNS[4][0]
    result, _ = _race({}, runs=8, returns={SEARCH_DESIGNS[2][0]: 1.0, SEARCH_DESIGNS[1][0]: 1.0})
    assert result.winner == SEARCH_DESIGNS[1][0]


SCENARIOS = [
    ({SEARCH_DESIGNS[1][0]: (True,) * 8, DESIGNS[0][0]: (True,) * 8}, {}, True, 30),
    ({SEARCH_DESIGNS[0][0]: (True,) * 8}, {}, True, 30),
    ({SEARCH_DESIGNS[0][0]: (True,) * 4 + (False,) * 4, DESIGNS[3][0]: (True,) * 7 + (False,)}, {}, True, 30),
    ({DESIGNS[2][0]: (True,) * 8}, {}, False, 30),
    ({}, {SEARCH_DESIGNS[2][0]: 1.0, DESIGNS[4][0]: 1.0}, True, 8),
    ({SEARCH_DESIGNS[3][0]: (True,) * 2}, {SEARCH_DESIGNS[3][0]: 2.0}, True, 8),
]


@pytest.mark.parametrize("case", range(len(SCENARIOS)))
def test_designs_raced_in_processes_give_the_race_one_process_gives(case: int) -> None:
    """workers = 2: the first design here, the rest in forked processes two at a time, consumed in order:
    the same designs raced, entries, winner, settings and skipped designs, and the winning search's
    trained state sent back."""
    success, returns, searching, runs = SCENARIOS[case]
    one, raced_one = _race(success, returns, searching, runs)
    two, raced_two = _race(success, returns, searching, runs, workers=2)
    assert raced_two == raced_one
    assert _result(two.record()) == _result(one.record()) and two.settings == one.settings
    assert two.entries == one.entries  # an entry's wall time is not part of it
    if one.searched is not None:
        assert (two.searched.name, two.searched.trained) == (one.searched.name, one.searched.trained)


def _result(record: dict) -> dict:
    """A race's record less each design's wall time (which measures the machine)."""
    designs = [{k: v for k, v in d.items() if k != "wall_s"} for d in record["designs"]]
    return {**record, "designs": designs}


def _mass_damper_learners(search_workers: int = 1):
    """The real learners on a small mass-damper spec: ``build(settings, runs, seed)`` (SACPN) and
    ``search(runs, changes)`` (the policy search, judged by the monitor, in ``search_workers`` processes)."""
    from mitlc.cli.train import _monitor_judge
    from mitlc.learn.search import SearchRuns, SearchSettings
    from mitlc.petri.compile import compile_spec
    from mitlc.spec.parse import parse_spec
    from mitlc.sweep.task import sacpn_learner

    spec = parse_spec(
        "plant mass-damper\ninit q in [-0.5, 0.5], qdot = 0\nhorizon 2\nprop far = abs(q) > 0.8\nformula F[0,1.5] far\n"
    )
    rs = compile_spec(spec)

    def build(settings, runs, seed):
        return sacpn_learner(rs, settings, runs, seed)

    def search(runs, changes):
        return SearchRuns(rs, runs, 0, SearchSettings(**changes), _monitor_judge(spec), workers=search_workers)

    return build, search


def test_a_real_race_in_processes_is_the_race_in_one_to_the_bit() -> None:
    """A race of the real learners (the search's designs, then SACPN's) on a small spec: two processes
    give the entries and the winning search's gains and fitness of one."""
    from mitlc.sweep.race import greedy_verdicts

    build, search = _mass_damper_learners(search_workers=2)

    got = [
        race(build, greedy_verdicts, SacpnSettings(kernel="numpy"), 16, 20, 0, search=search, generations=3, workers=w)
        for w in (1, 2)
    ]
    assert got[0] is not None and got[1] is not None
    assert _result(got[1].record()) == _result(got[0].record())
    assert len(got[0].entries) == len(DESIGNS) + len(SEARCH_DESIGNS)
    for one in got:  # each design's seconds, measured where it trained (here, or in its own process)
        assert all(e.wall_s > 0 for e in one.entries)
        assert [d["wall_s"] for d in one.record()["designs"]] == [round(e.wall_s, 2) for e in one.entries]
    if got[0].learner == "search":
        np.testing.assert_array_equal(got[1].searched.weights, got[0].searched.weights)
        np.testing.assert_array_equal(got[1].searched.returns, got[0].searched.returns)
        assert got[1].searched.trial == got[0].searched.trial == 3


def test_an_error_in_a_race_process_is_raised_here_as_in_one_process() -> None:
    """A design that fails to build (a plant SACPN cannot drive) raises the same error from its process."""
    from mitlc.errors import InputError

    def build(settings, runs, seed):
        raise InputError("SACPN cannot drive this plant", file="spec.mitl")

    def search(runs, changes):
        return Stand(str(changes), (False,) * runs, 0.0)

    def judge(agent):
        return np.array(agent.ok), np.zeros(len(agent.ok))

    for w in (1, 2):
        with pytest.raises(InputError, match="cannot drive"):
            race(build, judge, SacpnSettings(), 30, 500, 0, search=search, generations=100, workers=w)


def test_a_race_process_that_dies_is_one_training_error_naming_workers() -> None:
    """A design's process killed mid-race (here: it exits at once) is a TrainingError saying so and how to
    race in one process, not a traceback of the process pool."""
    import os

    from mitlc.errors import TrainingError

    def build(settings, runs, seed):  # only ever called in a race process here (workers = 2, searches first)
        os._exit(9)

    def search(runs, changes):
        return Stand(str(changes), (False,) * runs, 0.0)

    def judge(agent):
        return np.array(agent.ok), np.zeros(len(agent.ok))

    with pytest.raises(TrainingError, match="died") as err:
        race(build, judge, SacpnSettings(), 30, 500, 0, search=search, generations=100, workers=2)
    assert "--workers 1" in (err.value.hint or "")


def test_a_warning_raised_in_a_race_process_is_raised_here() -> None:
    """numpy's overflow in a design raced in a process of its own reaches this process's warnings (where
    mitlc train says it once), as if the design had raced here; a short race races here."""
    import warnings

    class Loud(Stand):
        def train(self, trials: int) -> None:
            warnings.warn("overflow encountered in exp", RuntimeWarning, stacklevel=1)
            self.trained = trials

    def build(settings, runs, seed):
        return Loud("sacpn", (False,) * runs, 0.0)

    def search(runs, changes):
        return Stand(str(changes), (False,) * runs, 0.0)

    def judge(agent):
        return np.array(agent.ok), np.zeros(len(agent.ok))

    for runs in (30, 8):
        with warnings.catch_warnings(record=True) as got:
            warnings.simplefilter("always")
            race(build, judge, SacpnSettings(), runs, 500, 0, search=search, generations=100, workers=2)
        texts = [str(w.message) for w in got if issubclass(w.category, RuntimeWarning)]
        assert texts and set(texts) == {"overflow encountered in exp"}, (runs, texts)


def test_the_race_ticks_after_each_trial_and_generation_and_a_tick_that_raises_stops_it() -> None:
    """``tick`` (the command line's: a Ctrl-C Python dropped while modules loaded) is called after every
    generation of a search design and every trial of a SACPN design raced here; what it raises ends the race."""
    from mitlc.sweep.race import RACE_SHARE, greedy_verdicts

    build, search = _mass_damper_learners()

    ticks: list[int] = []

    def counting() -> None:
        ticks.append(1)

    settings = SacpnSettings(kernel="numpy")
    result = race(build, greedy_verdicts, settings, 8, 20, 0, search=search, generations=3, tick=counting)
    assert result is not None and len(result.entries) == len(SEARCH_DESIGNS) + len(DESIGNS)  # 2 race runs each
    assert len(ticks) == 3 * len(SEARCH_DESIGNS) + round(20 * RACE_SHARE) * len(DESIGNS)

    def interrupted() -> None:
        ticks.append(1)
        if len(ticks) == 2:
            raise KeyboardInterrupt

    ticks.clear()
    with pytest.raises(KeyboardInterrupt):
        race(build, greedy_verdicts, settings, 8, 20, 0, search=search, generations=3, tick=interrupted)
    assert len(ticks) == 2  # in the first search design's second generation


def test_a_formula_that_asks_for_a_response_races_the_response_design_last_among_the_searches() -> None:
    """G (a -> F[0,d] b): RESPONSE_DESIGN after SEARCH_DESIGNS and before SACPN's; it wins where only it sweeps
    (the rest raced for nothing); a formula without a response races SEARCH_DESIGNS alone."""
    from mitlc.spec.parse import parse_formula

    searches = search_designs_for(parse_formula("5 * G (lean -> F[0,1] upright) & 10 * G !tipped"))
    assert searches == (*SEARCH_DESIGNS, RESPONSE_DESIGN)
    assert search_designs_for(parse_formula("F[0,4] G up & G (up -> slow)")) == SEARCH_DESIGNS
    assert search_designs_for(None) == SEARCH_DESIGNS
    result, raced = _race({RESPONSE_DESIGN[0]: (True,) * 8}, searches=searches)
    assert raced == [n for n, _ in SEARCH_DESIGNS] + [RESPONSE_DESIGN[0]]
    assert result.winner == RESPONSE_DESIGN[0] and result.learner == "search" and result.skipped == len(DESIGNS)
    result, raced = _race({DESIGNS[1][0]: (True,) * 8}, searches=searches)
    assert raced == [n for n, _ in searches] + [n for n, _ in DESIGNS[:2]] and result.winner == DESIGNS[1][0]
