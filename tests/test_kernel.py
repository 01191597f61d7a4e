"""SACPN's fused trial kernel (mitlc.learn.sacpn.kernel) against the numpy trial, the reference.

Exactness: to the bit (returns, actor and critic parameters), no tolerance, wherever
numpy's float64 sin/cos/exp are the C library's (numba's are): both paths sum in numpy's
pairwise order. On a machine with AVX-512, numpy computes them with its own SIMD code,
which rounds some results differently in the last place (``LIBM`` below says which kind
this machine is); there the in-process checks allow ``RTOL`` of the parameters' size and
the bits are checked in a process of its own with numpy held to its x86-64-v2 baseline
(``golden.PORTABLE``), as the golden trainings are.

The uncompiled kernel (plain Python, ``jit`` the identity) runs without numba: that test
is what keeps the two copies of Algorithm 1 from drifting apart.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numerics import LIBM, same

from mitlc.errors import TrainingError
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.learn.sacpn import kernel as fk
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.plants import PLANTS, make_integrator
from mitlc.plants.base import pairwise_sum
from mitlc.runtime.atoms import compile_atoms, compile_predicate, scalar_atoms
from mitlc.spec import predicates as P
from mitlc.spec.parse import load_spec, parse_spec

ROOT = Path(__file__).resolve().parent.parent
SPECS = [
    "pendulum/p1_swing_up",
    "pendulum/p2_avoid",
    "pendulum/p3_avoid_speed_limit",
    "pendulum/p4_alternate",
    "pendulum/p5_timed_visit",
    "mass-damper: F G near",
    "mass-damper: F G near & 5 * G !fast",
]
MASS_DAMPER = """plant mass-damper
init q in [-1, 1], qdot in [-0.5, 0.5]
horizon 2
prop near = abs(q) < 0.1
prop fast = abs(qdot) > 1.5 and q * qdot > 0
formula {}
"""


NESTED = """plant pendulum(u_max = 5)
init q in [-1, 1], qdot in [-3, 3]
horizon 1
prop a = abs(q) < 0.5
prop b = abs(qdot) < 1.5
formula {}
"""
TIMED = [  # timed obligations (nested intervals, clock = standard): the kernel steps their engine
    "pendulum/n1_reach_in_time",
    "pendulum/n2_hold_up",
    "pendulum/n3_bounded_response",
    "pendulum/n4_recurring_window",
    "nested: F[0,2] G[0,1] a",
    "nested: F[0,0.3] G[0,0.2] a & G b",
    "nested: 3 * G (a -> F[0,0.5] b)",
    "nested: a U[0,0.6] G[0,0.15] b",
    "nested: b R[0.1,0.6] F[0,0.2] a",
    "nested: G[0,0.3] F[0.1,0.4] a | F G b",
]


def rs_of(name: str, violations: str = "off"):
    if name.startswith("mass-damper: "):  # the shipped mass-damper specs are HyRL requirements
        spec = parse_spec(MASS_DAMPER.format(name.removeprefix("mass-damper: ")))
    elif name.startswith("nested: "):
        spec = parse_spec(NESTED.format(name.removeprefix("nested: ")))
    else:
        spec = load_spec(ROOT / "specs" / f"{name}.mitl")
    return compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))


def same_trials(rs, settings: SacpnSettings, jit, trials: int, runs: int = 3, ramp: int = 0) -> None:
    """``trials`` trials of the numpy trial and of the kernel from the same seed: equal bits."""
    a = Sacpn(rs, settings, runs=runs, seed=3)
    b = Sacpn(rs, settings, runs=runs, seed=3)
    a.ramp_trials = b.ramp_trials = ramp
    fused = b.fused_trial(jit)
    for _ in range(trials):
        ra, rb = a._trial_numpy(), fused()
        a.trial += 1
        b.trial += 1
        assert same(ra, rb)
        assert same(a.xi, b.xi) and same(a.theta, b.theta)
    assert np.abs(a.theta).max() > 0  # it learned something


SMALL = {"rbf": (4, 3), "trial_s": 0.9}
VARIANTS = [
    {},
    {"mask": "next"},
    {"saturation": "none", "bootstrap_timeout": False},
]


@pytest.mark.parametrize("name", SPECS)
@pytest.mark.parametrize("variant", range(len(VARIANTS)))
def test_uncompiled_kernel_is_the_numpy_trial(name: str, variant: int) -> None:
    same_trials(rs_of(name), SacpnSettings(kernel="numpy", **SMALL, **VARIANTS[variant]), fk.identity, trials=2)


def test_uncompiled_kernel_at_the_input_bounds() -> None:
    """Problem 1's weak motor (u_max 3) with wide exploration: the policy's output passes the
    input box, and the actor's update is held where it would push further out (anti-windup)."""
    rs = rs_of("pendulum/p1_swing_up")
    st = SacpnSettings(kernel="numpy", rbf=(4, 3), trial_s=0.9, sigma_frac=1.0, alpha_a=2.0)
    same_trials(rs, st, fk.identity, trials=4)


