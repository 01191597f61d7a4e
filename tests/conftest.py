from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SPECS = ROOT / "specs"


@pytest.fixture
def spec_dir() -> Path:
    return SPECS


# Problem 2 with a 1 s trial: training a few runs for a few trials takes milliseconds.
P2_SHORT = """\
plant pendulum(u_max = 10)
init q in [2.4, pi], qdot = 0
horizon 1
prop kappa = abs(q) < 0.3
prop psi   = 0.3 < q < pi/2 + 0.5
formula F G kappa & 10 * G !psi
"""


@pytest.fixture
def short_spec(tmp_path: Path) -> Path:
    """A spec file of problem 2 with a 1 s trial (fast to train)."""
    p = tmp_path / "p2_short.mitl"
    p.write_text(P2_SHORT)
    return p
