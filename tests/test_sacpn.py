"""SACPN: reproducibility, checkpoints, learning, and the pieces of its hot path."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numerics import same

from mitlc.errors import TrainingError
from mitlc.learn.features import RbfFeatures
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.petri.compile import compile_spec
from mitlc.plants import make_integrator
from mitlc.plants.base import PLANTS
from mitlc.spec.parse import parse_spec

P1 = """
plant pendulum(u_max = 3)
init q = pi, qdot = 0
horizon 3
prop kappa = abs(q) < 0.3
formula F G kappa
"""

P2 = """
plant pendulum(u_max = 10)
init q in [2.4, pi], qdot = 0
horizon 3
prop kappa = abs(q) < 0.3
prop psi   = 0.3 < q < pi/2 + 0.5
formula F G kappa & 10 * G !psi
"""

P5 = """
plant pendulum(u_max = 10)
init q in [-pi/2, pi/2], qdot = 0
horizon 3
prop kappa = -pi < q < -pi + 0.5 or pi - 0.5 < q < pi
option clock = trial
formula 2 * !kappa U(1,2] (3 * kappa U(2,inf) G !kappa)
"""


def agent(text: str = P2, runs: int = 3, seed: int = 5, **settings) -> Sacpn:
    return Sacpn(compile_spec(parse_spec(text)), SacpnSettings(**settings), runs=runs, seed=seed)


# ------------------------------------------------------------------ reproducibility


@pytest.mark.parametrize("text", [P2, P5])
def test_same_seed_gives_bit_identical_returns(text):
    a, b = agent(text), agent(text)
    ra, rb = a.train(4), b.train(4)
    np.testing.assert_array_equal(ra, rb)
    np.testing.assert_array_equal(a.xi, b.xi)
    np.testing.assert_array_equal(a.theta, b.theta)
    c = agent(text, seed=6)
    assert not np.array_equal(c.train(4), ra)


def test_a_runs_numbers_do_not_depend_on_the_batch_size():
    one, three = agent(runs=1), agent(runs=3)
    np.testing.assert_array_equal(one.sample_init(one.rngs), three.sample_init(three.rngs)[:1])
    np.testing.assert_allclose(one.train(3)[0], three.train(3)[0], rtol=1e-9, atol=1e-9)


def test_resume_after_interruption_equals_uninterrupted(tmp_path):
    # width 1: at the default 0.5 the anti-wind-up's branch flips on the last-place differences of an
    # AVX-512 numpy's exp, and the paths part by 1.6e-8 after 6 trials (bit-equal where numpy is libm)
    whole = agent(rbf_width=1.0)
    whole.train(6)

    first = agent(kernel="numpy", rbf_width=1.0)  # the numpy trial calls integrate, where the interrupt is injected
    calls = {"n": 0}
    real = first.integrate

    def flaky(x, u):
        calls["n"] += 1
        if calls["n"] == 3 * first.n_steps + 17:  # in the middle of trial 4
            raise KeyboardInterrupt
        real(x, u)

    first.integrate = flaky
    with pytest.raises(KeyboardInterrupt):
        first.train(6)
    assert first.trial == 3  # rolled back to the end of the last complete trial
    first.save(tmp_path / "ckpt.npz")

    resumed = agent(seed=99, rbf_width=1.0)  # the checkpoint's seed and generator states win
    resumed.load(tmp_path / "ckpt.npz")
    assert resumed.trial == 3
    resumed.train(3)
    # whole and resumed train on the kernel (auto), first on numpy: equal bits where numpy is libm
    assert same(resumed.xi, whole.xi) and same(resumed.theta, whole.theta)
    assert same(resumed.returns, whole.returns)
    if whole.kernel == "numpy":  # no numba: one path, the bits
        np.testing.assert_array_equal(resumed.xi, whole.xi)


# ------------------------------------------------------------------ learning


def test_a_short_training_run_improves_the_return():
    a = agent(P2, runs=6, seed=0)
    returns = a.train(150)
    early, late = returns[:, :20].mean(), returns[:, -20:].mean()
    assert late > early + 100, (early, late)
    ro = a.rollout(a.evaluation_states())
    assert ro.returns.mean() > 0


def test_printed_masking_and_no_anti_windup_are_available():
    base = agent(runs=2).train(3)
    nxt = agent(runs=2, mask="next").train(3)
    raw = agent(runs=2, saturation="none").train(3)
    assert nxt.shape == raw.shape == base.shape
    assert not np.array_equal(nxt, base)


def _max_raw_output(a: Sacpn) -> float:
    rng = np.random.default_rng(0)
    x = np.column_stack([rng.uniform(-math.pi, math.pi, 400), rng.uniform(-15, 15, 400)])
    phi = a.features(x)
    worst = 0.0
    for code in range(a.runtime.n_codes):
        rows = a.xi[np.arange(400) % a.runs][:, a.runtime.tables.marked[code]]  # (400, K, F)
        worst = max(worst, float(np.abs(np.einsum("rkf,rf->r", rows, phi)).max() / a.n_tokens))
    return worst


@pytest.mark.parametrize(("width", "bound"), [(1.0, 2.5), (0.5, 4.5)])
def test_anti_windup_keeps_the_policy_output_near_the_bound(width, bound):
    """Measured: width 1 keeps the raw output at 19.9 (30.7 without), width 0.5 at 39.5 (49.9 without):
    narrower features spill less of a blocked update's neighbours' growth back, so they sit higher."""
    applied = agent(P2, runs=4, seed=1, sigma=5.0, rbf_width=width)
    applied.train(150)
    none = agent(P2, runs=4, seed=1, sigma=5.0, saturation="none", rbf_width=width)
    none.train(150)
    assert _max_raw_output(applied) < bound * applied.u_max
    assert _max_raw_output(applied) < 0.85 * _max_raw_output(none)


def test_a_diverged_run_is_marked_and_only_all_of_them_raise():
    a = agent(runs=2)
    a.theta[1, 0, 3] = np.nan
    returns = a.train(2)
    assert a.diverged.tolist() == [-1, 1] and np.isnan(returns[1]).all() and np.isfinite(returns[0]).all()
    a.theta[0, 0, 3] = np.inf
    with pytest.raises(TrainingError, match="every run diverged"):
        a.train(1)
    assert a.diverged.tolist() == [3, 1] and a.trial == 2  # the failed trial is not counted


def test_bad_settings_are_training_errors():
    with pytest.raises(TrainingError):
        agent(mask="later")
    with pytest.raises(TrainingError):
        agent(gamma=1.5)


def test_greedy_rollout_shapes_and_bounds():
    a = agent(P5, runs=2)
    a.train(2)
    ro = a.rollout(np.array([[0.0, 0.0], [1.0, 0.0], [-1.0, 0.0]]))
    assert ro.states.shape == (3, a.n_steps + 1, 2)
    assert ro.actions.shape == ro.rewards.shape == (3, a.n_steps)
    assert np.abs(ro.actions).max() <= 10.0
    assert (ro.states[:, :, 0] >= -math.pi).all() and (ro.states[:, :, 0] < math.pi).all()
    # the rollout's rewards are the runtime's for its markings
    rt = a.runtime
    np.testing.assert_array_equal(ro.rewards, rt.tables.reward[ro.codes[:, :-1], ro.codes[:, 1:]])


def test_initial_states_come_from_the_init_ranges():
    a = agent(P2, runs=50)
    x = a.sample_init(a.rngs)
    assert (x[:, 0] >= 2.4).all() and (x[:, 0] <= math.pi).all() and (x[:, 1] == 0).all()


# ------------------------------------------------------------------ hot-path pieces


@pytest.mark.parametrize("u_max", [3.0, 10.0])
def test_fused_pendulum_step_equals_plant_step(u_max):
    plant = PLANTS["pendulum"]
    params = plant.params({"u_max": u_max})
    rng = np.random.default_rng(1)
    x = np.column_stack([rng.uniform(-math.pi, math.pi, 64), rng.uniform(-47, 47, 64)])
    u = rng.uniform(-15, 15, 64)
    ref = plant.step(x.copy(), u, params)
    fast = x.copy()
    make_integrator(plant, params)(fast, u)
    dq = (fast[:, 0] - ref[:, 0] + math.pi) % (2 * math.pi) - math.pi
    assert np.abs(dq).max() < 1e-12 and np.abs(fast[:, 1] - ref[:, 1]).max() < 1e-11
    xt = np.ascontiguousarray(x.T)  # the trainer's transposed layout gives the same numbers
    make_integrator(plant, params)(xt.T, u)
    np.testing.assert_array_equal(xt.T, fast)


def test_rbf_features_are_normalised_gaussians_and_periodic_in_the_angle():
    plant = PLANTS["pendulum"]
    f = RbfFeatures.for_state(plant.state, (10, 10), 1.0, {"qdot": (-20.0, 20.0)})
    x = np.array([[math.pi - 1e-9, 1.0], [-math.pi + 1e-9, 1.0], [0.3, -50.0], [0.3, -20.0]])
    phi = f(x)
    np.testing.assert_allclose(phi.sum(axis=1), 1.0)
    np.testing.assert_allclose(phi[0], phi[1], atol=1e-8)  # wraps
    np.testing.assert_allclose(phi[2], phi[3])  # clipped to the feature range
    # against the definition: exp((cos(q - c) - 1) / w^2) * exp(-(v - d)^2 / (2 w_v^2)), normalised
    q, v = 0.7, 3.0
    cq = -math.pi + 2 * math.pi * np.arange(10) / 10
    wq = 2 * math.pi / 10
    cv = np.linspace(-20, 20, 10)
    wv = 40 / 9
    g = np.exp((np.cos(q - cq) - 1) / wq**2)
    h = np.exp(-((v - cv) ** 2) / (2 * wv**2))
    ref = np.outer(g, h).ravel()
    np.testing.assert_allclose(f(np.array([[q, v]]))[0], ref / ref.sum(), rtol=1e-10)


def test_settings_round_trip():
    s = SacpnSettings(sigma=2.0, mask="next", rbf=(8, 6))
    assert SacpnSettings.from_dict(s.to_dict()) == s


def test_a_net_too_large_to_tabulate_is_a_clear_error():
    """Twelve nested (so never disjoint) propositions make 2^12 region markings, more pairs than the
    runtime tabulates: SACPN says so instead of failing inside the first trial."""
    from mitlc.errors import TrainingError
    from mitlc.petri.compile import compile_spec
    from mitlc.spec.parse import parse_spec

    props = "\n".join(f"prop a{i} = q > {i / 10}" for i in range(12))
    conj = " & ".join(f"F a{i}" for i in range(12))
    rs = compile_spec(parse_spec(f"plant pendulum\ninit q in [0, 1], qdot = 0\nhorizon 1\n{props}\nformula {conj}"))
    assert rs.net.subnets and len(rs.net.subnets) >= 12
    with pytest.raises(TrainingError, match="too many markings"):
        Sacpn(rs, SacpnSettings(), runs=1)
