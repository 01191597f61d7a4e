"""mitlc.learn.search: CMA-ES over a time-varying linear feedback, judged by the monitor. It learns
a cart-pole balance that SACPN misses at every design (docs/suite.md), it is deterministic by seed
and leaves numpy's global generator alone, its policy replays its own rollouts, it drives a plant
with two inputs inside their boxes, its scores order rollouts as its text says, and it refuses
what it cannot search (a Gymnasium environment, no horizon, bad settings) in one line."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mitlc.errors import InputError, TrainingError
from mitlc.learn.search import SearchRuns, SearchSettings, scores
from mitlc.monitor.offline import monitor
from mitlc.petri.compile import compile_spec
from mitlc.plants.base import make_integrator
from mitlc.spec.parse import parse_spec

pytest.importorskip("cma")

BALANCE = """plant cartpole
init x in [-0.5, 0.5], xdot = 0, theta in [-0.15, 0.15], thetadot in [-0.5, 0.5]
horizon 3
prop tipped   = abs(theta) > 0.4
prop on_track = abs(x) < 2.4
formula G !tipped & G on_track
"""

EASY = """plant mass-damper
init q in [-1, -0.5], qdot = 0
horizon 1
prop near = abs(q) < 0.2
formula F[0,0.8] G near
"""

TWO_INPUTS = """plant unicycle
init x in [-1.6, -1.2], y in [-0.4, 0.4], theta in [-0.5, 0.5]
horizon 4
prop goal = (x - 1.0) * (x - 1.0) + y * y < 0.09
formula F[0,3.5] G goal
"""


def _runs(text: str, runs: int, seed: int = 0, **kw) -> SearchRuns:
    spec = parse_spec(text)

    def judge(states: np.ndarray, dt: float, mean: bool = False):
        return monitor(spec, states, dt, spec.monitor_formula, mean=mean)

    return SearchRuns(compile_spec(spec), runs, seed, SearchSettings(**kw), judge)


def _judge(sr: SearchRuns, x0: np.ndarray) -> np.ndarray:
    ro = sr.rollout(x0)
    return monitor(sr.spec, ro.states, ro.dt, sr.spec.monitor_formula).satisfied


def test_it_learns_a_cartpole_balance_from_the_whole_init_box() -> None:
    sr = _runs(BALANCE, 4, seed=3)
    sr.train(30)
    assert _judge(sr, sr.evaluation_states()).all()
    fresh = np.random.default_rng(5).uniform([-0.5, 0, -0.15, -0.5], [0.5, 0, 0.15, 0.5], size=(40, 4))
    assert _judge(sr, fresh).mean() >= 0.9
    # the fitness climbed: the best of the last generation beats the first's in every run
    assert sr.returns.shape == (4, 30)
    assert np.all(sr.returns[:, -1] > sr.returns[:, 0])
    assert np.all(sr.returns[:, -1] >= 2.0)  # every run's best candidate satisfied all its starts


def test_the_same_seed_gives_the_same_gains_and_numpys_generator_is_left_alone() -> None:
    np.random.seed(11)
    before = np.random.get_state()[1].copy()
    a = _runs(EASY, 2, seed=7)
    a.train(3)
    assert np.array_equal(np.random.get_state()[1], before)
    b = _runs(EASY, 2, seed=7)
    b.train(3)
    c = _runs(EASY, 2, seed=8)
    c.train(3)
    assert np.array_equal(a.weights, b.weights) and np.array_equal(a.returns, b.returns)
    assert not np.array_equal(a.weights, c.weights)
    assert not np.array_equal(a.weights[0], a.weights[1])  # runs search independently


def test_the_policy_replays_the_searchs_rollouts_and_the_net_marks_them() -> None:
    sr = _runs(EASY, 3, seed=1)
    sr.train(4)
    x0 = sr.evaluation_states()
    ro = sr.rollout(x0)
    pol = sr.policy()
    x = x0.copy()
    state = pol.reset(x)
    advance = make_integrator(sr.plant, sr.episode.params)
    for k in range(sr.n_steps):
        u = pol.act(x, state)
        np.testing.assert_array_equal(u, ro.actions[:, k])
        advance(x, u)
        state = pol.step(state, x)
        np.testing.assert_array_equal(x, ro.states[:, k + 1])
    # the net's marking codes start where the runtime puts x0 and follow the states
    rt = sr.runtime
    np.testing.assert_array_equal(ro.codes[:, 0], rt.reset_code(x0.copy()))
    assert ro.rewards.shape == (3, sr.n_steps) and np.all(np.isfinite(ro.rewards))


def test_a_plant_with_two_inputs_gets_one_gain_column_per_input_inside_its_box() -> None:
    sr = _runs(TWO_INPUTS, 2, seed=0, popsize=6, starts=2)
    sr.train(2)
    n = len(sr.plant.state)
    assert sr.weights.shape == (2, 2 * n + 2, 2)
    ro = sr.rollout(sr.evaluation_states())
    assert ro.actions.shape == (2, sr.n_steps, 2)
    lo, hi = sr.episode.u_lo, sr.episode.u_hi
    assert np.all(ro.actions >= lo) and np.all(ro.actions <= hi)
    assert not np.allclose(ro.actions[..., 0], ro.actions[..., 1])


@pytest.mark.parametrize("shape", [(1024, 30, 2), (7, 5, 2), (100, 42, 3), (1, 30, 2), (33, 15, 4), (64, 9, 1)])
def test_gains_times_gives_einsums_numbers_over_the_input_axis(shape) -> None:
    """The per-input einsums give einsum("bf,bfm->bm")'s numbers to the bit (the search's numbers do not
    move with it), on features of every size."""
    from mitlc.learn.search import gains_times

    B, f, m = shape
    rng = np.random.default_rng(B + f + m)
    for scale in (1e-3, 1.0, 1e3):
        phi, w = scale * rng.normal(size=(B, f)), rng.normal(size=(B, f, m))
        assert gains_times(phi, w).tobytes() == np.einsum("bf,bfm->bm", phi, w).tobytes()


def test_the_features_are_centred_on_the_init_box_and_wrap_an_angle() -> None:
    text = "plant pendulum\ninit q in [2.4, pi], qdot = 0\nhorizon 2\nprop up = abs(q) < 0.3\nformula F G up\n"
    sr = _runs(text, 1, spec_scale=False)
    ep = sr.episode
    centre = (2.4 + np.pi) / 2
    z = ep.normalise(np.array([[centre, 0.0], [-np.pi + 0.1, 1.0]]))
    assert z[0].tolist() == [0.0, 0.0]
    # -pi + 0.1 is 0.1 past pi, near the box's top end: a small positive z, not a large negative one
    assert z[1, 0] == pytest.approx((np.pi + 0.1 - centre) / ((np.pi - 2.4) / 2))
    # qdot, pinned at 0 by init, is seen on a tenth of its half-range
    assert z[1, 1] == pytest.approx(1.0 / (0.1 * (ep.plant.state[1].hi - ep.plant.state[1].lo) / 2))


@settings(max_examples=200, deadline=None)
@given(
    rho_s=st.floats(0, 1e6),
    rho_v=st.floats(-1e6, 0),
    tv=st.floats(0, 10),
    later=st.floats(0, 10),
    worse=st.floats(0, 1e3),
)
def test_a_satisfied_rollout_outscores_any_violated_one_and_later_or_nearer_is_better(
    rho_s: float, rho_v: float, tv: float, later: float, worse: float
) -> None:
    T = 10.0
    sat, vio = scores(np.array([True, False]), np.array([rho_s, rho_v]), np.array([np.nan, tv]), T)
    assert sat >= 2.0 > vio
    assert vio >= -1.0
    (v_later,) = scores(np.array([False]), np.array([rho_v]), np.array([min(T, tv + later)]), T)
    (v_worse,) = scores(np.array([False]), np.array([rho_v - worse]), np.array([tv]), T)
    assert v_later >= vio >= v_worse


def test_miss_weight_weighs_the_robustness_beside_the_violation_time() -> None:
    """A violated rollout scores ``t_v / T + w tanh(rho)``: with equal violation times the order is the
    robustness's whatever ``w`` (CMA-ES ranks), and a small ``w`` lets a later violation outrank a nearer one."""
    T, rho, tv = 10.0, np.array([-0.05, -1.5]), np.array([4.0, 5.0])  # hovering below a trigger; tripping it
    scored = {}
    for w in (1.0, 0.1):
        hover, trip = scored[w] = scores(np.array([False, False]), rho, tv, T, miss_weight=w)
        assert (hover, trip) == pytest.approx((0.4 + w * np.tanh(-0.05), 0.5 + w * np.tanh(-1.5)), abs=1e-15)
        same = scores(np.array([False, False]), rho, np.array([4.0, 4.0]), T, miss_weight=w)
        assert same[0] > same[1]
    assert scored[1.0][0] > scored[1.0][1]  # w = 1: hovering short of the trigger outranks tripping it
    assert scored[0.1][0] < scored[0.1][1]  # w = 0.1: the later violation outranks it
    np.testing.assert_array_equal(scores(np.array([False, False]), rho, tv, T), scored[1.0])  # w = 1: the default
    assert SearchSettings.from_dict({"popsize": 16}).miss_weight == 1.0  # a file from before the setting


