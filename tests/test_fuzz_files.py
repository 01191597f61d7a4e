"""Fuzzing the files mitlc reads (#29): a real ``trace.npz`` and a real ``params.npz``, damaged at
random bytes, with random damage inside a member (the zip rebuilt around it, so that its CRC holds
and the ``.npy`` header itself is what gets read), and checkpoints whose ``meta`` fields are replaced
by random JSON values.

Whatever the damage, ``mitlc check``, ``mitlc simulate`` and ``mitlc train --resume`` end with a valid
result or with one error line naming the file (exit 2), in bounded time: never a traceback, a numpy
warning, a hang or a crash inside mitlc.
"""

from __future__ import annotations

import io
import json
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.cli import main
from mitlc.monitor.trace import write_trace
from tests.conftest import P2_SHORT

S = "pendulum/p2_avoid"
FUZZ = settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
SECONDS = 30.0
"""The most one command may take on a damaged file (they take well under a second)."""


def run(*args: str):
    start = time.perf_counter()
    result = CliRunner().invoke(main, list(args), prog_name="mitlc")
    assert time.perf_counter() - start < SECONDS, args
    return result


def assert_clean(result, path: Path, ok_codes=(0,), named: bool = True) -> None:
    """A result, or one error line (exit 2) naming ``path`` (``named``; else naming a file or an option,
    never ``<spec>``): never a traceback or a warning."""
    exc = result.exception
    assert exc is None or isinstance(exc, SystemExit), f"{type(exc).__name__}: {exc}\n{result.output}"
    assert "Traceback" not in result.output and "Warning" not in result.output, result.output
    if result.exit_code == 2:
        lines = result.output.strip().splitlines()
        assert lines and (lines[0].startswith(f"{path}:") or not named), result.output
        assert not lines[0].startswith("<spec>"), result.output
        assert ": error: " in lines[0] or ": syntax error: " in lines[0], result.output
        assert all(line.startswith("  ") for line in lines[1:]), result.output
    else:
        assert result.exit_code in ok_codes, result.output


@pytest.fixture(scope="module")
def trace_npz(tmp_path_factory) -> Path:
    """A real trace as ``mitlc simulate --trace`` writes it: t, q, qdot and the inputs u."""
    path = tmp_path_factory.mktemp("trace") / "trace.npz"
    t = np.arange(101) * 0.03
    write_trace(path, t, {"q": np.pi - 0.02 * np.arange(101), "qdot": np.zeros(101)}, {"u": np.zeros(100)})
    return path


@pytest.fixture(scope="module")
def params_npz(tmp_path_factory) -> Path:
    """A real checkpoint from a tiny training (2 runs x 2 trials of the 1-s problem 2)."""
    d = tmp_path_factory.mktemp("train")
    spec = d / "p2_short.mitl"
    spec.write_text(P2_SHORT)
    r = CliRunner().invoke(
        main, ["train", "--spec", str(spec), "--runs", "2", "--trials", "2", "-q", "--no-plots", "--out", str(d / "p")]
    )
    assert r.exit_code == 0, r.output
    return d / "p" / "params.npz"


def _structure(data: bytes) -> list[int]:
    """The offsets of the zip's record fields (local headers, central directory, its end: the methods,
    flags, sizes, offsets) and of each ``.npy`` header: where one byte changes how the rest is read."""
    spots: list[int] = []
    for sig, size in ((b"PK\x03\x04", 30), (b"PK\x01\x02", 46), (b"PK\x05\x06", 22), (b"\x93NUMPY", 64)):
        at = data.find(sig)
        while at >= 0:
            spots.extend(range(at, min(at + size, len(data))))
            at = data.find(sig, at + 1)
    return spots


@st.composite
def byte_damage(draw: st.DrawFn, data: bytes) -> bytes:
    """``data`` with a few bytes flipped, overwritten, cut or inserted: anywhere, or (half the time) in
    the zip's and the ``.npy`` headers' fields."""
    out = bytearray(data)
    spots = _structure(data)
    for _ in range(draw(st.integers(1, 4))):
        anywhere = st.integers(0, len(out) - 1)
        i = draw(st.one_of(anywhere, st.sampled_from([j for j in spots if j < len(out)] or [0])))
        kind = draw(st.sampled_from(["flip", "set", "cut", "insert"]))
        if kind == "flip":
            out[i] ^= 1 << draw(st.integers(0, 7))
        elif kind == "set":
            out[i] = draw(st.sampled_from([0x00, 0xFF, 0x7F, 0x80, ord("9"), ord("{"), ord("(")]))
        elif kind == "cut":
            del out[i : i + draw(st.integers(1, 64))]
        else:
            out[i:i] = draw(st.binary(min_size=1, max_size=16))
        if not out:
            break
    return bytes(out)


