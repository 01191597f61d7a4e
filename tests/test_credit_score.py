"""The policy search's ``score = credit`` (mitlc.monitor.offline.credit_score) and its ``trigger_starts``:
a bounded response ``G (a -> F[0,d] b)`` scored by the responses met and by how near a missed one came, and
tried from where it is asked for (bench/suite's unicycle patrol: patrol-notes.md on branch patrol)."""

from __future__ import annotations

import numpy as np
import pytest

from mitlc.errors import InputError
from mitlc.learn.search import SearchRuns, SearchSettings, scores
from mitlc.monitor.offline import credit_score, monitor
from mitlc.petri.compile import compile_spec
from mitlc.spec.parse import parse_spec

RESPONSE = parse_spec("prop a = x > 1\nprop b = y > 1\nformula G[0,2] (a -> F[0,1] b)")


def _trace(x: list[float], y: list[float]) -> dict[str, np.ndarray]:
    return {"x": np.array([x]), "y": np.array([y])}


def test_credit_counts_met_missed_and_vacuous_instances_of_a_response() -> None:
    # dt 0.5: G[0,2] looks at samples 0..4, F[0,1] two samples ahead
    met = _trace([0, 2, 0, 0, 0], [0, 0, 2, 0, 0])
    missed = _trace([0, 2, 0, 0, 0], [0, 0, 0, 0, 0])
    never = _trace([0, 0, 0, 0, 0], [0, 0, 0, 0, 0])
    c = [float(credit_score(RESPONSE, t, dt=0.5)[0][0]) for t in (met, missed, never)]
    assert c == pytest.approx([(0.5 * 4 + 1) / 5, (0.5 * 4 + 0) / 5, 0.5])
    assert monitor(RESPONSE, met, dt=0.5).satisfied[0] and not monitor(RESPONSE, missed, dt=0.5).satisfied[0]


def test_the_non_vacuous_robustness_is_how_near_a_triggered_response_came() -> None:
    near = _trace([0, 1.1, 0, 0, 0], [0, 0, 0.9, 0, 0])
    far = _trace([0, 1.1, 0, 0, 0], [0, 0, -2.0, -2.0, -2.0])
    n_near, n_far = (float(credit_score(RESPONSE, t, dt=0.5)[1][0]) for t in (near, far))
    assert n_near == pytest.approx(-0.1) and n_far == pytest.approx(-1.0)
    # the robustness sees only the antecedent's depth (0.1) in both
    rho = monitor(RESPONSE, {k: np.concatenate([near[k], far[k]]) for k in near}, dt=0.5).robustness
    assert rho == pytest.approx([-0.1, -0.1])
    # where no antecedent holds, it is the robustness
    quiet = _trace([0, 0.5, 0, 0, 0], [0, 0, 0, 0, 0])
    assert float(credit_score(RESPONSE, quiet, dt=0.5)[1][0]) == pytest.approx(
        float(monitor(RESPONSE, quiet, dt=0.5).robustness[0])
    )


def test_credit_stays_in_0_1_on_every_operator() -> None:
    spec = parse_spec(
        "prop a = x > 0\nprop b = y > 0\n"
        "formula (a U[0,1] b) & (a R[0,1] b) & (a W[0,1] b) & (a <-> b) & !G[0,1] a & F[0.5,9] (a | !b)"
    )
    rng = np.random.default_rng(0)
    states = {"x": rng.normal(size=(50, 12)), "y": rng.normal(size=(50, 12))}
    c, n = credit_score(spec, states, dt=0.25)
    assert c.shape == n.shape == (50,)
    assert np.all((c >= 0) & (c <= 1)) and np.all(np.isfinite(n))


def test_a_satisfied_rollout_outscores_any_violated_one_under_credit() -> None:
    sat, vio, worse = scores(
        np.array([True, False, False]),
        np.array([0.01, -0.5, -0.5]),
        np.array([np.nan, 9.0, 9.0]),
        10.0,
        credit=(np.array([0.2, 1.0, 0.4]), np.array([0.01, -0.0, -3.0])),
    )
    assert sat >= 2.0 > vio > worse >= -1.0


TRIGGERED = """
plant unicycle
init x in [-0.2, 0.2], y in [-1.6, -1.4], theta in [-0.5, 0.5]
horizon 3
prop at_a = (x + 0.8) * (x + 0.8) + y * y < 0.09
prop at_b = (x - 0.8) * (x - 0.8) + y * y < 0.09
formula G[0,1] (at_a -> F[0,2] at_b) & F[0,3] at_b
"""