def test_what_it_cannot_search_is_one_line() -> None:
    with pytest.raises(InputError, match="names no plant"):
        SearchRuns(compile_spec(parse_spec("prop up = abs(q) < 0.2\nhorizon 2\nformula F G up\n")), 2, 0)
    with pytest.raises(InputError, match="no 'horizon'"):
        SearchRuns(compile_spec(parse_spec(EASY.replace("horizon 1\n", ""))), 2, 0)
    for bad, what in (
        ({"popsize": 2}, "popsize"),
        ({"starts": 0}, "starts"),
        ({"sigma0": -1.0}, "sigma0"),
        ({"score": "max"}, "score must be one of mean, min"),
        ({"miss_weight": 0.0}, "miss_weight must be a positive number"),
    ):
        with pytest.raises(InputError, match=what) as info:
            _runs(EASY, 1, **bad)
        assert "\n" not in str(info.value)
    with pytest.raises(InputError, match="runs"):
        _runs(EASY, 0)
    with pytest.raises(TrainingError, match="judge"):
        SearchRuns(compile_spec(parse_spec(EASY)), 1, 0).train(1)


def _cli(*args: str):
    from click.testing import CliRunner

    from mitlc.cli.main import main

    return CliRunner().invoke(main, list(args))


def test_mitlc_train_learner_search_writes_a_folder_that_simulate_and_load_policy_read(tmp_path) -> None:
    import json

    from mitlc.learn.policy import load_policy
    from mitlc.learn.search import FILE, load_search

    spec = tmp_path / "balance.mitl"
    spec.write_text(BALANCE)
    out = tmp_path / "run"
    r = _cli("train", "--spec", str(spec), "--learner", "search", "--runs", "3", "--trials", "12", "--out", str(out))
    assert r.exit_code == 0, r.output
    assert "3 searches x 12 generations" in r.output
    for name in (FILE, "metrics.json", "manifest.json", "learning_curve.png", "rollout.png"):
        assert (out / name).is_file(), name
    m = json.loads((out / "metrics.json").read_text())
    assert m["learner"] == "search" and m["runs"] == 3 and m["trials"] == 12
    assert len(m["satisfied"]) == 3 and m["success_rate"] == np.mean(m["satisfied"])
    # the folder's search is the trained one: the same gains, and the same verdicts from the same starts
    loaded = load_search(out)
    again = _runs(BALANCE, 3, seed=0)
    again.train(12)
    np.testing.assert_array_equal(loaded.weights, again.weights)
    assert _judge(loaded, np.array(m["evaluation_starts"])).tolist() == m["satisfied"]
    pol = load_policy(out)
    assert pol.runs == 3 and pol.act(np.zeros((2, 4)), pol.reset(np.zeros((2, 4)))).shape == (2,)
    r = _cli("simulate", "--policy", str(out), "--starts", "train")
    assert r.exit_code == 0, r.output
    assert f"{sum(m['satisfied'])}/3 rollouts satisfy" in r.output


