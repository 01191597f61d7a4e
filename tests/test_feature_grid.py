"""SACPN's default RBF grid follows from the plant (mitlc.learn.features.default_rbf): the
10 x 10 of Table 4-4 for the two-variable plants, about 100 features for more variables."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli.main import main
from mitlc.learn.features import default_rbf
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.petri.compile import compile_spec
from mitlc.plants import PLANTS
from mitlc.plants import user as U
from mitlc.spec.parse import load_spec, parse_spec

ROOT = Path(__file__).resolve().parent.parent

CHAIN = '''\
"""A chain of integrators of {n} state variables: x1' = x2, ..., x{n}' = u - x{n}."""

import numpy as np

from mitlc.plants import Plant, StateVar


def chain(x, u, p):
    out = np.empty_like(x)
    out[:, :-1] = x[:, 1:]
    out[:, -1] = u - x[:, -1]
    return out


CHAIN = Plant(
    name="chain{n}",
    state=tuple(StateVar(f"x{{i}}", -2.0, 2.0) for i in range(1, {n} + 1)),
    defaults={{"u_max": 1.0, "dt": 0.1}},
    dynamics=chain,
)
'''


pytestmark = pytest.mark.usefixtures("forget_user_plants")  # tests/conftest.py


def _chain(tmp_path: Path, n: int) -> tuple[Path, Path]:
    plant = tmp_path / f"chain{n}.py"
    plant.write_text(CHAIN.format(n=n))
    spec = tmp_path / f"chain{n}.mitl"
    spec.write_text(f"plant chain{n}\ninit x1 in [-1, 1]\nhorizon 1\nprop near = abs(x1) < 0.2\nformula F G near\n")
    return plant, spec


def _train(plant: Path, spec: Path, out: Path, *args: str):
    return CliRunner().invoke(
        main,
        ["train", "--plant-file", str(plant), "--spec", str(spec), "--runs", "2", "--no-plots", "-q"]
        + ["--out", str(out), *args],
    )


@pytest.mark.parametrize(
    "n, counts",
    [
        (1, (10,)),
        (2, (10, 10)),  # Table 4-4
        (3, (5, 5, 4)),  # 4^3 = 64 <= 100 < 5^3; one more centre on x1 (80), on x2 (100), not on x3 (125)
        (4, (3, 3, 3, 3)),  # 3^4 = 81 <= 100 < 4^4; one more on x1 would be 108
        (5, (3, 3, 2, 2, 2)),  # 2^5 = 32 -> 48 -> 72, 108 is over
        (6, (3, 2, 2, 2, 2, 2)),  # 64 -> 96
        (7, (2,) * 7),  # 2^7 = 128: at least two centres each
    ],
)
def test_the_default_grid_by_hand(n, counts):
    assert default_rbf(n) == counts
    assert math.prod(counts) <= 100 or counts == (2,) * n


def test_the_pendulum_and_mass_damper_keep_the_10_by_10_grid_to_the_bit():
    assert SacpnSettings().rbf is None
    for name in ("pendulum", "mass-damper"):
        assert SacpnSettings().resolved(PLANTS[name]).rbf == (10, 10)
    rs = compile_spec(load_spec(ROOT / "specs/pendulum/p2_avoid.mitl"))
    auto = Sacpn(rs, SacpnSettings(trial_s=0.6), runs=2, seed=3)
    literal = Sacpn(rs, SacpnSettings(trial_s=0.6, rbf=(10, 10)), runs=2, seed=3)
    assert auto.settings == literal.settings and auto.settings.rbf == (10, 10) and auto.n_features == 100
    auto.train(3)
    literal.train(3)
    assert auto.returns.tobytes() == literal.returns.tobytes()
    assert auto.xi.tobytes() == literal.xi.tobytes() and auto.theta.tobytes() == literal.theta.tobytes()


def test_a_four_state_plant_trains_at_defaults_and_records_its_grid(tmp_path):
    plant, spec = _chain(tmp_path, 4)
    r = _train(plant, spec, tmp_path / "o", "--trials", "3")
    assert r.exit_code == 0, r.output
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert metrics["settings"]["rbf"] == [3, 3, 3, 3]
    assert np.asarray(metrics["returns"]).shape == (2, 3)
    with np.load(tmp_path / "o" / "params.npz") as z:
        assert z["xi"].shape[-1] == 81
    again = CliRunner().invoke(
        main,
        ["train", "--plant-file", str(plant), "--resume", str(tmp_path / "o"), "--trials", "5", "-q", "--no-plots"],
    )
    assert again.exit_code == 0, again.output
    assert json.loads((tmp_path / "o" / "metrics.json").read_text())["settings"]["rbf"] == [3, 3, 3, 3]


def test_a_three_state_plant_gets_5_5_4(tmp_path):
    plant, spec = _chain(tmp_path, 3)
    r = _train(plant, spec, tmp_path / "o", "--trials", "2")
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "o" / "metrics.json").read_text())["settings"]["rbf"] == [5, 5, 4]


@pytest.mark.parametrize(
    "value, counts", [("5x5x5x5", [5, 5, 5, 5]), ("auto", [3, 3, 3, 3]), ("2x1x4x3", [2, 1, 4, 3])]
)
def test_set_rbf_still_chooses_the_grid(tmp_path, value, counts):
    plant, spec = _chain(tmp_path, 4)
    r = _train(plant, spec, tmp_path / "o", "--trials", "2", "--set", f"rbf={value}")
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "o" / "metrics.json").read_text())["settings"]["rbf"] == counts


def test_a_grid_of_the_wrong_length_is_one_line_and_exit_2(tmp_path):
    plant, spec = _chain(tmp_path, 4)
    r = _train(plant, spec, tmp_path / "o", "--trials", "2", "--set", "rbf=5x5")
    assert r.exit_code == 2
    assert r.output.strip() == "--set: error: rbf has 2 entries, the plant has 4 state variables"
    assert len(r.output.strip().splitlines()) == 1 and "Traceback" not in r.output


def test_a_default_grid_too_large_says_to_set_rbf(tmp_path):
    plant, spec = _chain(tmp_path, 17)  # 2^17 = 131,072 features, over MAX_FEATURES
    r = _train(plant, spec, tmp_path / "o", "--trials", "1")
    assert r.exit_code == 2, r.output
    first, hint = r.output.strip().splitlines()
    assert first == (
        "mitlc train: error: rbf = " + "x".join(["2"] * 17) + " is 131,072 features, more than the 100,000 "
        "supported: the default grid for 17 state variables"
    )
    assert hint.strip() == "hint: set rbf with fewer centres (1 on some variables: --set rbf=2x2x1x...)"


def test_a_sweep_resolves_the_grid_so_its_task_keys_stay(tmp_path):
    from mitlc.sweep import plan_sweep

    plan = plan_sweep(load_spec(ROOT / "specs/pendulum/p2_avoid.mitl"), ["sigma=1,2"], [0], 1, 1)
    assert [t.payload["settings"]["rbf"] for t in plan.tasks] == [[10, 10], [10, 10]]
    plant, _ = _chain(tmp_path, 4)
    U.load_plants(str(plant))
    chain = parse_spec("plant chain4\ninit x1 in [-1, 1]\nhorizon 1\nprop near = abs(x1) < 0.2\nformula F G near\n")
    assert plan_sweep(chain, [], [0], 1, 1).tasks[0].payload["settings"]["rbf"] == [3, 3, 3, 3]


# ---------------------------------------------------------------- the grid's range from the spec

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from mitlc.learn.features import GRID_MARGIN, GRID_SAMPLES, spec_grid  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-4.5, 4.5),
    st.floats(0.05, 4.0),
    st.floats(-4.9, 4.9),
    st.booleans(),
)
def test_the_spec_grid_spans_thresholds_and_init_widened_by_the_margin(lo, width, start, absolute):
    """Against the thresholds written down: ``lo < qdot < lo + width`` (or ``abs(qdot - lo) < width``) on the
    mass-damper (qdot's box [-5, 5]) with ``qdot = start`` at the start; q's prop is two-variable, so q is left out."""
    hi = min(lo + width, 4.95)
    prop = f"abs(qdot - {lo!r}) < {width!r}" if absolute else f"{lo!r} < qdot < {hi!r}"
    marks = [lo - width, lo + width] if absolute else [lo, hi]
    marks = [m for m in marks if -5 < m < 5]
    spec = parse_spec(
        f"plant mass-damper\ninit q = 0, qdot = {start!r}\nprop p = {prop}\nprop r = q + qdot > 0\nformula F p & G r\n"
    )
    grid = spec_grid(spec)
    assert "q" not in grid
    if not marks:
        assert grid == {}
        return
    a, b = min(marks + [start]), max(marks + [start])
    pad = GRID_MARGIN * max(b - a, 1e-3 * 10)
    want = (max(-5.0, a - pad), min(5.0, b + pad))
    step = 10 / (GRID_SAMPLES - 1)
    assert grid["qdot"] == pytest.approx(want, abs=step * (1 + GRID_MARGIN))


def test_the_spec_grid_by_hand_and_where_it_stays_the_plants():
    speed = parse_spec(
        "plant mass-damper\ninit q in [-1, -0.8], qdot = 0\nprop far = abs(q - 0.9) < 0.1\n"
        "prop fast = abs(qdot) > 1\nformula F[0,3] G far & G !fast\n"
    )
    grid = spec_grid(speed)  # q: thresholds 0.8, 1.0 and init -1..-0.8 -> [-1, 1] padded, clipped to the box
    assert grid["q"] == pytest.approx((-1.0, 1.0)) and grid["qdot"] == pytest.approx((-2.0, 2.0), abs=3e-3)
    # the pendulum: q is an angle (periodic, left out); qdot's grid is Table 4-4's [-20, 20], not the box's 15 pi
    p3 = load_spec(ROOT / "specs/pendulum/p2_avoid.mitl")
    assert spec_grid(p3) == {}
    slow = parse_spec("plant pendulum\nprop up = abs(q) < 0.2\nprop fast = abs(qdot) > 30\nformula F up & G !fast\n")
    assert spec_grid(slow) == {"qdot": (-20.0, 20.0)}
    agent = Sacpn(compile_spec(speed), SacpnSettings(trial_s=0.3), runs=1, seed=0)
    assert agent.features.bounds[1] == pytest.approx((-2.0, 2.0), abs=3e-3)
    plant = Sacpn(compile_spec(speed), SacpnSettings(trial_s=0.3, feature_grid="plant"), runs=1, seed=0)
    assert plant.features.bounds == ((-1.0, 1.0), (-5.0, 5.0))
    given_ = Sacpn(
        compile_spec(speed), SacpnSettings(trial_s=0.3, feature_bounds=(("qdot", -3.0, 3.0),)), runs=1, seed=0
    )
    assert given_.features.bounds[1] == (-3.0, 3.0)


def test_a_checkpoint_without_feature_grid_was_trained_on_the_plants_grid():
    assert SacpnSettings.from_dict({"gamma": 0.97}).feature_grid == "plant"
    assert SacpnSettings.from_dict(SacpnSettings().to_dict()).feature_grid == "spec"


def test_the_discount_follows_the_trial_length():
    """``gamma = 1 - 3 / N``: Table 4-4's 0.97 at the pendulum's 100 steps, to the bit."""
    rs = compile_spec(load_spec(ROOT / "specs/pendulum/p2_avoid.mitl"))
    assert Sacpn(rs, SacpnSettings(), runs=1, seed=0).gamma == 0.97
    long = Sacpn(rs, SacpnSettings(trial_s=6.0), runs=1, seed=0)
    assert long.gamma == pytest.approx(1 - 3 / 200) and long.settings.gamma == long.gamma
    assert Sacpn(rs, SacpnSettings(trial_s=6.0, gamma=0.9), runs=1, seed=0).gamma == 0.9
    assert Sacpn(rs, SacpnSettings(trial_s=0.09), runs=1, seed=0).gamma == 0.5  # 3 steps: floored


def test_a_bad_plant_grid_is_refused():
    from mitlc.plants import StateVar

    with pytest.raises(ValueError, match="grid must be two finite numbers"):
        StateVar("v", -1.0, 1.0, grid=(2.0, 1.0))
    with pytest.raises(ValueError, match="grid must be two finite numbers"):
        StateVar("v", -1.0, 1.0, grid=(0.0, math.inf))


def test_an_unknown_feature_grid_is_one_line_and_exit_2(tmp_path):
    r = CliRunner().invoke(
        main, ["train", "--plant", "pendulum", "--set", "feature_grid=box", "-q", "--out", str(tmp_path / "o")]
    )
    assert r.exit_code == 2 and r.output == "--set: error: unknown feature_grid 'box' (spec or plant)\n"
    assert not (tmp_path / "o").exists()