def _search(**kw) -> SearchRuns:
    from mitlc.cli.train import _monitor_judge  # the judge mitlc train gives the search: it gives the credit

    spec = parse_spec(TRIGGERED)
    return SearchRuns(compile_spec(spec), 3, 0, SearchSettings(**kw), _monitor_judge(spec))


def test_trigger_starts_put_a_share_of_the_starts_where_the_antecedent_holds() -> None:
    plain, half = _search(), _search(trigger_starts=0.5)
    rngs = [np.random.default_rng([0, r, 0]) for r in range(3)]
    x0 = plain._starts(rngs, 2, 4).reshape(3, 2, 4, 3)
    rngs = [np.random.default_rng([0, r, 0]) for r in range(3)]
    x1 = half._starts(rngs, 2, 4).reshape(3, 2, 4, 3)
    assert np.array_equal(x0[:, :, :2], x1[:, :, :2])  # the first starts are the init box's, as before
    assert np.array_equal(x1[:, 0], x1[:, 1])  # every candidate of a run starts alike
    last = x1[:, 0, 2:].reshape(-1, 3)
    assert np.all((last[:, 0] + 0.8) ** 2 + last[:, 1] ** 2 < 0.09)  # in A, anywhere round
    assert plain.evaluation_states().tolist() == half.evaluation_states().tolist()


def test_trigger_starts_without_an_implication_draw_from_the_init_box_and_bad_shares_are_refused() -> None:
    spec = parse_spec(TRIGGERED.replace("G[0,1] (at_a -> F[0,2] at_b) & ", ""))
    sr = SearchRuns(compile_spec(spec), 2, 0, SearchSettings(trigger_starts=1.0), lambda s, dt, mean=False: None)
    x = sr._starts([np.random.default_rng(1), np.random.default_rng(2)], 1, 3)
    assert np.all((np.abs(x[:, 0]) <= 0.2) & (x[:, 1] >= -1.6) & (x[:, 1] <= -1.4))
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(InputError, match="trigger_starts"):
            SearchSettings(trigger_starts=bad).check()


def test_a_search_scored_by_credit_trains_and_reloads_its_settings() -> None:
    sr = _search(score="credit", trigger_starts=0.5, products=True, popsize=8)
    sr.train(3)
    assert sr.returns.shape == (3, 3) and np.all(np.isfinite(sr.returns))
    assert np.all(sr.returns <= 3.0) and np.all(sr.returns >= -1.0)
    again = SearchSettings.from_dict(sr.settings.to_dict())
    assert again == sr.settings


def test_score_credit_with_a_judge_that_gives_no_credit_is_one_error() -> None:
    """The credit comes from the judge, as the averaged robustness does (the search imports no monitor)."""
    from mitlc.errors import TrainingError

    spec = parse_spec(TRIGGERED)

    def judge(states: np.ndarray, dt: float, mean: bool = False):
        return monitor(spec, states, dt, spec.monitor_formula, mean=mean, blame=False)

    sr = SearchRuns(compile_spec(spec), 2, 0, SearchSettings(score="credit", popsize=4), judge)
    with pytest.raises(TrainingError, match="no credit"):
        sr.train(1)


def test_the_antecedent_is_evaluated_as_the_monitor_reads_it() -> None:
    """_holds (the trigger starts' test, on the propositions' predicates) against the monitor on one-sample
    traces, for propositional formulas over the spec's propositions, an angle past pi included."""
    spec = parse_spec(
        "plant unicycle\ninit x in [-0.4, 0.4], y in [-1.6, -1.4], theta in [-0.1, 0.1]\nhorizon 3\n"
        "prop a = x > 0.2\nprop b = y < -0.5\nprop c = abs(theta) < 1\nformula G (a -> F b)\n"
    )
    sr = SearchRuns(compile_spec(spec), 1, 0, SearchSettings(), lambda s, dt, mean=False: None)
    x = np.random.default_rng(5).uniform(-7, 7, size=(400, 3))
    for text in ("a", "!a", "a & b", "a | !c", "(a -> b) & c", "(a <-> c) | false", "true & !(b | c)"):
        node = parse_spec(spec.source.replace("G (a -> F b)", text)).formula
        want = monitor(spec, x[:, None, :], sr.dt, node, blame=False).satisfied
        assert sr._holds(node, x).tolist() == want.tolist(), text