def test_what_mitlc_train_learner_search_refuses_is_one_line_exit_2(tmp_path) -> None:
    spec = tmp_path / "easy.mitl"
    spec.write_text(EASY)
    for extra, what in (
        (["--resume", str(tmp_path)], "--resume"),
        (["--sigma", "0.5"], "--sigma"),
        (["--no-race"], "--no-race"),
    ):
        r = _cli("train", "--spec", str(spec), "--learner", "search", *extra, "--out", str(tmp_path / "o"))
        assert r.exit_code == 2 and what in r.output and len(r.output.strip().splitlines()) == 1, r.output
    r = _cli("train", "--spec", str(spec), "--learner", "search", "--set", "popsize=1", "--out", str(tmp_path / "o"))
    assert r.exit_code == 2 and "popsize" in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert not (tmp_path / "o").exists()
    out = tmp_path / "run"
    r = _cli("train", "--spec", str(spec), "--learner", "search", "--runs", "2", "--trials", "1", "--out", str(out))
    assert r.exit_code == 0, r.output
    (out / "search.npz").write_bytes(b"PK\x03\x04 not a zip")
    r = _cli("simulate", "--policy", str(out))
    assert r.exit_code == 2 and "search.npz" in r.output and len(r.output.strip().splitlines()) == 1, r.output


def test_workers_where_neither_race_nor_search_trains_is_one_line_exit_2(tmp_path) -> None:
    """--workers spreads the race's designs and the policy search's runs over processes; with a learner
    that has neither (SAC, a HyRL spec) it would do nothing, so it is refused before anything is
    trained or written."""
    spec = tmp_path / "easy.mitl"
    spec.write_text(EASY)
    for options, what in (
        (["--spec", str(spec), "--learner", "sac"], "SAC"),
        (["--spec", "specs/mass_damper/rise_time.mitl"], "HyRL"),
    ):
        r = _cli("train", *options, "--workers", "2", "--out", str(tmp_path / "o"))
        assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output
        assert "--workers" in r.output and what in r.output, r.output
    assert not (tmp_path / "o").exists()


