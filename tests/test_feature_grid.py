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
