"""Kernels compiled through the disk cache (mitlc.learn.jitcache): the same code, the same bits,
compiled once per machine; anything the cache cannot hold compiles in memory as before."""

from __future__ import annotations

import hashlib
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


def run_modules(modules: list[tuple[str, str]]) -> dict[str, dict]:
    """The generated modules run as plain Python (``_jit`` the identity), each registered where the
    modules after it import it from; their namespaces by module name."""
    import types

    spaces: dict[str, dict] = {}
    try:
        for name, source in modules:
            mod = types.ModuleType(name)
            sys.modules[name] = mod
            code = source.replace("_jit = numba.njit(", "_jit = (lambda f: f) or numba.njit(")
            exec(compile(code, f"<{name}>", "exec"), mod.__dict__)
            spaces[name] = mod.__dict__
    finally:
        for name, _ in modules:
            sys.modules.pop(name, None)
    return spaces


def test_one_module_per_function_named_by_its_text():
    modules, top, name = jitcache.module_sources(_factory(0.25, 3), "test")
    assert name == "outer" and top == modules[-1][0]
    texts = dict(modules)
    helper, inner, outer = (next(m for m, t in modules if f"def {f}(a" in t) for f in ("helper", "inner", "outer"))
    assert [m for m, _ in modules] == [helper, inner, outer]  # a module after the modules it imports
    assert "SCALE = 2.5" in texts[helper]
    assert "offset = 0.25" in texts[inner] and f"from {helper} import helper" in texts[inner]
    assert "n = 3" in texts[outer] and f"from {inner} import inner" in texts[outer]
    assert all(t.count("= _jit(") == 1 for t in texts.values())
    for module, text in modules:  # the name is the text's hash, and the text names its imports' modules
        assert module == jitcache.MODULE_PREFIX + hashlib.sha256(text.encode()).hexdigest()[:24]
    a = np.array([1.0, 2.0, 4.0])
    assert run_modules(modules)[top]["outer"](a) == _factory(0.25, 3)(a)
    assert jitcache.module_sources(_factory(0.25, 3), "test") == (modules, top, name)  # the same text each time
    assert jitcache.module_sources(_factory(0.25, 3), "other versions")[1] != top


def test_two_closures_of_one_factory_share_the_function_they_both_call():
    a, b = _factory(0.25, 3), _factory(0.5, 3)

    def both(x):
        return a(x) + b(x)

    modules, top, _ = jitcache.module_sources(both, "test")
    texts = dict(modules)
    assert len(modules) == 6  # helper once; inner, outer twice each (their numbers differ); both
    assert sum("def helper(a, i):" in t for t in texts.values()) == 1
    assert sum("offset = 0.25" in t for t in texts.values()) == sum("offset = 0.5" in t for t in texts.values()) == 1
    assert "import outer as a" in texts[top] and "import outer as b" in texts[top]  # named as both reads them
    x = np.array([1.0, 2.0, 4.0])
    assert run_modules(modules)[top]["both"](x) == a(x) + b(x)


def test_what_cannot_be_written_is_refused():
    table = {"k": 1}

    def reads_a_dict(x):
        return table["k"] + x

    def has_default(x, y=1):
        return x + y

    def calls_itself(x):
        return calls_itself(x - 1) if x > 0 else 0

    for fn in (reads_a_dict, has_default, len, calls_itself):
        with pytest.raises(jitcache.Unwritable):
            jitcache.module_source(fn, "test")


def test_load_compiles_equal_results(tmp_path, monkeypatch):
    monkeypatch.setenv("MITLC_CACHE_DIR", str(tmp_path))
    fn = jitcache.load(_factory(0.25, 3))
    assert fn is not None
    a = np.array([1.0, 2.0, 4.0])
    assert fn(a) == _factory(0.25, 3)(a)
    files = list((tmp_path / "kernels").glob("kernel_*.py"))
    assert len(files) == 3 and not list((tmp_path / "kernels").glob(".kernel-*"))  # no temporary left
    # a kernel that differs in one number: a new module for the functions that read it, and for those
    # that call them; the helper is the one compiled already
    other = jitcache.load(_factory(0.5, 3))
    assert other is not None and other(a) == _factory(0.5, 3)(a)
    assert len(list((tmp_path / "kernels").glob("kernel_*.py"))) == 5
    helper = jitcache._LOADED[jitcache.module_sources(_factory(0.5, 3), jitcache._versions())[0][0][0]].helper
    assert len(helper.signatures) == 1


def test_no_cache_where_it_is_off_unwritable_or_damaged(tmp_path, monkeypatch):
    monkeypatch.setenv("MITLC_CACHE_DIR", "")
    assert jitcache.cache_dir() is None and jitcache.load(_factory(1.0, 2)) is None
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("MITLC_CACHE_DIR", str(blocked))
    assert jitcache.load(_factory(1.0, 2)) is None
    for which, offset in ((1, 3.0), (-1, 4.0)):  # a damaged module the kernel imports, or its own
        monkeypatch.setenv("MITLC_CACHE_DIR", str(tmp_path / f"c{offset}"))
        modules, _, _ = jitcache.module_sources(_factory(offset, 2), jitcache._versions())
        module, source = modules[which]
        digest = module.removeprefix(jitcache.MODULE_PREFIX)
        (tmp_path / f"c{offset}" / "kernels").mkdir(parents=True)
        (tmp_path / f"c{offset}" / "kernels" / f"kernel_{digest}.py").write_text(source + "x = 1\n")  # not ours
        assert jitcache.load(_factory(offset, 2)) is None


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