def test_a_run_does_not_depend_on_the_runs_beside_it_and_joined_runs_are_one_search() -> None:
    """Run r draws only from streams of (seed, r), cma's samples included: runs 0-1 and runs 2-4
    searched apart and joined are the five runs searched at once, to the bit."""
    whole = _runs(EASY, 5, seed=3)
    whole.train(4)
    head, tail = _runs(EASY, 2, seed=3), _runs(EASY, 3, seed=3)
    tail = SearchRuns(tail.rs, 3, 3, tail.settings, tail.judge, first=2)
    head.train(4)
    tail.train(4)
    both = head.joined(tail)
    np.testing.assert_array_equal(both.weights, whole.weights)
    np.testing.assert_array_equal(both.returns, whole.returns)
    np.testing.assert_array_equal(both.evaluation_states(), whole.evaluation_states())
    np.testing.assert_array_equal(tail.evaluation_states(), whole.evaluation_states()[2:])
    with pytest.raises(ValueError, match="share"):
        head.joined(head)  # not the runs that follow


def test_runs_that_fail_their_check_are_searched_again_and_keep_the_better() -> None:
    """restart_failed: every run's final gains checked from CHECK_STARTS starts of its own; the failed ones
    (here 1 of 8 after 10 generations) searched again from zero with streams of their own, each keeping the
    restart where it scores higher on the same starts; the runs that passed left to the bit."""
    from mitlc.learn.search import CHECK_STARTS

    sr = _runs(EASY, 8, seed=0)
    sr.train(10)
    before, weights = sr.check_scores(), sr.weights.copy()
    assert before.shape == (8, CHECK_STARTS)
    passed = before.min(axis=1) >= 2.0
    assert passed.sum() == 7
    sr.restart_failed(10)
    failed = [int(i) for i in np.flatnonzero(~passed)]
    assert sr.restarted == [failed]
    after = sr.check_scores()
    for i in range(8):
        if i in sr.kept_restarts[0]:
            assert after[i].mean() > before[i].mean() and not np.array_equal(sr.weights[i], weights[i])
        else:
            np.testing.assert_array_equal(sr.weights[i], weights[i])
    assert sr.kept_restarts == [failed]  # the restart passed its check where the first search did not
    assert (after.min(axis=1) >= 2.0).all()
    # the restart is the same whatever the processes, and none where restarts=0
    two = _runs(EASY, 8, seed=0)
    two.workers = 2
    two.train(10)
    two.restart_failed(10)
    np.testing.assert_array_equal(two.weights, sr.weights)
    np.testing.assert_array_equal(two.returns, sr.returns)
    none = _runs(EASY, 8, seed=0, restarts=0)
    none.train(10)
    none.restart_failed(10)
    assert none.restarted == [] and np.array_equal(none.weights, weights)


def test_a_second_round_restarts_only_the_runs_the_first_left_failing() -> None:
    """restarts=2: round 2 searches again exactly the runs round 1 restarted and did not improve (their
    check scores carried from round 1, not rolled out again), and every run kept is one that now passes."""
    sr = _runs(EASY, 8, seed=2, restarts=2)
    sr.train(10)
    sr.restart_failed(10)
    assert len(sr.restarted) == 2
    assert sr.restarted[1] == [r for r in sr.restarted[0] if r not in sr.kept_restarts[0]]
    passed = sr.check_scores().min(axis=1) >= 2.0
    assert all(passed[r] for rounds in sr.kept_restarts for r in rounds)


def test_no_run_is_restarted_where_too_few_runs_pass(monkeypatch) -> None:
    """Below RESTART_SHARE of the runs passing, none is restarted: 3 of 8 pass, under a share of 0.5
    (with the default, 0.1, the same 5 failed runs are restarted)."""
    import mitlc.learn.search as search

    sr = _runs(EASY, 8, seed=1)
    sr.train(10)
    passed = sr.check_scores().min(axis=1) >= 2.0
    assert passed.sum() == 3
    weights = sr.weights.copy()
    monkeypatch.setattr(search, "RESTART_SHARE", 0.5)
    sr.restart_failed(10)
    assert sr.restarted == [] and np.array_equal(sr.weights, weights)
    monkeypatch.setattr(search, "RESTART_SHARE", 0.1)
    sr.restart_failed(10)
    assert sr.restarted[0] == [int(r) for r in np.flatnonzero(~passed)]
    assert 1 <= len(sr.restarted) <= sr.settings.restarts == 3  # the rounds after: the runs still failing


