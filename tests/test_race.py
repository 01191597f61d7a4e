"""The race's rules on stand-in learners whose race success is set: which designs race, in which
order, when it stops and who wins (mitlc.sweep.race; the CLI's race is tested in test_train_cli.py
and test_search.py)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from mitlc.learn.sacpn import SacpnSettings
from mitlc.sweep.race import DESIGNS, EARLY_WIN_RUNS, SEARCH_DESIGNS, race


@dataclass
class Stand:
    """A learner that trains instantly and whose runs satisfy as ``ok`` says, with greedy returns ``ret``."""

    name: str
    ok: tuple[bool, ...]
    ret: float
    trained: int = 0

    def train(self, trials: int) -> None:
        self.trained = trials


def _race(
    success: dict[str, tuple[bool, ...]],
    returns: dict[str, float] | None = None,
    searching: bool = True,
    runs: int = 30,
):
    returns = returns or {}
    made: list[Stand] = []
    sacpn_names = {tuple(sorted(c.items())): n for n, c in DESIGNS}
    search_names = {tuple(sorted(c.items())): n for n, c in SEARCH_DESIGNS}

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

    result = race(build, judge, SacpnSettings(), runs, 500, 0, search=search if searching else None, generations=100)
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
