"""The classical-criteria checker on hand-made step responses, with exact numbers."""

from __future__ import annotations

import numpy as np
import pytest

from mitlc.errors import InputError
from mitlc.hybrid.criteria import DEFAULT_SETTLING_BAND, check, measure
from mitlc.spec.model import Requirement
from mitlc.spec.parse import parse_spec


def approx(x):
    return pytest.approx(x, abs=1e-12)


def test_ramp_without_overshoot():
    q = np.linspace(-1.0, 0.0, 11)  # 1 m in 1 s, dt = 0.1
    m = measure(q, 0.1)
    assert m.overshoot[0] == 0.0
    assert m.rise_time[0] == approx(0.8)  # 10% at 0.1 s, 90% at 0.9 s
    # 2% band = 0.02: |e| = 0.1 at 0.9 s, 0 at 1.0 s -> crosses 0.02 at 0.98 s
    assert m.settling_time[0] == approx(0.98)
    assert m.steady_state_error[0] == 0.0
    assert m.band == DEFAULT_SETTLING_BAND


def test_step_with_overshoot_interpolates_crossings():
    q = np.array([-1.0, -0.8, -0.4, 0.0, 0.1, 0.02, 0.0, 0.0])
    m = measure(q, 0.1)
    assert m.overshoot[0] == approx(0.1)
    # 10%: between 0 (p=0) and 0.1 s (p=0.2) -> 0.05 s; 90%: between 0.2 s (0.6) and 0.3 s (1.0) -> 0.275 s
    assert m.rise_time[0] == approx(0.225)
    # last exit from the 2% band: 0.1 at 0.4 s, 0.02 at 0.5 s (on the border, inside)
    assert m.settling_time[0] == approx(0.5)
    m5 = measure(q, 0.1, band=0.05)  # 0.05: between 0.4 s (0.1) and 0.5 s (0.02): 0.4 + 0.1 * 0.05/0.08
    assert m5.settling_time[0] == approx(0.4625)


def test_falling_step_to_a_nonzero_setpoint():
    # from 2 down to 1: an undershoot to 0.8 is an overshoot of 0.2 of the step
    q = np.array([2.0, 1.5, 1.0, 0.8, 1.0])
    m = measure(q, 0.5, setpoint=1.0)
    assert m.overshoot[0] == approx(0.2)
    # progress 0, 0.5, 1: 10% at 0.1 s, 90% at 0.5 + 0.5 * 0.8 = 0.9 s
    assert m.rise_time[0] == approx(0.8)
    assert m.steady_state_error[0] == 0.0


def test_never_rising_or_ending_outside_the_band_is_infinite():
    q = np.array([-1.0, -0.9, -0.5, -0.3])
    m = measure(q, 0.1)
    assert m.rise_time[0] == np.inf
    assert m.settling_time[0] == np.inf
    assert m.steady_state_error[0] == approx(0.3)


def test_zero_step_has_no_overshoot_and_no_rise_time():
    m = measure(np.zeros(5), 0.1)
    assert (m.overshoot[0], m.rise_time[0], m.settling_time[0]) == (0.0, 0.0, 0.0)


def test_vectorised_over_runs_equals_one_by_one():
    rows = np.array(
        [
            np.linspace(-1.0, 0.0, 11),
            [-1.0, -0.8, -0.4, 0.0, 0.1, 0.02, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.5, 0.45, 0.3, 0.1, 0.0, -0.01, 0.0, 0.0, 0.0, 0.0, 0.005],
        ]
    )
    both = measure(rows, 0.1)
    for i, row in enumerate(rows):
        one = measure(row, 0.1)
        for name in ("overshoot", "rise_time", "settling_time", "steady_state_error"):
            assert getattr(both, name)[i] == getattr(one, name)[0]


def test_check_against_requirements_and_spec():
    q = np.array(
        [
            np.linspace(-1.0, 0.0, 11),  # t_r 0.8, no overshoot
            [-1.0, -0.8, -0.4, 0.0, 0.1, 0.02, 0.0, 0.0, 0.0, 0.0, 0.0],  # t_r 0.225, M_p 0.1
        ]
    )
    spec = parse_spec(
        "plant mass-damper\ninit q in [-1, -0.5], qdot = 0\nsetpoint 0\n"
        "require overshoot <= 0\nrequire rise_time in [0.6, 0.8]\n"
        "require settling_time <= 1 band 0.05\nrequire steady_state_error <= 0.02\n"
    )
    v = check(spec, q, 0.1)
    np.testing.assert_array_equal(v.passed["overshoot"], [True, False])
    np.testing.assert_array_equal(v.passed["rise_time"], [True, False])
    np.testing.assert_array_equal(v.passed["settling_time"], [True, True])
    np.testing.assert_array_equal(v.passed["steady_state_error"], [True, True])
    np.testing.assert_array_equal(v.all, [True, False])
    assert v.rates() == {
        "overshoot": 0.5,
        "rise_time": 0.5,
        "settling_time": 1.0,
        "steady_state_error": 1.0,
        "all": 0.5,
    }
    # settling band 0.05 of the step: the ramp leaves it at 0.95 s
    assert v.measured["settling_time"][0] == approx(0.95)
    loose = check([Requirement("overshoot", 0.0, 0.1)], q, 0.1, setpoint=0.0)
    np.testing.assert_array_equal(loose.passed["overshoot"], [True, True])  # 0.1 <= 0.1 (with tolerance)


@pytest.mark.parametrize(
    "q, dt, message",
    [
        (np.array([1.0]), 0.1, "at least 2 samples"),
        (np.array([0.0, np.nan]), 0.1, "NaN"),
        (np.array([0.0, 1.0]), 0.0, "sample time"),
    ],
)
def test_bad_input(q, dt, message):
    with pytest.raises(InputError, match=message):
        measure(q, dt)