def test_no_run_is_restarted_where_none_passes() -> None:
    """A design none of whose runs passes its check is not restarted (one generation learns nothing here)."""
    sr = _runs(EASY, 4, seed=1)
    sr.train(1)
    assert not (sr.check_scores().min(axis=1) >= 2.0).any()
    weights = sr.weights.copy()
    sr.restart_failed(1)
    assert sr.restarted == [] and np.array_equal(sr.weights, weights)


def test_mitlc_train_races_the_search_and_trains_it_as_learner_search_would(tmp_path) -> None:
    """The default race: the search's three designs, then SACPN's five; the search wins the cart-pole's
    balance (SACPN learns nothing in 50 trials) and the folder is ``--learner search``'s with the same seed,
    to the bit (the race's two search runs kept, four more searched), with the race recorded."""
    import json

    spec = tmp_path / "balance.mitl"
    spec.write_text(BALANCE)
    raced, alone = tmp_path / "raced", tmp_path / "alone"
    r = _cli("train", "--spec", str(spec), "--runs", "6", "--trials", "100", "--seed", "2", "--out", str(raced))
    assert r.exit_code == 0, r.output
    assert "search (2 runs x 20 generations)" in r.output and "; search won" in r.output
    m = json.loads((raced / "metrics.json").read_text())
    assert m["learner"] == "search" and m["trials"] == 20 and m["runs"] == 6
    race = m["race"]
    assert (race["winner"], race["learner"], race["runs"], race["trials"], race["generations"]) == (
        "search", "search", 2, 50, 20
    )  # fmt: skip
    names = [d["name"] for d in race["designs"]]  # the searches first; 2 race runs: no early win, all race
    assert len(names) == 9 and names[:4] == [
        "search",
        "search harmonics=2",
        "search products=true popsize=32",
        "search products=true popsize=32 score=mean",
    ]
    assert race["designs"][0]["success"] == 1.0 and "skipped" not in race
    assert not (raced / "params.npz").exists()
    alone_args = ("--learner", "search", "--runs", "6", "--trials", "20", "--seed", "2", "--out", str(alone))
    assert _cli("train", "--spec", str(spec), *alone_args).exit_code == 0
    assert (raced / "search.npz").read_bytes() == (alone / "search.npz").read_bytes()
    assert m["satisfied"] == json.loads((alone / "metrics.json").read_text())["satisfied"]


def test_the_search_races_only_when_nothing_of_sacpns_was_given(tmp_path) -> None:
    import json

    spec = tmp_path / "easy.mitl"
    spec.write_text(EASY)
    for extra, searched in (
        ((), True),
        (("--learner", "sacpn"), False),
        (("--set", "rbf_width=0.5"), False),
        (("--sigma", "0.3"), False),
    ):
        out = tmp_path / ("o" + "".join(extra).replace("-", "").replace("=", "").replace(".", ""))
        r = _cli("train", "--spec", str(spec), "--runs", "2", "--trials", "4", "--out", str(out), "-q", *extra)
        assert r.exit_code == 0, r.output
        names = [d["name"] for d in json.loads((out / "metrics.json").read_text())["race"]["designs"]]
        assert ("search" in names) == searched, (extra, names)


def test_harmonics_add_periodic_terms_in_time_that_a_folder_keeps(tmp_path) -> None:
    from mitlc.learn.search import load_search

    sr = _runs(EASY, 2, seed=4, harmonics=2)
    assert sr.n_features == 2 * 2 + 2 + 4  # [q, qdot, 1, tau q, tau qdot, tau] and sin, cos of 2 pi tau, 4 pi tau
    sr.weights[:] = 0.0
    sr.weights[:, 6, 0] = 3.0  # the input follows sin(2 pi tau) alone: u = tanh(3 sin(2 pi tau)) in the box
    ro = sr.rollout(sr.evaluation_states())
    lo, hi = sr.episode.u_lo[0], sr.episode.u_hi[0]
    tau = np.arange(sr.n_steps) * sr.dt / sr.episode.horizon
    want = lo + (np.tanh(3.0 * np.sin(2 * np.pi * tau)) + 1) / 2 * (hi - lo)
    np.testing.assert_allclose(ro.actions[0], want, rtol=0, atol=1e-12)
    spec = tmp_path / "easy.mitl"
    spec.write_text(EASY)
    out = tmp_path / "h"
    args = ("--learner", "search", "--set", "harmonics=2", "--runs", "2", "--trials", "3", "--out", str(out))
    assert _cli("train", "--spec", str(spec), *args).exit_code == 0
    loaded = load_search(out)
    assert loaded.settings.harmonics == 2 and loaded.weights.shape == (2, 10, 1)
    again = _runs(EASY, 2, seed=0, harmonics=2)
    again.train(3)
    np.testing.assert_array_equal(loaded.weights, again.weights)
    r = _cli("train", "--spec", str(spec), "--learner", "search", "--set", "harmonics=-1", "--out", str(tmp_path / "x"))
    assert r.exit_code == 2 and "harmonics" in r.output and len(r.output.strip().splitlines()) == 1, r.output