@st.composite
def member_damage(draw: st.DrawFn, data: bytes) -> bytes:
    """The archive ``data`` rebuilt with one member's bytes damaged (mostly in its ``.npy`` header, where
    the dtype and shape are), its CRC that of the damaged bytes: the damage reaches numpy's format."""
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        members = {i.filename: z.read(i) for i in z.infolist()}
    name = draw(st.sampled_from(sorted(members)))
    body = bytearray(members[name])
    head = body.index(b"\n") + 1 if b"\n" in body else len(body)
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, max(0, min(len(body), head + 16) - 1)))
        piece = draw(
            st.sampled_from([b"9", b"99999999999", b"-1", b"(", b")", b",", b"'", b"<c16", b"|O", b"True", b" ", b""])
        )
        body[i : i + draw(st.integers(0, 4))] = piece
    members[name] = bytes(body)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for n, b in members.items():
            z.writestr(n, b)
    return buf.getvalue()


@FUZZ
@given(st.data())
def test_damaged_trace_npz_is_read_or_refused_in_one_line(tmp_path_factory, trace_npz, data):
    good = trace_npz.read_bytes()
    damaged = data.draw(st.one_of(byte_damage(good), member_damage(good)))
    path = tmp_path_factory.mktemp("fuzz") / "trace.npz"
    path.write_bytes(damaged)
    assert_clean(run("check", S, str(path)), path, ok_codes=(0, 1))


def _policy(tmp_path_factory, data: bytes) -> Path:
    folder = tmp_path_factory.mktemp("policy")
    (folder / "params.npz").write_bytes(data)
    return folder


@FUZZ
@given(st.data())
def test_damaged_params_npz_is_loaded_or_refused_in_one_line(tmp_path_factory, params_npz, data):
    good = params_npz.read_bytes()
    damaged = data.draw(st.one_of(byte_damage(good), member_damage(good)))
    folder = _policy(tmp_path_factory, damaged)
    ckpt = folder / "params.npz"
    assert_clean(run("simulate", "--policy", str(folder), "--rollouts", "2"), ckpt)
    assert_clean(run("train", "--resume", str(folder), "--trials", "3", "-q", "--no-plots"), ckpt)


JSON_VALUES = st.recursive(
    st.one_of(
        st.none(),
        st.booleans(),
        st.integers(-(2**70), 2**70),
        st.sampled_from([0, -1, 1, 2, 3, 10**6, 2**63, 2**128, 2**200, -(2**64)]),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from([1e308, -1e308, 5e-324, 1e-320, 0.5, 1.5, -0.0]),
        st.text(max_size=8),
        st.sampled_from(["", "abc", "x", "hyrl", "sacpn", "PCG64", "net", "permanent", "\ud800", "a\0b"]),
    ),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=8,
)


def _paths(node, prefix=()):
    """Every path into the JSON ``node`` (keys and list indices), the root's children first."""
    if isinstance(node, dict):
        items = list(node.items())
    elif isinstance(node, list):
        items = list(enumerate(node))
    else:
        return
    for key, child in items:
        yield (*prefix, key)
        yield from _paths(child, (*prefix, key))


@st.composite
def meta_mutation(draw: st.DrawFn, meta: dict) -> dict:
    """``meta`` with one to three fields (anywhere in it) replaced by a random JSON value or removed,
    or a top-level field added."""
    meta = json.loads(json.dumps(meta))
    for _ in range(draw(st.integers(1, 3))):
        paths = list(_paths(meta))
        kind = draw(st.sampled_from(["replace", "replace", "remove", "add", "kind"]))
        if kind == "add":
            meta[draw(st.text(max_size=8))] = draw(JSON_VALUES)
            continue
        if kind == "kind":
            meta["kind"] = draw(st.sampled_from(["hyrl", "sacpn", "HYRL", 3, None]))
            continue
        path = draw(st.sampled_from(paths))
        node = meta
        for key in path[:-1]:
            node = node[key]
        if kind == "remove":
            del node[path[-1]]
        else:
            node[path[-1]] = draw(JSON_VALUES)
    return meta


@FUZZ
@given(st.data())
def test_checkpoint_meta_mutations_are_loaded_or_refused_in_one_line(tmp_path_factory, params_npz, data):
    with np.load(params_npz) as d:
        arrays = {k: d[k] for k in d.files}
    meta = data.draw(meta_mutation(json.loads(str(arrays["meta"]))))
    arrays["meta"] = np.array(json.dumps(meta))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    folder = _policy(tmp_path_factory, buf.getvalue())
    ckpt = folder / "params.npz"
    sim = run("simulate", "--policy", str(folder), "--rollouts", "2")
    assert_clean(sim, ckpt)
    assert_clean(run("train", "--resume", str(folder), "--trials", "3", "-q", "--no-plots"), ckpt)
