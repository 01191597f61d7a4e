"""Kernels compiled through the disk cache (mitlc.learn.jitcache): the same code, the same bits,
compiled once per machine; anything the cache cannot hold compiles in memory as before."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numerics import same

from mitlc.learn import jitcache
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.petri.compile import compile_spec
from mitlc.spec.parse import load_spec

pytest.importorskip("numba")

ROOT = Path(__file__).resolve().parent.parent

SCALE = 2.5


def _helper(a: np.ndarray, i: int) -> float:
    return a[i] * SCALE


def _factory(offset: float, n: int):
    def inner(a, i):
        return _helper(a, i) + offset + math.pi

    def outer(a):
        s = 0.0
        for i in range(n):
            s += inner(a, i)
        return np.sqrt(s)

    return outer


def test_module_source_flattens_closures_globals_and_numbers():
    source, name = jitcache.module_source(_factory(0.25, 3), "test")
    assert name == "outer"
    assert "offset = 0.25" in source and "n = 3" in source and "SCALE = 2.5" in source
    for fn in ("def helper(a, i):", "def inner(a, i):", "def outer(a):"):
        assert fn in source
    assert source.count("= _jit(") == 3
    ns: dict = {}
    exec(compile(source.replace("_jit = numba.njit(", "_jit = (lambda f: f) or numba.njit("), "<t>", "exec"), ns)
    a = np.array([1.0, 2.0, 4.0])
    assert ns["outer"](a) == _factory(0.25, 3)(a)


def test_two_closures_of_one_factory_get_two_names():
    a, b = _factory(0.25, 3), _factory(0.5, 3)

    def both(x):
        return a(x) + b(x)

    source, _ = jitcache.module_source(both, "test")
    assert "offset = 0.25" in source and "offset_2 = 0.5" in source
    assert "def outer(a):" in source and "def outer_2(a):" in source


def test_what_cannot_be_written_is_refused():
    table = {"k": 1}

    def reads_a_dict(x):
        return table["k"] + x

    def has_default(x, y=1):
        return x + y

    for fn in (reads_a_dict, has_default, len):
        with pytest.raises(jitcache.Unwritable):
            jitcache.module_source(fn, "test")


def test_load_compiles_equal_results(tmp_path, monkeypatch):
    monkeypatch.setenv("MITLC_CACHE_DIR", str(tmp_path))
    fn = jitcache.load(_factory(0.25, 3))
    assert fn is not None
    a = np.array([1.0, 2.0, 4.0])
    assert fn(a) == _factory(0.25, 3)(a)
    files = list((tmp_path / "kernels").glob("kernel_*.py"))
    assert len(files) == 1 and not list((tmp_path / "kernels").glob(".kernel-*"))  # no temporary left


def test_no_cache_where_it_is_off_unwritable_or_damaged(tmp_path, monkeypatch):
    monkeypatch.setenv("MITLC_CACHE_DIR", "")
    assert jitcache.cache_dir() is None and jitcache.load(_factory(1.0, 2)) is None
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("MITLC_CACHE_DIR", str(blocked))
    assert jitcache.load(_factory(1.0, 2)) is None
    monkeypatch.setenv("MITLC_CACHE_DIR", str(tmp_path / "c"))
    source, _ = jitcache.module_source(_factory(3.0, 2), jitcache._versions())
    import hashlib

    digest = hashlib.sha256(source.encode()).hexdigest()[:24]
    (tmp_path / "c" / "kernels").mkdir(parents=True)
    (tmp_path / "c" / "kernels" / f"kernel_{digest}.py").write_text(source + "x = 1\n")  # not what we wrote
    assert jitcache.load(_factory(3.0, 2)) is None


TRAIN = """
import json, sys
import numpy as np
from mitlc.learn.sacpn import Sacpn, SacpnSettings
from mitlc.petri.compile import compile_spec
from mitlc.spec.parse import load_spec
rs = compile_spec(load_spec(sys.argv[1]))
a = Sacpn(rs, SacpnSettings(kernel="numba", rbf=(4, 3), trial_s=0.9), runs=2, seed=1)
a.train(2)
hits = sum(a._kernel_fn.stats.cache_hits.values())
print(json.dumps({"kernel": a.kernel, "hits": hits, "theta": a.theta.ravel().tolist()}))
"""


def test_a_second_process_loads_the_kernel_and_gets_the_same_bits(tmp_path):
    spec = str(ROOT / "specs" / "pendulum" / "p2_avoid.mitl")

    def train(cache: str) -> dict:
        env = {**os.environ, "MITLC_CACHE_DIR": cache}
        out = subprocess.run([sys.executable, "-c", TRAIN, spec], env=env, capture_output=True, text=True, check=True)
        return json.loads(out.stdout)

    first, second = train(str(tmp_path)), train(str(tmp_path))
    assert first["kernel"] == second["kernel"] == "numba"
    assert (first["hits"], second["hits"]) == (0, 1)  # compiled, then loaded from the cache
    assert first["theta"] == second["theta"]
    ref = Sacpn(compile_spec(load_spec(spec)), SacpnSettings(kernel="numpy", rbf=(4, 3), trial_s=0.9), runs=2, seed=1)
    ref.train(2)
    assert same(ref.theta.ravel(), np.array(second["theta"]))  # the numpy trial's (to the bit where LIBM)