@pytest.mark.parametrize("violations", ["permanent", "counted"])
def test_uncompiled_kernel_with_violations_and_the_penalty_ramp(violations: str) -> None:
    rs = rs_of("pendulum/p2_avoid", violations)
    for value in ("known", "learned"):
        st = SacpnSettings(kernel="numpy", violation_value=value, **SMALL)
        same_trials(rs, st, fk.identity, trials=3, ramp=2)  # s_pen 0, 0.5, then 1


@pytest.mark.parametrize("name", TIMED)
@pytest.mark.parametrize("variant", range(len(VARIANTS)))
def test_uncompiled_kernel_with_timed_obligations(name: str, variant: int) -> None:
    rs = rs_of(name)
    assert rs.timed
    same_trials(rs, SacpnSettings(kernel="numpy", **SMALL, **VARIANTS[variant]), fk.identity, trials=2)


@pytest.mark.parametrize("violations", ["permanent", "counted"])
def test_uncompiled_kernel_with_timed_obligations_and_violations(violations: str) -> None:
    for name in ("pendulum/n3_bounded_response", "nested: 3 * G (a -> F[0,0.5] b)"):
        st = SacpnSettings(kernel="numpy", **SMALL)
        same_trials(rs_of(name, violations), st, fk.identity, trials=3, ramp=2)


# Compiled: one spec per kind of predicate and net (each new set of predicates is a compile
# of several seconds); the uncompiled test above runs all of SPECS.
COMPILED = ["pendulum/p1_swing_up", "pendulum/p3_avoid_speed_limit", "pendulum/p4_alternate", SPECS[-1]]


@pytest.mark.parametrize("name", COMPILED)
def test_compiled_kernel_is_the_numpy_trial(name: str) -> None:
    pytest.importorskip("numba")
    same_trials(rs_of(name), SacpnSettings(kernel="numpy"), fk.jit, trials=3)


def test_compiled_kernel_variants_and_violations() -> None:
    pytest.importorskip("numba")
    same_trials(rs_of("pendulum/p4_alternate"), SacpnSettings(kernel="numpy", mask="next"), fk.jit, trials=2)
    st = SacpnSettings(kernel="numpy", saturation="none", bootstrap_timeout=False)
    same_trials(rs_of("pendulum/p1_swing_up"), st, fk.jit, trials=2)
    same_trials(rs_of("pendulum/p3_avoid_speed_limit", "permanent"), SacpnSettings(), fk.jit, trials=3, ramp=2)


@pytest.mark.parametrize("name", TIMED[:4])
def test_compiled_kernel_with_timed_obligations(name: str) -> None:
    """N1..N4, whole trials at the spec's horizon (the windows of seconds, tens of samples)."""
    pytest.importorskip("numba")
    same_trials(rs_of(name), SacpnSettings(kernel="numpy"), fk.jit, trials=3)
    if name == "pendulum/n3_bounded_response":  # the same predicates: the same compiled kernel
        st = SacpnSettings(kernel="numpy", mask="next")
        same_trials(rs_of(name, "permanent"), st, fk.jit, trials=3, ramp=2)


