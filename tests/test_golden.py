"""The CLI's outputs on the shipped specs, compared with tests/fixtures/golden/.

Compile and automaton outputs must match to the character; seeded trainings to rounding
(``RTOL``), run with numpy held to its portable baseline code (``golden.PORTABLE``: an
AVX-512 machine's sin and exp round differently, and a training amplifies that).
Regenerate with ``python tests/golden.py`` only for an intended change.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from golden import CASES, GOLDEN, VOLATILE, run_case

RTOL = 1e-9


def _close(got: object, want: object, where: str) -> None:
    if isinstance(want, dict):
        assert isinstance(got, dict) and set(got) - VOLATILE == set(want) - VOLATILE, where
        for k in set(want) - VOLATILE:
            _close(got[k], want[k], f"{where}.{k}")
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), where
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            _close(g, w, f"{where}[{i}]")
    elif isinstance(want, float) and not isinstance(want, bool):
        assert isinstance(got, (int, float)), where
        assert math.isclose(got, want, rel_tol=RTOL, abs_tol=1e-12), f"{where}: {got} != {want}"
    else:
        assert got == want, f"{where}: {got!r} != {want!r}"


@pytest.mark.parametrize("name", list(CASES))
def test_golden(name: str) -> None:
    got = run_case(CASES[name])
    if "stdout" in got:
        assert got["stdout"] == (GOLDEN / f"{name}.out").read_text()
        return
    want = json.loads((GOLDEN / f"{name}.metrics.json").read_text())
    _close(got["metrics"], want, "metrics")
    params = got["params"]
    assert isinstance(params, dict)
    with np.load(GOLDEN / f"{name}.params.npz") as z:
        assert set(params) == set(z.files)
        for k in z.files:
            if z[k].dtype.kind == "U":  # a JSON record (the checkpoint's meta)
                _close(json.loads(str(params[k])), json.loads(str(z[k])), k)
            else:
                np.testing.assert_allclose(params[k], z[k], rtol=RTOL, atol=1e-12, err_msg=k)
