"""The Gymnasium wrapper's fast path (one sample on Python numbers: the net on nested lists, the
start's marking found once per atom code, the episode's verdict by the one-run offline monitor)
gives what the reference path gives (the runtime's arrays, the offline monitor), to the bit: the
same rewards, observations, terminations and infos, verdicts included, on random formulas and
random rollouts of Pendulum-v1."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from mitlc.errors import MitlError
from mitlc.gym import MitlRewardWrapper, pendulum_v1_state
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.spec import ast as A
from mitlc.spec.parse import parse_spec

try:
    from tests.strategies import formulas, grid_intervals
except ImportError:  # tests/ itself is on sys.path
    from strategies import formulas, grid_intervals  # type: ignore[no-redef]

SPEC = """plant pendulum
horizon 1.5
prop a = abs(q) < {t}
prop b = qdot > {w}
prop c = q > 0 and qdot < 1
formula {formula}
"""


def _bits(v: object) -> object:
    return np.float64(v).tobytes() if isinstance(v, float) else v


def _same_info(fast: dict, ref: dict) -> None:
    assert list(fast) == list(ref)
    for key in fast:
        a, b = fast[key], ref[key]
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b)
            assert a.dtype == b.dtype
        elif isinstance(a, dict):  # the verdict
            assert list(a) == list(b)
            assert {k: _bits(v) for k, v in a.items()} == {k: _bits(v) for k, v in b.items()}, (a, b)
        else:
            assert _bits(a) == _bits(b), (key, a, b)


def _rollout(env: MitlRewardWrapper, seed: int, steps: int) -> list:
    env.action_space.seed(seed)
    out = [env.reset(seed=seed)]
    for _ in range(steps):
        step = env.step(env.action_space.sample())
        out.append(step)
        if step[2] or step[3]:
            out.append(env.reset())
    return out


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    f=formulas(atoms=("a", "b", "c"), interval=grid_intervals(0.25, 6), max_leaves=5),
    t=st.sampled_from([0.3, 1.0, 2.5]),
    w=st.sampled_from([-1.0, 0.0, 0.5]),
    violations=st.sampled_from(["off", "permanent"]),
    verdict=st.sampled_from(["step", "end", "off"]),
    seed=st.integers(0, 2**16),
)
def test_fast_path_is_the_reference_path(
    f: A.Formula, t: float, w: float, violations: str, verdict: str, seed: int
) -> None:
    spec = parse_spec(SPEC.format(t=t, w=w, formula=f))
    try:
        rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))
    except MitlError:  # a formula the compiler refuses (a net too large): nothing to compare
        assume(False)

    def make() -> MitlRewardWrapper:
        return MitlRewardWrapper(
            gym.make("Pendulum-v1"), rs, pendulum_v1_state, verdict=verdict, truncate_at_horizon=True
        )

    try:
        fast, ref = make(), make()
    except ValueError:  # a net of no places (a constant formula): gymnasium has no MultiBinary(0)
        assume(False)
    ref._step1 = None  # noqa: SLF001 - the runtime's arrays, the start found by reset
    ref._judge = None  # noqa: SLF001 - the offline monitor's verdict
    event(f"one sample on Python numbers: {fast._step1 is not None}")  # noqa: SLF001
    a, b = _rollout(fast, seed, 70), _rollout(ref, seed, 70)
    verdicts = [s[-1]["verdict"] for s in a if "verdict" in s[-1] and "failing" in s[-1]["verdict"]]
    event(f"episodes judged: {min(len(verdicts), 2)}, violated: {min(sum(not v['satisfied'] for v in verdicts), 2)}")
    assert len(a) == len(b)
    for sa, sb in zip(a, b, strict=True):
        assert len(sa) == len(sb)
        obs_a, obs_b = sa[0], sb[0]
        assert list(obs_a) == list(obs_b)
        for key in obs_a:
            np.testing.assert_array_equal(obs_a[key], obs_b[key])
            assert obs_a[key].dtype == obs_b[key].dtype
        if len(sa) == 5:
            assert _bits(sa[1]) == _bits(sb[1]) and sa[2:4] == sb[2:4]
            assert type(sa[2]) is type(sb[2]) is bool and type(sa[3]) is type(sb[3]) is bool
        _same_info(sa[-1], sb[-1])