def test_train_with_auto_equals_numpy() -> None:
    pytest.importorskip("numba")
    rs = rs_of("pendulum/p2_avoid", "permanent")
    a = Sacpn(rs, SacpnSettings(kernel="numpy"), runs=2, seed=5)
    b = Sacpn(rs, SacpnSettings(kernel="auto"), runs=2, seed=5)
    assert (a.kernel, b.kernel, b.kernel_reason) == ("numpy", "numba", None)
    assert same(a.train(4), b.train(4))
    assert same(a.xi, b.xi) and same(a.theta, b.theta)


def test_compiled_in_memory_where_the_disk_cache_is_off(monkeypatch) -> None:
    """MITLC_CACHE_DIR empty: the trial is compiled in memory by ``kernel.jit`` (numba, IEEE
    order) for the process, and trains to the numpy trial's numbers."""
    pytest.importorskip("numba")
    from mitlc.learn.sacpn import sacpn as sacpn_module

    monkeypatch.setenv("MITLC_CACHE_DIR", "")
    monkeypatch.setattr(sacpn_module, "_KERNELS", {})
    rs = rs_of("pendulum/p3_avoid_speed_limit", "permanent")
    a = Sacpn(rs, SacpnSettings(kernel="numpy"), runs=2, seed=3)
    b = Sacpn(rs, SacpnSettings(kernel="numba"), runs=2, seed=3)
    assert b.kernel == "numba" and type(b._kernel_fn).__name__ == "CPUDispatcher"
    # IEEE order kept (no fastmath), numpy's error model: what makes the bits numpy's
    assert b._kernel_fn.targetoptions["fastmath"] is False
    assert b._kernel_fn.targetoptions["error_model"] == "numpy"
    assert same(a.train(3), b.train(3))
    assert same(a.xi, b.xi) and same(a.theta, b.theta)


def test_compiled_kernel_to_the_bit_in_a_portable_process() -> None:
    """Where this machine's numpy rounds sin/cos/exp its own way: the bits, with numpy at its baseline."""
    pytest.importorskip("numba")
    if LIBM:
        pytest.skip("numpy is the C library here: the in-process tests already compared bits")
    from golden import PORTABLE

    code = (
        "import test_kernel as t\n"
        "assert t.LIBM, 'numpy at its baseline is still not the C library'\n"
        "t.same_trials(t.rs_of('pendulum/p1_swing_up'), t.SacpnSettings(kernel='numpy'), t.fk.jit, trials=3)\n"
        "t.same_trials(t.rs_of('pendulum/p4_alternate'), t.SacpnSettings(kernel='numpy'), t.fk.jit, trials=3)\n"
        "for name in t.TIMED:\n"  # timed obligations: the uncompiled kernel on all, the compiled one on N1..N4
        "    t.same_trials(t.rs_of(name), t.SacpnSettings(kernel='numpy', **t.SMALL), t.fk.identity, trials=2)\n"
        "for name in t.TIMED[:4]:\n"
        "    t.same_trials(t.rs_of(name), t.SacpnSettings(kernel='numpy'), t.fk.jit, trials=3)\n"
    )
    env = {**os.environ, **PORTABLE}
    run = subprocess.run(
        [sys.executable, "-c", code], cwd=Path(__file__).parent, env=env, capture_output=True, text=True, check=False
    )
    assert run.returncode == 0, run.stdout + run.stderr


def test_timed_obligations_train_on_the_kernel() -> None:
    pytest.importorskip("numba")
    rs = rs_of("pendulum/n2_hold_up")
    a = Sacpn(rs, SacpnSettings(kernel="numpy"), runs=2, seed=5)
    b = Sacpn(rs, SacpnSettings(kernel="auto"), runs=2, seed=5)
    assert (b.kernel, b.kernel_reason) == ("numba", None)
    assert same(a.train(3), b.train(3))
    assert same(a.xi, b.xi) and same(a.theta, b.theta)
    # the learner's own runtime is not the kernel's obligations: a rollout still steps it
    assert same(a.rollout(a.evaluation_states()).codes, b.rollout(b.evaluation_states()).codes)