ALTERNATE = """plant pendulum(u_max = 10)
init q in [-0.3, 0.3], qdot = 0
horizon 5
prop left   = abs(q + pi/2) < 0.3
prop right  = abs(q - pi/2) < 0.3
prop bottom = abs(q) > 2.5
formula 5 * G[0,3.5] F[0,1.5] left & 5 * G[0,3.5] F[0,1.5] right & 10 * G !bottom
"""


def test_the_harmonics_period_is_the_deadline_a_g_repeats_and_a_patrol_learns_on_it(tmp_path) -> None:
    from mitlc.learn.search import load_search, recurrence_period
    from mitlc.spec.parse import parse_formula

    def period(text: str) -> float | None:
        return recurrence_period(parse_formula(text))

    assert period("G[0,3.5] F[0,1.5] a & G[0,3.5] F[0,1.5] b & G !c") == 1.5
    assert period("G[0,8] (a -> F[0,3.5] b) & G[0,7] F[0,5] a") == 3.5  # a bounded response repeats its deadline
    assert period("G (a U[0,2] b) & F[0,1] c") == 2.0  # an until's deadline too; the F outside every G does not
    assert period("F[0,4] G a & G F b & F[1,2] c") is None  # nothing repeats a finite deadline
    assert period("G !(F[0,0.5] a)") == 0.5  # under a negation as well: a deadline the G repeats
    # the sine of the one harmonic, alone, drives the input: with the spec's period 1.5 s, the horizon's
    # (5.01 s: 167 steps of 0.03 s), or 2 s
    for chosen, seconds in ((None, 1.5), (0.0, 5.01), (2.0, 2.0)):
        sr = _runs(ALTERNATE, 1, harmonics=1, period=chosen)
        sr.weights[:] = 0.0
        sr.weights[0, sr.n_features - 2, 0] = 3.0
        ro = sr.rollout(sr.evaluation_states())
        lo, hi = sr.episode.u_lo[0], sr.episode.u_hi[0]
        t = np.arange(sr.n_steps) * sr.dt
        want = lo + (np.tanh(3.0 * np.sin(2 * np.pi * t / seconds)) + 1) / 2 * (hi - lo)
        np.testing.assert_allclose(ro.actions[0], want, rtol=0, atol=1e-9)
    # swinging left and right every 1.5 s: a schedule on the spec's period learns it, one on the horizon's does not
    learnt = {}
    for chosen in (None, 0.0):
        sr = _runs(ALTERNATE, 4, seed=0, harmonics=2, period=chosen)
        sr.train(25)
        learnt[chosen] = int(_judge(sr, sr.evaluation_states()).sum())
    assert learnt[None] >= 3 and learnt[0.0] == 0, learnt
    # a search.npz from before the setting was trained on the horizon's period, and reloads so
    assert SearchSettings.from_dict({"harmonics": 2}).period == 0.0
    assert SearchSettings().period is None
    spec = tmp_path / "alt.mitl"
    spec.write_text(ALTERNATE)
    out = tmp_path / "p"
    args = ("--learner", "search", "--set", "harmonics=1", "--set", "period=2", "--runs", "1", "--trials", "2")
    assert _cli("train", "--spec", str(spec), *args, "--out", str(out)).exit_code == 0
    assert load_search(out).settings.period == 2.0 and load_search(out).cycles == pytest.approx(5.01 / 2)
    r = _cli("train", "--spec", str(spec), "--learner", "search", "--set", "period=-1", "--out", str(tmp_path / "x"))
    assert r.exit_code == 2 and "period" in r.output and len(r.output.strip().splitlines()) == 1, r.output


