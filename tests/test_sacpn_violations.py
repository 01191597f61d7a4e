"""SACPN under violation-aware rewards: the known penalty value, the penalty ramp, success."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.monitor.offline import monitor
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.spec.parse import load_spec

SPECS = Path(__file__).resolve().parent.parent / "specs" / "pendulum"


def _p2_unit(violations: str = "permanent"):
    spec = load_spec(SPECS / "unit_weights" / "p2_avoid.mitl")
    return spec, compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))


def test_known_penalty_value_cancels_the_penalty_after_a_violation() -> None:
    """delta's penalty part: -c charge + pen_k G_k - gamma pen_k+1 G_k+1.

    On a step between two violated markings it is 0 (the critic owes nothing to
    the penalty after the first violation); on the step into a violation it is
    the whole discounted penalty to the end of the trial, -c G_k+1 gamma - c.
    """
    _, rs = _p2_unit()
    agent = Sacpn(rs, runs=1)
    g, n = agent.settings.gamma, agent.n_steps
    G = agent._pen_left
    assert G[n] == 0.0 and G[n - 1] == 1.0
    assert np.allclose(G[:-1], 1.0 + g * G[1:])
    assert G[0] == pytest.approx((1 - g**n) / (1 - g))
    charge, pen, c = agent.runtime.tables.charge, agent._pen, rs.penalty
    assert c == 5.0
    both = np.flatnonzero(pen > 0)
    none = np.flatnonzero(pen == 0)
    assert both.size and none.size
    for k in (0, 37, n - 1):
        part = -c * charge + pen[:, None] * G[k] - g * G[k + 1] * pen[None, :]
        assert np.allclose(part[np.ix_(both, both)], 0.0)
        into = part[np.ix_(none, both)]
        assert np.allclose(into, -c * (1 + g * G[k + 1]))
        assert np.allclose(part[np.ix_(none, none)], 0.0)


def test_without_violation_places_the_critic_is_the_actor() -> None:
    _, rs = _p2_unit()
    known = Sacpn(rs, runs=1)
    learned = Sacpn(rs, SacpnSettings(violation_value="learned"), runs=1)
    assert known.n_tokens == known.n_tokens_c == 1  # the region net only
    assert learned.n_tokens == 1 and learned.n_tokens_c == 3  # ... and both violation nets


def test_penalty_ramp_schedule_and_recorded_returns() -> None:
    """The ramp changes what the learner is paid, never the returns it records."""
    _, rs = _p2_unit()
    frozen = SacpnSettings(alpha_a=0.0, alpha_c=0.0)  # no learning: the same trajectories
    ramped = Sacpn(rs, frozen, runs=4, seed=3)
    full = Sacpn(rs, SacpnSettings(alpha_a=0.0, alpha_c=0.0, penalty_ramp=0.0), runs=4, seed=3)
    a = ramped.train(4, total=8)
    b = full.train(4)
    assert ramped.ramp_trials == 6 and full.ramp_trials == 0
    assert [ramped.penalty_scale(t) for t in (0, 3, 6, 9)] == [0.0, 0.5, 1.0, 1.0]
    assert np.array_equal(a, b)
    assert (a < -100).any()  # random inputs enter psi: the full penalty is in the returns


def test_penalty_ramp_changes_learning_and_resumes_to_the_bit(tmp_path: Path) -> None:
    _, rs = _p2_unit()
    straight = Sacpn(rs, runs=3, seed=5)
    straight.train(6)
    flat = Sacpn(rs, SacpnSettings(penalty_ramp=0.0), runs=3, seed=5)
    flat.train(6)
    assert not np.array_equal(straight.xi, flat.xi)
    first = Sacpn(rs, runs=3, seed=5)
    first.train(3, total=6)
    first.save(tmp_path / "ck.npz")
    second = Sacpn(rs, runs=3, seed=5)
    second.load(tmp_path / "ck.npz")
    assert second.ramp_trials == 4
    second.train(3)
    assert np.array_equal(second.xi, straight.xi) and np.array_equal(second.theta, straight.theta)
    assert np.array_equal(second.returns, straight.returns)


def test_off_has_no_charge_and_no_ramp() -> None:
    _, rs = _p2_unit("off")
    agent = Sacpn(rs, runs=1)
    agent.train(1)
    assert rs.charge is None and agent.ramp_trials == 0
    assert not agent.runtime.tables.charge.any()


def test_problem_2_with_equal_weights_learns_to_go_round_psi() -> None:
    """Issue 5's acceptance at test size: (4-15) with the option, 30 runs, 2000 trials."""
    spec, rs = _p2_unit()
    agent = Sacpn(rs, runs=30, seed=0)
    agent.train(2000)
    ro = agent.rollout(agent.evaluation_states())
    verdict = monitor(spec, ro.states, ro.dt)
    assert verdict.satisfied.mean() >= 0.9
    assert not (np.abs(ro.states[verdict.satisfied, :, 0] - 1.2) < 0.87).any()  # never in psi