def test_fallback_for_timed_obligations_with_compact_tables() -> None:
    """Codes that index reachable markings cannot move a token by arithmetic: the numpy path."""
    bounded = " & ".join(f"F[0,{1 + 0.1 * i:.1f}] b" for i in range(8))
    rs = compile_spec(parse_spec(NESTED.format(f"F[0,0.5] G a & {bounded}")))
    agent = Sacpn(rs, SacpnSettings(kernel="auto", rbf=(3, 3)), runs=1, seed=0)
    assert agent.runtime.compact and agent.runtime.timed
    assert agent.kernel == "numpy" and agent.kernel_reason is not None
    if fk.numba_available():
        assert "compact" in agent.kernel_reason
    agent.train(1)


GYM_PENDULUM = """plant gym:Pendulum-v1
state q = atan2(obs[1], obs[0]), w = obs[2] / 2 in [-4, 4]
init w in [-0.5, 0.5]
horizon 1.5
prop up = abs(q) < 0.5
prop slow = abs(w) < 1
formula {}
"""
GYM_FORMULAS = ["F G up", "F[0,1] G[0,0.3] up & G (!slow -> F[0,0.4] slow)"]


@pytest.mark.parametrize("variant", range(len(VARIANTS)))
@pytest.mark.parametrize("formula", GYM_FORMULAS)
def test_uncompiled_kernel_steps_an_environment_as_its_twin(formula: str, variant: int) -> None:
    """Pendulum-v1 in the kernel (its twin's physics, the spec's reads of the observation, the
    environment's resets): the numpy trial's bits, the torque unsaturated too (the environment clips it)."""
    pytest.importorskip("gymnasium")
    spec = parse_spec(GYM_PENDULUM.format(formula))
    rs = compile_spec(spec, CompileOptions.from_spec(spec))
    same_trials(rs, SacpnSettings(kernel="numpy", rbf=(4, 3), **VARIANTS[variant]), fk.identity, trials=3)


GYM_MOUNTAIN_CAR = """plant gym:MountainCarContinuous-v0(dt = 1)
state x = obs[0], v = obs[1]
horizon 120
prop goal = x > 0.45
prop left = x < -0.7
formula {}
"""


@pytest.mark.parametrize("variant", [0, 2])
def test_uncompiled_kernel_steps_the_mountain_car_as_its_twin(variant: int) -> None:
    """MountainCarContinuous-v0 in the kernel: float64 first steps, float32 after, copies that reach the
    goal keeping their state to the trial's end (large exploration: some do), the numpy trial's bits."""
    pytest.importorskip("gymnasium")
    spec = parse_spec(GYM_MOUNTAIN_CAR.format("F[0,60] (left & F[0,60] G goal)"))
    rs = compile_spec(spec, CompileOptions.from_spec(spec))
    st = SacpnSettings(kernel="numpy", rbf=(5, 5), sigma_frac=2.0, **VARIANTS[variant])
    same_trials(rs, st, fk.identity, trials=4, runs=4)


def test_compiled_kernel_steps_an_environment_as_its_twin() -> None:
    pytest.importorskip("gymnasium")
    pytest.importorskip("numba")
    spec = parse_spec(GYM_PENDULUM.format(GYM_FORMULAS[1]))
    rs = compile_spec(spec, CompileOptions.from_spec(spec))
    same_trials(rs, SacpnSettings(kernel="numpy"), fk.jit, trials=3)
    agent = Sacpn(rs, SacpnSettings(kernel="auto", rbf=(4, 4)), runs=2, seed=0)
    assert (agent.kernel, agent.kernel_reason) == ("numba", None)
    spec = parse_spec(GYM_MOUNTAIN_CAR.format("F G goal"))
    rs = compile_spec(spec, CompileOptions.from_spec(spec))
    same_trials(rs, SacpnSettings(kernel="numpy", sigma_frac=2.0), fk.jit, trials=3, runs=4)