def test_product_features_make_go_to_point_steering_one_weighted_sum() -> None:
    """With ``products``, ``dy cos(theta) - dx sin(theta)`` (the turn towards a point) and
    ``dx cos(theta) + dy sin(theta)`` (the speed towards it) are sums of the features: gains written
    by hand from the goal's place drive the unicycle into it from every corner of the init box."""
    sr = _runs(TWO_INPUTS, 1, products=True)
    ep = sr.episode
    b = 4  # x, y, sin and cos of theta's difference from the box's centre
    assert ep.n_state_features(True) == b + b * (b + 1) // 2
    assert sr.n_features == 2 * (b + b * (b + 1) // 2) + 2
    x = np.array([[-1.3, 0.2, 0.4]])
    d = x - ep.centre
    z = d / ep.scale
    base = [z[0, 0], z[0, 1], np.sin(d[0, 2]), np.cos(d[0, 2])]
    pairs = [base[i] * base[j] for i in range(b) for j in range(i, b)]
    np.testing.assert_allclose(ep.normalise(x, True)[0], base + pairs, rtol=0, atol=1e-15)
    assert ep.centre[2] == 0.0  # so theta's sine and cosine are the features' own
    gx, gy = 1.0, 0.0
    (cx, cy, _), (sx, sy, _) = ep.centre, ep.scale
    col = {name: k for k, name in enumerate(["x", "y", "sin", "cos", "xx", "xy", "xsin", "xcos", "yy", "ysin", "ycos"])}
    W = np.zeros((sr.n_features, 2))
    # speed: 3 (dx cos + dy sin), dx = (gx - cx) - sx z_x, dy = (gy - cy) - sy z_y
    for name, w in (("cos", gx - cx), ("xcos", -sx), ("sin", gy - cy), ("ysin", -sy)):
        W[col[name], 0] = 3 * w
    # turn: 5 (dy cos - dx sin); omega's box is symmetric, so tanh's zero is no turn
    for name, w in (("cos", gy - cy), ("ycos", -sy), ("sin", -(gx - cx)), ("xsin", sx)):
        W[col[name], 1] = 5 * w
    sr.weights[0] = W
    corners = np.array([[a, c, t] for a in (-1.6, -1.2) for c in (-0.4, 0.4) for t in (-0.5, 0.5)])
    assert _judge(sr, corners).all()
    sr.weights[0] = 0.0
    assert not _judge(sr, corners).any()  # standing still at the box's centre input does not get there


def test_scale_floor_sets_how_far_from_the_init_box_a_feature_stays_near_1(tmp_path) -> None:
    from mitlc.learn.search import load_search

    sr = _runs(TWO_INPUTS, 2, seed=1, scale_floor=1.0, spec_scale=False)
    z = sr.episode.normalise(np.array([[2.0, -2.0, 0.5]]))
    # x's and y's scale is their half-range, 2 m (the init box is narrower); theta's is pi
    np.testing.assert_allclose(z[0], [(2.0 + 1.4) / 2.0, -2.0 / 2.0, 0.5 / np.pi], rtol=1e-12)
    narrow = _runs(TWO_INPUTS, 2, seed=1, spec_scale=False).episode.normalise(np.array([[2.0, -2.0, 0.5]]))
    np.testing.assert_allclose(narrow[0], [(2.0 + 1.4) / 0.2, -2.0 / 0.4, 0.5 / 0.5], rtol=1e-12)
    spec = tmp_path / "two.mitl"
    spec.write_text(TWO_INPUTS)
    out = tmp_path / "s"
    sets = ("--set", "scale_floor=1", "--set", "products=true")
    args = ("--learner", "search", *sets, "--runs", "2", "--trials", "2", "--seed", "1", "--out", str(out))
    assert _cli("train", "--spec", str(spec), *args).exit_code == 0
    loaded = load_search(out)
    assert loaded.settings.scale_floor == 1.0 and loaded.settings.products is True
    again = _runs(TWO_INPUTS, 2, seed=1, scale_floor=1.0, products=True)
    again.train(2)
    np.testing.assert_array_equal(loaded.weights, again.weights)
    for bad in ("scale_floor=0", "scale_floor=nan", "scale_floor=-1"):
        r = _cli("train", "--spec", str(spec), "--learner", "search", "--set", bad, "--out", str(tmp_path / "x"))
        assert r.exit_code == 2 and "scale_floor" in r.output and len(r.output.strip().splitlines()) == 1, r.output


def test_spec_scale_reaches_the_propositions_boundaries_on_each_variable(tmp_path) -> None:
    """With ``spec_scale``, a variable's scale is also the farthest of the spec's thresholds on it from
    the init box's centre: for TWO_INPUTS' goal disc at (1, 0) of radius 0.3, x reaches 1.3 from -1.4
    (2.7) and y 0.3 from 0 (under the init half-width 0.4, which stays); theta has no threshold."""
    from mitlc.learn.features import spec_thresholds
    from mitlc.learn.search import load_search

    marks = spec_thresholds(parse_spec(TWO_INPUTS))
    assert set(marks) == {"x", "y"}
    # the grid's flips bracket the disc's edge to within one grid step (4 m / 63 per axis)
    step = 4.0 / 63
    assert abs(marks["x"].max() - 1.3) < step and abs(marks["x"].min() - 0.7) < step
    assert abs(np.abs(marks["y"]).max() - 0.3) < step
    plain = _runs(TWO_INPUTS, 2, seed=1, spec_scale=False).episode
    wide = _runs(TWO_INPUTS, 2, seed=1, spec_scale=True).episode
    assert wide.scale[0] == pytest.approx(marks["x"].max() + 1.4) and abs(wide.scale[0] - 2.7) < step
    assert wide.scale[1] == plain.scale[1] == pytest.approx(0.4)  # the disc's 0.3 is inside the init box's 0.4
    assert wide.scale[2] == plain.scale[2] == pytest.approx(0.5)
    spec = tmp_path / "two.mitl"
    spec.write_text(TWO_INPUTS)
    out = tmp_path / "s"
    args = ("--learner", "search", "--runs", "2", "--trials", "2", "--seed", "1")
    assert _cli("train", "--spec", str(spec), *args, "--out", str(out)).exit_code == 0
    loaded = load_search(out)  # on by default
    assert loaded.settings.spec_scale is True and loaded.episode.scale[0] == wide.scale[0]
    again = _runs(TWO_INPUTS, 2, seed=1, spec_scale=True)
    again.train(2)
    np.testing.assert_array_equal(loaded.weights, again.weights)
    off = tmp_path / "off"
    assert _cli("train", "--spec", str(spec), *args, "--set", "spec_scale=false", "--out", str(off)).exit_code == 0
    assert load_search(off).episode.scale[0] == plain.scale[0]
    # a search.npz written before the setting existed was trained without it, and reloads so
    assert SearchSettings.from_dict({"harmonics": 2}).spec_scale is False
    assert SearchSettings.from_dict(loaded.settings.to_dict()) == loaded.settings


def test_spec_thresholds_of_one_variable_match_where_its_truth_flips() -> None:
    from mitlc.learn.features import spec_thresholds

    spec = parse_spec(
        "plant cartpole\ninit x = 0, xdot = 0, theta in [-0.1, 0.1], thetadot = 0\nprop tipped = abs(theta) > 0.4\n"
        "prop mark = abs(x - 1.5) < 0.1\nprop c = 1 > 0\nformula G !tipped & F G mark & G c"
    )
    marks = spec_thresholds(spec)
    assert set(marks) == {"theta", "x"}  # the constant proposition reads no variable
    theta = marks["theta"]
    # 4096 samples of theta's box [-pi, pi): the two flips within a sample's width of -0.4 and 0.4
    assert len(theta) == 2 and np.all(np.abs(np.abs(theta) - 0.4) < 2 * np.pi / 4095)
    assert len(marks["x"]) == 2 and np.all(np.abs(np.sort(marks["x"]) - [1.4, 1.6]) < 5.0 / 4095)


def test_runs_trained_in_forked_processes_are_the_runs_trained_in_one() -> None:
    """workers = 2 splits the runs into two forked parts (at least MIN_PART_RUNS each): the same gains and
    fitness to the bit, the progress reported up to the last generation, and a part's error raised as
    one process raises it."""
    from mitlc.learn.search import MIN_PART_RUNS

    one, two = _runs(EASY, 2 * MIN_PART_RUNS, seed=4), _runs(EASY, 2 * MIN_PART_RUNS, seed=4)
    two.workers = 2
    seen: list[int] = []
    one.train(5)
    two.train(5, lambda g, n: seen.append(g))
    np.testing.assert_array_equal(one.weights, two.weights)
    np.testing.assert_array_equal(one.returns, two.returns)
    assert seen == [1, 2, 3, 4, 5] and two.trial == 5

    def failing(states: np.ndarray, dt: float, mean: bool = False):
        raise TrainingError("the judge failed")

    bad = SearchRuns(one.rs, 2 * MIN_PART_RUNS, 0, SearchSettings(), failing, workers=2)
    with pytest.raises(TrainingError, match="the judge failed"):
        bad.train(2)
    with pytest.raises(InputError, match="workers must be at least 1"):
        SearchRuns(one.rs, 2, 0, SearchSettings(), failing, workers=0)


def test_a_forked_part_that_dies_is_one_line_naming_workers() -> None:
    """A part's process killed mid-training (here: it exits at once) is a TrainingError that says so
    and how to train in one process, not a traceback of the process pool."""
    import os

    from mitlc.learn.search import MIN_PART_RUNS

    def dying(states: np.ndarray, dt: float, mean: bool = False):
        os._exit(9)

    spec = parse_spec(EASY)
    bad = SearchRuns(compile_spec(spec), 2 * MIN_PART_RUNS, 0, SearchSettings(), dying, workers=2)
    with pytest.raises(TrainingError, match="died") as err:
        bad.train(2)
    assert "--workers 1" in (err.value.hint or "")
