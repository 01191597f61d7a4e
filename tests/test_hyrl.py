"""HyRL: the batched learner against a plain per-run loop of section 2-1-3 / (3-7)..(3-10),
seeding, checkpoints, learning, composition (section 3-3-3)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from mitlc.errors import TrainingError
from mitlc.hybrid.criteria import check
from mitlc.learn.hyrl import (
    HANDOVER_SIGMA,
    HybridLearner,
    HyrlSettings,
    brake_bound,
    compose,
    evaluate,
    load_learner,
    train_handover,
    train_hybrid,
)
from mitlc.spec.parse import load_spec, parse_spec

OVERSHOOT = """plant mass-damper
init q in [-1, 1], qdot = 0
setpoint 0
require overshoot <= 0
"""
SHORT = HyrlSettings(trial_s=0.45)  # 15 steps


@pytest.fixture(scope="module")
def md_specs():
    d = Path(__file__).resolve().parent.parent / "specs" / "mass_damper"
    return {n: load_spec(d / f"{n}.mitl") for n in ("overshoot", "rise_time", "overshoot_rise_time")}


# ------------------------------------------------------------------ the update rules


def reference_trials(spec, settings, runs, seed, trials):
    """Standard actor-critic on the hybrid automaton, one run at a time, no tricks:
    V = (theta_delta + theta_g) . phi (3-7), pi = xi_delta . phi (3-10), TD error (2-8),
    accumulating trace (2-16), critic (2-17), actor (2-18) with the applied exploration;
    exploration white or Ornstein-Uhlenbeck (``noise_tau``), critic started at
    ``learner.initial_values()`` (checked on its own below)."""
    learner = HybridLearner(spec, settings, runs=1, seed=0)  # for its features and automaton only
    A, plant, params = learner.automaton, learner.plant, learner.params
    M, F = learner.n_modes, learner.n_features
    G = M
    N, dt, u_max = learner.n_steps, learner.dt, learner.u_max
    st = settings
    out_returns = np.zeros((runs, trials))
    xis, thetas = [], []
    children = np.random.SeedSequence(seed).spawn(runs)
    for r in range(runs):
        rng = np.random.Generator(np.random.PCG64(children[r].spawn(2)[0]))
        xi = np.zeros((M, F))
        theta = np.zeros((M + 1, F))
        theta[:M] = learner.initial_values()[:, None]
        for trial in range(trials):
            (qlo, qhi), (vlo, vhi) = A.q0_range, A.qdot0_range
            x = np.array([[rng.uniform(qlo, qhi), rng.uniform(vlo, vhi)]])
            eps = rng.standard_normal(N)
            noise = eps.copy()
            if st.noise_tau > 0:
                a_ou = np.exp(-dt / st.noise_tau)
                for k in range(1, N):
                    noise[k] = a_ou * noise[k - 1] + np.sqrt(1 - a_ou**2) * eps[k]
            noise *= max(st.sigma_min, st.sigma * st.sigma_decay**trial)
            q0 = x[:, 0].copy()
            mode, t = A.reset(x)
            phi = learner.phi(x, q0, t, 0.0)[0]
            e = np.zeros((M + 1, F))
            ret = 0.0
            for k in range(N):
                m = int(mode[0])
                u = xi[m] @ phi
                u_sat = min(max(u, -u_max), u_max)
                a = min(max(u_sat + noise[k], -u_max), u_max)
                du = a - u_sat
                x = plant.step(x, np.array([a]), params)
                mode1, t1, rew = A.step(mode, t, x, q0, (k + 1) * dt, dt)
                m1 = int(mode1[0])
                phi1 = learner.phi(x, q0, t1, (k + 1) * dt)[0]
                delta = rew[0] + st.gamma * (theta[m1] + theta[G]) @ phi1 - (theta[m] + theta[G]) @ phi
                coef = st.alpha_a * delta * du
                if (u >= u_max and coef > 0) or (u <= -u_max and coef < 0):
                    coef = 0.0
                xi[m] += coef * phi
                e *= st.gamma * st.lam
                e[m] += phi
                e[G] += phi
                theta += st.alpha_c * delta * e
                ret += rew[0]
                mode, t, phi = mode1, t1, phi1
            out_returns[r, trial] = ret
        xis.append(xi)
        thetas.append(theta)
    return out_returns, np.array(xis), np.array(thetas)


@pytest.mark.parametrize(
    "name,noise_tau,critic_init",
    [
        ("overshoot", 0.0, "zero"),
        ("rise_time", 0.0, "constant"),
        ("overshoot", 0.1, "stay"),
        ("rise_time", 0.2, "stay"),
    ],
)
def test_batched_learner_equals_the_per_run_loop(md_specs, name, noise_tau, critic_init):
    spec = md_specs[name]
    settings = dataclasses.replace(
        SHORT, sigma=3.0, sigma_decay=0.8, sigma_min=2.0, noise_tau=noise_tau, critic_init=critic_init
    )
    learner = HybridLearner(spec, settings, runs=3, seed=11)
    returns = learner.train(4)
    ref_returns, ref_xi, ref_theta = reference_trials(spec, settings, 3, 11, 4)
    np.testing.assert_allclose(returns, ref_returns, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(learner.xi, ref_xi, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(learner.theta, ref_theta, rtol=1e-8, atol=1e-10)
    assert np.abs(learner.xi).max() > 0.01 and np.abs(learner.theta).max() > 0.01  # it did learn something


def test_value_is_general_plus_mode_part_and_policy_is_per_mode():
    learner = HybridLearner(parse_spec(OVERSHOOT), runs=2, seed=0)
    # normalised RBFs sum to one, so constant rows give constant outputs
    learner.xi[:, :, :] = np.array([1.0, -2.0, 3.0, 20.0])[None, :, None]
    learner.theta[:, :, :] = np.array([10.0, 20.0, 30.0, 40.0, 0.5])[None, :, None]
    x = np.array([[-0.3, 0.1], [0.2, -1.0]])
    q0 = np.array([-1.0, 1.0])
    t = np.zeros(2)
    for m, u in enumerate([1.0, -2.0, 3.0, 10.0]):  # P's 20 is clipped to u_max = 10
        mode = np.full(2, m)
        np.testing.assert_allclose(learner.policy(x, q0, t, mode, 0.0), u)
        np.testing.assert_allclose(learner.value(x, q0, t, mode, 0.0), [10.0, 20.0, 30.0, 40.0][m] + 0.5)
    # each row reads its own run's parameters, or the run it is given
    learner.xi[1] *= 2.0
    learner.theta[1] *= 2.0
    mode = np.zeros(2, dtype=int)
    np.testing.assert_allclose(learner.policy(x, q0, t, mode, 0.0), [1.0, 2.0])
    np.testing.assert_allclose(learner.value(x, q0, t, mode, 0.0), [10.5, 21.0])
    np.testing.assert_allclose(learner.value(x, q0, t, mode, 0.0, run=np.array([1, 1])), [21.0, 21.0])
    np.testing.assert_allclose(learner.policy(x, q0, t, mode, 0.0, run=np.array([1, 0])), [2.0, 1.0])


def test_critic_starts_at_the_value_of_the_constant_rewards(md_specs):
    # S: +3 stay bonus kept forever = 3 / (1 - 0.98) = 150; P: -9 / 0.02 = -450; I, E: no constant part
    names = ("I", "E_Mp", "S", "P")
    for init, want in (("zero", (0, 0, 0, 0)), ("stay", (0, 0, 150, 0)), ("constant", (0, 0, 150, -450))):
        lrn = HybridLearner(md_specs["overshoot"], HyrlSettings(critic_init=init), runs=2)
        assert lrn.automaton.names == names
        np.testing.assert_allclose(lrn.initial_values(), want, atol=1e-9)
        x = np.array([[-0.05, 0.3], [0.7, -2.0]])
        for m in range(4):  # the features sum to one: the value is the constant itself
            v = lrn.value(x, np.array([-1.0, 1.0]), np.zeros(2), np.full(2, m), 0.0)
            np.testing.assert_allclose(v, want[m], atol=1e-9)
    r = HybridLearner(md_specs["rise_time"], runs=1)  # default: stay; the rise-time S is permanent
    np.testing.assert_allclose(r.initial_values(), (0, 0, 150, 0), atol=1e-9)
    assert r.automaton.names == ("I", "E_tr", "S", "P")


def _applied_exploration(noise_tau, trials=40):
    # alpha_a = 0 keeps the policy at 0: the applied input is the exploration itself
    lrn = HybridLearner(
        parse_spec(OVERSHOOT), HyrlSettings(noise_tau=noise_tau, sigma=2.0, alpha_a=0.0), runs=1, seed=4
    )
    seen = []
    orig = lrn.plant.step

    class Spy:
        def step(self, x, a, params):
            seen.append(float(a[0]))
            return orig(x, a, params)

    lrn.plant = Spy()
    lrn.train(trials)
    n = np.array(seen).reshape(trials, -1)
    return n.std(), np.mean([np.corrcoef(r[:-1], r[1:])[0, 1] for r in n])


def test_exploration_is_ornstein_uhlenbeck_with_stationary_sigma():
    std, lag1 = _applied_exploration(0.3)
    assert abs(std - 2.0) < 0.2  # stationary deviation sigma
    assert abs(lag1 - np.exp(-0.03 / 0.3)) < 0.05  # a = exp(-T_s / tau) = 0.905
    std, lag1 = _applied_exploration(0.0)  # white
    assert abs(std - 2.0) < 0.1 and abs(lag1) < 0.05


def test_features_follow_table_3_2(md_specs):
    o = HybridLearner(md_specs["overshoot"], runs=1)
    r = HybridLearner(md_specs["rise_time"], runs=1)
    assert o.features.names == ("q", "qdot", "q0") and o.n_features == 10 * 10 * 5
    assert r.features.names == ("q", "qdot", "q0", "t") and r.n_features == 10 * 10 * 5 * 5
    assert r.features.bounds == ((-1.0, 1.0), (-1.5, 1.5), (-1.0, -0.5), (0.0, 0.8))  # qdot_grid 1.5
    wide = HybridLearner(md_specs["rise_time"], HyrlSettings(qdot_grid=None), runs=1)
    assert wide.features.bounds[1] == (-5.0, 5.0)  # the plant's bound (section 3-1)
    assert o.n_steps == 167 and o.dt == 0.03  # T_t = 5 s, T_s = 0.03 s
    s = HybridLearner(parse_spec(OVERSHOOT + "require settling_time <= 2\n"), runs=1)
    assert s.features.names == ("q", "qdot", "q0", "tau") and s.features.bounds[3] == (0.0, 5.0)


def test_q_centres_crowd_towards_the_set_point(md_specs):
    # q_warp 0.5: centres even in s + sign(q - s) D sqrt(|q - s| / D), D = 1 here
    o = HybridLearner(md_specs["overshoot"], runs=1)
    w = np.linspace(-1, 1, 10)
    np.testing.assert_allclose(o.features.centres_in(0), np.sign(w) * w**2, atol=1e-12)
    np.testing.assert_allclose(o.features.centres_in(0)[5:], [1 / 81, 1 / 9, 25 / 81, 49 / 81, 1.0])
    even = HybridLearner(md_specs["overshoot"], HyrlSettings(q_warp=1.0), runs=1)
    np.testing.assert_allclose(even.features.centres_in(0), np.linspace(-1, 1, 10))
    # auto: an even grid for the rise time alone (its bands spread over the step), crowded otherwise
    assert o.q_warp == 0.5 and even.q_warp == 1.0
    assert HybridLearner(md_specs["rise_time"], runs=1).q_warp == 1.0
    assert HybridLearner(md_specs["overshoot_rise_time"], runs=1).q_warp == 0.5
    assert HybridLearner(md_specs["rise_time"], HyrlSettings(q_warp=0.5), runs=1).q_warp == 0.5
    settle = HybridLearner(parse_spec(OVERSHOOT.replace("require overshoot <= 0", "require settling_time <= 2")))
    assert settle.q_warp == 0.5
    # the other axes are even grids either way
    np.testing.assert_allclose(o.features.centres_in(1), np.linspace(-1.5, 1.5, 10))
    # a q at a centre puts the largest weight on it; the kernels narrow with the spacing
    f = o.features
    for c in f.centres_in(0):
        z = np.array([[c, 0.0, 0.0]])
        g = f(z).reshape(10, 10, 5).sum(axis=(1, 2))
        assert np.argmax(g) == np.argmin(np.abs(f.centres_in(0) - c))
    near = f(np.array([[0.012, 0.0, 0.0], [0.011, 0.0, 0.0]])).reshape(2, 10, -1).sum(axis=2)
    far = f(np.array([[0.605, 0.0, 0.0], [0.604, 0.0, 0.0]])).reshape(2, 10, -1).sum(axis=2)
    assert np.abs(near[0] - near[1]).sum() > 5 * np.abs(far[0] - far[1]).sum()  # sqrt(0.605 / 0.012) = 7
    # a set-point off zero moves the crowding with it
    moved = HybridLearner(parse_spec(OVERSHOOT.replace("setpoint 0", "setpoint 0.5")), runs=1)
    assert np.min(np.abs(moved.features.centres_in(0) - 0.5)) < 0.02


# ------------------------------------------------------------------ seeding and checkpoints


def test_same_seed_gives_identical_returns_and_parameters():
    spec = parse_spec(OVERSHOOT)
    a = train_hybrid(spec, SHORT, runs=3, trials=5, seed=7)
    b = train_hybrid(spec, SHORT, runs=3, trials=5, seed=7)
    c = train_hybrid(spec, SHORT, runs=3, trials=5, seed=8)
    assert np.array_equal(a.returns, b.returns) and np.array_equal(a.xi, b.xi) and np.array_equal(a.theta, b.theta)
    assert not np.array_equal(a.returns, c.returns)


def test_a_run_does_not_depend_on_how_many_runs_share_the_batch():
    spec = parse_spec(OVERSHOOT)
    one = train_hybrid(spec, SHORT, runs=1, trials=4, seed=5)
    three = train_hybrid(spec, SHORT, runs=3, trials=4, seed=5)
    assert np.array_equal(one.returns[0], three.returns[0])
    assert np.array_equal(one.xi[0], three.xi[0])


def test_checkpoint_resume_and_interrupt_are_bit_exact(tmp_path):
    spec = parse_spec(OVERSHOOT)
    straight = train_hybrid(spec, SHORT, runs=2, trials=4, seed=3)

    def stop_after_two(trial, returns):
        if trial == 2:
            raise KeyboardInterrupt

    first = HybridLearner(spec, SHORT, runs=2, seed=3)
    with pytest.raises(KeyboardInterrupt):
        first.train(4, stop_after_two)
    assert first.trial == 2 and first.returns.shape == (2, 2)
    first.save(tmp_path / "params.npz")
    resumed = load_learner(tmp_path / "params.npz")
    resumed.train(2)
    assert np.array_equal(resumed.returns, straight.returns)
    assert np.array_equal(resumed.xi, straight.xi) and np.array_equal(resumed.theta, straight.theta)


def test_a_checkpoint_without_the_newer_settings_loads_with_what_it_was_trained_with(tmp_path):
    import json

    lrn = train_hybrid(parse_spec(OVERSHOOT), SHORT, runs=1, trials=1, seed=0)
    d = lrn.state_dict()
    meta = json.loads(str(d["meta"]))
    for k in ("critic_init", "qdot_grid", "noise_tau", "q_warp"):
        del meta["settings"][k]
    d["meta"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "old.npz", **d)
    old = load_learner(tmp_path / "old.npz")
    assert old.features.bounds[1] == (-5.0, 5.0)  # the grid it was trained on
    assert old.settings.noise_tau == 0.0 and old.settings.critic_init == "zero" and old.settings.q_warp == 1.0
    np.testing.assert_allclose(old.features.centres_in(0), np.linspace(-1, 1, 10))
    assert load_learner_roundtrip(lrn, tmp_path).features.bounds[1] == (-1.5, 1.5)


def load_learner_roundtrip(lrn, tmp_path):
    lrn.save(tmp_path / "new.npz")
    return load_learner(tmp_path / "new.npz")


def test_divergence_and_bad_settings_are_training_errors():
    spec = parse_spec(OVERSHOOT)
    with pytest.raises(TrainingError, match="diverged"):
        train_hybrid(spec, HyrlSettings(alpha_c=1e4, trial_s=3.0), runs=2, trials=3, seed=0)
    with pytest.raises(TrainingError, match="gamma"):
        HybridLearner(spec, HyrlSettings(gamma=1.5))
    with pytest.raises(TrainingError, match="saturation"):
        HybridLearner(spec, HyrlSettings(saturation="maybe"))
    with pytest.raises(TrainingError, match="critic_init"):
        HybridLearner(spec, HyrlSettings(critic_init="random"))
    with pytest.raises(TrainingError, match="noise_tau"):
        HybridLearner(spec, HyrlSettings(noise_tau=-0.1))
    with pytest.raises(TrainingError, match="qdot_grid"):
        HybridLearner(spec, HyrlSettings(qdot_grid=0.0))
    for bad in (0.0, 1.5, float("nan")):
        with pytest.raises(TrainingError, match="q_warp"):
            HybridLearner(spec, HyrlSettings(q_warp=bad))
    with pytest.raises(TrainingError, match="names no plant"):
        HybridLearner(parse_spec("init q in [-1, 1]\nrequire overshoot <= 0\n"))


# ------------------------------------------------------------------ learning


def test_short_training_improves_the_return():
    # the thesis: "for a fixed initial value of -1, the learning curve converged very nicely"
    spec = parse_spec(OVERSHOOT.replace("q in [-1, 1]", "q = -1"))
    learner = train_hybrid(spec, HyrlSettings(trial_s=3.0), runs=4, trials=300, seed=2)
    first, last = learner.returns[:, :30].mean(), learner.returns[:, -30:].mean()
    assert last > first + 150, (first, last)
    ev = evaluate(learner, n_init=1)
    assert not ev.visited_p.any()  # the greedy policies never overshoot


def test_greedy_rollouts_and_evaluation():
    spec = parse_spec(OVERSHOOT)
    learner = train_hybrid(spec, SHORT, runs=2, trials=3, seed=1)
    ro1 = learner.rollout(np.array([[-1.0, 0.0], [0.5, 0.0], [-0.2, 0.0]]))
    ro2 = learner.rollout(np.array([[-1.0, 0.0], [0.5, 0.0], [-0.2, 0.0]]))
    assert np.array_equal(ro1.states, ro2.states) and ro1.states.shape == (3, 16, 2)
    ev = evaluate(learner, n_init=6)
    np.testing.assert_allclose(ev.q0, np.linspace(-1, 1, 6))
    v = check(spec, ev.rollout.states[:, :, 0], learner.dt)
    np.testing.assert_array_equal(ev.passed.ravel(), v.all)
    assert ev.passed.shape == (2, 6) and 0.0 <= ev.success_rate() <= ev.state_rate() <= 1.0


# ------------------------------------------------------------------ composition


def test_composition_runs_each_mode_with_the_policy_learned_for_it(md_specs):
    rise = HybridLearner(md_specs["rise_time"], runs=2, seed=0)
    over = HybridLearner(md_specs["overshoot"], runs=2, seed=0)
    # hand-set policies: constants per mode (normalised features sum to one)
    rise.xi[:, rise.automaton.index("I"), :] = 1.0
    rise.xi[:, rise.automaton.index("E_tr"), :] = 2.5
    over.xi[:, over.automaton.index("E_Mp"), :] = -4.0
    over.xi[:, over.automaton.index("S"), :] = 0.25
    over.xi[:, over.automaton.index("P"), :] = -0.5
    ctl = compose(md_specs["overshoot_rise_time"], [rise, over])
    assert ctl.describe() == {
        "E_tr": "rise_time:E_tr",
        "E_Mp": "overshoot:E_Mp",
        "I": "rise_time:I",
        "S": "overshoot:S",
        "P": "overshoot:P",
    }
    ro = ctl.rollout(np.array([[-1.0, 0.0], [-0.6, 0.0]]))
    expected = {"I": 1.0, "E_tr": 2.5, "E_Mp": -4.0, "S": 0.25, "P": -0.5}
    names = ctl.automaton.names
    for b in range(2):
        want = [expected[names[m]] for m in ro.modes[b, :-1]]
        np.testing.assert_allclose(ro.actions[b], want)
    assert set(names[m] for m in np.unique(ro.modes)) >= {"I", "E_tr"}
    with pytest.raises(TrainingError, match="no learned policy for mode"):
        compose(md_specs["overshoot_rise_time"], [over])


def test_brake_bound_tells_which_handovers_any_overshoot_policy_could_still_stop(md_specs):
    # a constant 0.8 N push in I and E_tr: from q0 = -1 the mass enters E_Mp at
    # (-0.0996 m, 1.638 m/s), which full braking (20 m/s^2) stops in 0.067 m < 0.0996;
    # from -0.75 at (-0.0358, 1.465), which needs 0.054 m; from -0.5 it never enters E_Mp
    # (too slow for the window: P) and overshoots
    rise = HybridLearner(md_specs["rise_time"], runs=1, seed=0)
    over = HybridLearner(md_specs["overshoot"], runs=1, seed=0)
    rise.xi[:] = 0.8
    over.xi[:] = 0.0
    ctl = compose(md_specs["overshoot_rise_time"], [rise, over])
    ev = ctl.evaluate(3)
    ok = brake_bound(ev, ctl.automaton, ctl.plant, ctl.params)
    assert ok.tolist() == [[True, False, False]]
    assert (ev.measured["overshoot"] > 0).all()  # the zero E_Mp policy does not brake
    ro = ev.rollout
    k = np.argmax(ro.modes == ro.names.index("E_Mp"), axis=1)
    x = ro.states[np.arange(3), k]
    np.testing.assert_allclose(x[:2], [[-0.0996, 1.638], [-0.0358, 1.465]], atol=1e-3)


def test_train_handover_retrains_only_the_modes_after_the_handover_on_a_copy(md_specs):
    rise = HybridLearner(md_specs["rise_time"], runs=2, seed=0)
    over = HybridLearner(md_specs["overshoot"], runs=2, seed=0)
    rise.xi[:] = 0.8  # hands over at about 1.6 m/s, 0.1 m before the set-point from q0 = -1
    ctl = compose(md_specs["overshoot_rise_time"], [rise, over])
    before = ctl.evaluate(3)
    xi_rise, xi_over, th_over = rise.xi.copy(), over.xi.copy(), over.theta.copy()
    new, lrn = train_handover(ctl, over, 60)
    assert lrn is not over and new.describe() == ctl.describe()
    np.testing.assert_array_equal(rise.xi, xi_rise)
    np.testing.assert_array_equal(over.xi, xi_over)
    np.testing.assert_array_equal(over.theta, th_over)
    A = over.automaton
    np.testing.assert_array_equal(lrn.xi[:, A.index("I")], xi_over[:, A.index("I")])  # I is run by rise
    assert np.abs(lrn.xi[:, A.index("E_Mp")] - xi_over[:, A.index("E_Mp")]).max() > 0.1
    after = new.evaluate(3)
    # from q0 = -1 the untrained policy coasts far past the set-point; after 60 trials it brakes
    assert (before.measured["overshoot"][:, 0] > 1.0).all()
    assert (after.measured["overshoot"][:, 0] < 0.5 * before.measured["overshoot"][:, 0]).all()
    _, short = train_handover(ctl, over, 8)
    _, again = train_handover(ctl, over, 8)  # same seed, same numbers
    np.testing.assert_array_equal(again.xi, short.xi)
    # it explores with HANDOVER_SIGMA (2 N) unless told to keep the learner's own (1 N)
    assert lrn.settings.sigma == HANDOVER_SIGMA == 2.0 and over.settings.sigma == 1.0
    _, own = train_handover(ctl, over, 8, sigma=None)
    assert own.settings.sigma == 1.0 and np.abs(own.xi - short.xi).max() > 1e-3
    _, same = train_handover(ctl, over, 8, sigma=1.0)
    np.testing.assert_array_equal(same.xi, own.xi)
    with pytest.raises(TrainingError, match="sigma"):
        train_handover(ctl, over, 1, sigma=-1.0)
