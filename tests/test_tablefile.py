"""A net's reward tables kept on disk (mitlc.runtime.tablefile): read back as built, keyed by the net
and not by the spec's file name, and a damaged or foreign file is ignored and written again, never a
traceback (``mitlc check --net`` reads them)."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli.check import check
from mitlc.petri.compile import CompileOptions, compile_spec
from mitlc.runtime import NetRuntime
from mitlc.runtime import tablefile as TF
from mitlc.spec.parse import load_spec, parse_spec

ROOT = Path(__file__).resolve().parent.parent
SPEC = "pendulum/n1_reach_in_time"  # with violations recorded 576 markings, 3 atoms, 2 clocks: worth keeping


def _runtime(rs, cache: bool = True) -> NetRuntime:
    return NetRuntime(rs, dt=0.05, steps=100, tables_cache=cache)


def _same(a, b) -> bool:
    names = ("next_code", "reward", "charge", "marked", "counter_inc", "markings", "clock_ends")
    for name in names:
        x, y = getattr(a, name), getattr(b, name)
        if (x is None) != (y is None) or (x is not None and not np.array_equal(x, y)):
            return False
    return a.index == b.index


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("MITLC_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache" / "tables"


def _compiled(spec, violations: str | None = "permanent"):
    """The net ``mitlc check --net`` steps: violations recorded."""
    return compile_spec(spec, CompileOptions.from_spec(spec, violations=violations))


@pytest.fixture(scope="module")
def rs():
    return _compiled(load_spec(SPEC))


def test_tables_read_back_as_built(cache: Path, rs) -> None:
    built = _runtime(rs, cache=False).tables
    first = _runtime(rs).tables  # built and written
    files = list(cache.glob("*.npz"))
    assert [f.name for f in files] == [f"{TF.tables_key(rs)}.npz"]
    kept = _runtime(rs).tables  # read
    assert _same(first, built) and _same(kept, built) and kept is not first
    assert not kept.next_code.flags.writeable


def test_small_tables_are_built_not_kept(cache: Path) -> None:
    small = compile_spec(load_spec("pendulum/p3_avoid_speed_limit"))
    assert _runtime(small).tables is not None
    assert not cache.exists() or not list(cache.iterdir())


def test_the_key_is_the_net_not_the_file(tmp_path: Path, rs) -> None:
    text = (ROOT / "specs" / "pendulum" / "n1_reach_in_time.mitl").read_text()
    elsewhere = tmp_path / "copy.mitl"
    elsewhere.write_text(text)
    assert TF.tables_key(_compiled(load_spec(str(elsewhere)))) == TF.tables_key(rs)
    assert TF.tables_key(_compiled(load_spec(SPEC), violations=None)) != TF.tables_key(rs)
    # the propositions' thresholds are not in the tables (they are over atom codes); the formula is
    assert TF.tables_key(_compiled(parse_spec(text.replace("abs(q) < 0.3", "abs(q) < 0.25")))) == TF.tables_key(rs)
    assert TF.tables_key(_compiled(parse_spec(text.replace("F[0,2]", "F[0,2.5]")))) != TF.tables_key(rs)


def _damage(path: Path, how: str) -> None:
    if how == "truncated":
        path.write_bytes(path.read_bytes()[:1000])
    elif how == "garbage":
        path.write_bytes(b"not a zip file\n")
    elif how == "empty":
        path.write_bytes(b"")
    else:
        with np.load(path) as z:
            arrays = {name: z[name] for name in z.files}
        if how == "code out of range":
            arrays["next_code"] = arrays["next_code"] + arrays["next_code"].shape[1]
        elif how == "wrong shape":
            arrays["reward"] = arrays["reward"][:-1]
        elif how == "wrong dtype":
            arrays["next_code"] = arrays["next_code"].astype(np.int32)
        elif how == "another net":
            arrays["next_code"] = arrays["next_code"][:, :10]
        elif how == "objects":
            arrays["extra"] = np.array([{"a": 1}], dtype=object)
        elif how == "missing":
            del arrays["marked"]
        with path.open("wb") as fh:
            np.savez(fh, **arrays)


@pytest.mark.parametrize(
    "how",
    ["truncated", "garbage", "empty", "code out of range", "wrong shape", "wrong dtype", "another net", "objects"]
    + ["missing"],
)
def test_a_damaged_file_is_built_again(cache: Path, rs, how: str) -> None:
    built = _runtime(rs, cache=False).tables
    _runtime(rs)
    (path,) = cache.glob("*.npz")
    _damage(path, how)
    assert _same(_runtime(rs).tables, built)  # ignored and built
    assert _same(_runtime(rs).tables, built)  # written again: read
    with np.load(path, allow_pickle=False) as z:
        assert "extra" not in z.files and np.array_equal(z["next_code"], built.next_code)


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="file modes")
def test_a_file_others_may_write_is_not_read(cache: Path, rs) -> None:
    built = _runtime(rs, cache=False).tables
    _runtime(rs)
    (path,) = cache.glob("*.npz")
    _damage(path, "code out of range")
    cache.chmod(0o755)  # others may enter the folder, and write the file
    path.chmod(0o666)
    assert TF._load(path, rs, 576, 2) is None
    assert _same(_runtime(rs).tables, built)


def test_check_net_reads_the_kept_tables(cache: Path, tmp_path: Path) -> None:
    """``mitlc check --net`` says the same with tables built, read, or read from a damaged file."""
    rows = ["t,q,qdot"] + [f"{k * 0.05!r},{0.5 * math.cos(k / 20)!r},{-math.sin(k / 20) / 40!r}" for k in range(200)]
    trace = tmp_path / "trace.csv"
    trace.write_text("\n".join(rows) + "\n")
    outs = []
    for damage in (None, None, "garbage"):
        if damage is not None:
            (path,) = cache.glob("*.npz")
            _damage(path, damage)
        r = CliRunner().invoke(check, ["--net", "--json", SPEC, str(trace)])
        assert r.exit_code in (0, 1), r.output
        assert r.exception is None or isinstance(r.exception, SystemExit)
        outs.append(json.loads(r.output))
    assert outs[0] == outs[1] == outs[2]
    assert list(cache.glob("*.npz"))