def test_fallback_for_an_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    """An environment without a numpy twin trains on numpy."""
    pytest.importorskip("gymnasium")
    from mitlc.plants import gym_twins

    monkeypatch.setattr(gym_twins, "TWINS", {})
    spec = parse_spec(GYM_MOUNTAIN_CAR.format("F G goal"))
    agent = Sacpn(compile_spec(spec), SacpnSettings(kernel="auto", rbf=(4, 4)), runs=1, seed=0)
    assert agent.kernel == "numpy"
    if fk.numba_available():
        assert agent.kernel_reason == (
            "plant 'gym:MountainCarContinuous-v0' is an environment, stepped in numpy: "
            "'MountainCarContinuous-v0' has no numpy twin (mitlc.plants.gym_twins) to step it in the kernel"
        )


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ("no kernel_step", "plant 'pendulum' has no kernel_step (its one-step map for one run)"),
        ("shaped", "the reward is graded (reward = shaped): it reads the state, not only the marking"),
    ],
)
def test_fallback_reasons(change: str, reason: str) -> None:
    """kernel = auto trains on numpy, saying why, where the fused trial cannot: a plant without
    its one-step map (a user's plant file may leave it out), a reward that reads the state."""
    import dataclasses

    spec = load_spec("pendulum/p1_swing_up")
    options = CompileOptions.from_spec(spec)
    if change == "no kernel_step":
        spec = dataclasses.replace(spec, env_plant=dataclasses.replace(spec.plant, kernel_step=None))
    else:
        options = CompileOptions.from_spec(spec, reward=change)
    agent = Sacpn(compile_spec(spec, options), SacpnSettings(kernel="auto"), runs=1, seed=0)
    assert agent.kernel == "numpy"
    assert fk.unsupported(agent) == reason
    if fk.numba_available():
        assert agent.kernel_reason == reason


