import atexit
import os
import shutil
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SPECS = ROOT / "specs"

# Compiled kernels (mitlc.learn.jitcache) go to a folder of this test session, shared with
# the processes the tests start (sweep workers, CLI runs), never to the user's ~/.cache.
if "MITLC_CACHE_DIR" not in os.environ:
    _cache = tempfile.mkdtemp(prefix="mitlc-test-cache-")
    os.environ["MITLC_CACHE_DIR"] = _cache
    atexit.register(shutil.rmtree, _cache, True)


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


@pytest.fixture
def forget_user_plants():
    """Put the plant registry back as it was: a test that loads plant files (``--plant-file``, a
    run folder's copy, ``load_plants``) registers plants that later tests must not see. Used by
    the modules that load them: ``pytestmark = pytest.mark.usefixtures("forget_user_plants")``."""
    from mitlc.plants import PLANTS
    from mitlc.plants import user as U

    before, sources, origins = dict(PLANTS), list(U.SOURCES), dict(U._ORIGINS)
    yield
    PLANTS.clear()
    PLANTS.update(before)
    U.SOURCES[:] = sources
    U._ORIGINS.clear()
    U._ORIGINS.update(origins)