def test_kernel_setting_is_checked(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(TrainingError, match="unknown kernel"):
        SacpnSettings(kernel="fast").check()
    rs = rs_of("pendulum/p1_swing_up")
    assert Sacpn(rs, SacpnSettings(kernel="numpy")).kernel_reason == "kernel = numpy"
    monkeypatch.setattr(fk, "numba_available", lambda: False)
    with pytest.raises(TrainingError, match="needs numba"):
        Sacpn(rs, SacpnSettings(kernel="numba"))
    agent = Sacpn(rs, SacpnSettings(kernel="auto"))
    assert (agent.kernel, agent.kernel_reason) == ("numpy", "numba is not installed")


@pytest.mark.parametrize("plant", ["pendulum", "mass-damper", "unicycle"])
def test_plant_kernel_step_is_the_batched_step(plant: str) -> None:
    pl = PLANTS[plant]
    p = pl.params()
    rng = np.random.default_rng(0)
    x = rng.uniform([v.lo for v in pl.state], [v.hi for v in pl.state], (200, len(pl.state)))
    lo, hi = pl.input_box(p)  # inputs up to twice their boxes: the clips are in the step
    u = rng.uniform(2 * lo, 2 * hi, (200, pl.n_inputs)) if pl.n_inputs > 1 else rng.uniform(2 * lo, 2 * hi, 200)
    batched = x.copy()
    make_integrator(pl, p)(batched, u)
    step, consts, work = pl.kernel_step(pl, p, fk.identity)
    one = x.copy()
    scratch = np.empty(work)
    for r in range(len(u)):
        step(one[r], u[r], consts, scratch)
    assert np.array_equal(one, batched)
    assert np.allclose(batched, pl.step(x.copy(), u, p), rtol=1e-12, atol=1e-12)


def test_pairwise_sum_is_numpys_reduce() -> None:
    rng = np.random.default_rng(1)
    for n in (1, 5, 7, 8, 9, 100, 128, 129, 300, 1600):
        a = rng.standard_normal((3, n))
        assert [pairwise_sum(row, 0, n) for row in a] == list(np.add.reduce(a, axis=1))


def test_atom_code_of_the_generated_predicates() -> None:
    rs = rs_of("pendulum/p4_alternate")
    agent = Sacpn(rs, SacpnSettings(kernel="numpy"))
    rt = agent.runtime
    atoms = compile_atoms(rt.preds, rt.columns, fk.identity)
    x = np.random.default_rng(2).uniform([-np.pi, -20], [np.pi, 20], (500, 2))
    assert [atoms(row) for row in x] == list(rt.atom_code(x))


# ------------------------------------------------------------ one sample in plain Python
_COLS = {"q": 0, "v": 1}
_NUMS = st.sampled_from([0.0, -0.0, 0.3, -1.5, 2.0, 1e-300, 1e300, math.pi])
_ARITH = st.recursive(
    st.one_of(st.sampled_from(["q", "v"]).map(P.Var), _NUMS.map(P.Num)),
    lambda c: st.one_of(
        c.map(P.Neg),
        st.builds(P.BinOp, st.sampled_from(["+", "-", "*", "/"]), c, c),
        st.builds(lambda f, a: P.Call(f, (a,)), st.sampled_from(["abs", "sqrt", "sin", "cos", "tan", "exp"]), c),
        st.builds(lambda f, a, b: P.Call(f, (a, b)), st.sampled_from(["min", "max", "atan2"]), c, c),
    ),
    max_leaves=5,
)
_CMP = st.builds(
    lambda ops, terms: P.Compare(tuple(terms[: len(ops) + 1]), tuple(ops)),
    st.lists(st.sampled_from(["<", "<=", ">", ">=", "==", "!="]), min_size=1, max_size=2),
    st.lists(_ARITH, min_size=3, max_size=3),
)
_BOOL = st.recursive(
    _CMP,
    lambda c: st.one_of(c.map(P.PNot), st.builds(P.PAnd, c, c), st.builds(P.POr, c, c)),
    max_leaves=3,
)
_STATE = st.floats(allow_nan=False, allow_infinity=False, width=64) | st.sampled_from([0.0, -0.0, 0.3, -0.3, 1.0])


@settings(max_examples=400, deadline=None)
@given(st.lists(_BOOL, min_size=1, max_size=3), st.lists(st.tuples(_STATE, _STATE), min_size=1, max_size=4))
def test_scalar_atoms_are_the_numpy_atom_code(preds, states) -> None:
    """The wrapper's one-sample atom code (plain Python floats) gives numpy's truths, division by
    zero, square roots of negatives, overflow and signed zeros included."""
    atoms = scalar_atoms(preds, _COLS)
    compiled = [compile_predicate(p, _COLS) for p in preds]
    x = np.array(states, dtype=float)
    with np.errstate(all="ignore"):
        want = sum(np.asarray(f(x), dtype=np.int64) << i for i, f in enumerate(compiled))
        got = [atoms([float(a), float(b)]) for a, b in states]
    assert got == list(np.broadcast_to(want, (len(states),)))


# ------------------------------------------------------------ several inputs: the unicycle
UNICYCLE = """plant unicycle
init x in [-1.2, -0.8], y in [-0.2, 0.2], theta in [-pi/4, pi/4]
horizon 1
prop goal = (x - 1) * (x - 1) + y * y < 0.25
prop rock = x * x + (y - 0.7) * (y - 0.7) < 0.16
formula {}
"""
UNICYCLE_SMALL = {"rbf": (3, 3, 2), "sigma_frac": 0.8}  # wide exploration: both inputs saturate now and then


@pytest.mark.parametrize("formula", ["F G goal", "F G goal & 10 * G !rock"])  # one marked row per run; several
@pytest.mark.parametrize("variant", range(len(VARIANTS)))
def test_two_inputs_uncompiled_kernel_is_the_numpy_trial(formula: str, variant: int) -> None:
    """A plant with two inputs (an actor row per place and input, each saturated to its own box):
    the fused kernel as plain Python is the numpy trial to the bit."""
    rs = compile_spec(parse_spec(UNICYCLE.format(formula)))
    same_trials(rs, SacpnSettings(kernel="numpy", **UNICYCLE_SMALL, **VARIANTS[variant]), fk.identity, trials=3)


def test_two_inputs_compiled_kernel_is_the_numpy_trial() -> None:
    pytest.importorskip("numba")
    rs = compile_spec(parse_spec(UNICYCLE.format("F G goal & 10 * G !rock")))
    a = Sacpn(rs, SacpnSettings(kernel="numpy", **UNICYCLE_SMALL), runs=2, seed=3)
    assert a.xi.shape == (2, a.n_places, 2, a.n_features)  # (runs, places, inputs, features)
    same_trials(rs, SacpnSettings(kernel="numpy", **UNICYCLE_SMALL), fk.jit, trials=3)
    b = Sacpn(rs, SacpnSettings(kernel="auto", **UNICYCLE_SMALL), runs=2, seed=3)
    assert (b.kernel, b.kernel_reason) == ("numba", None)
