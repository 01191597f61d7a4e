"""Files mitlc reads are data (#29): a trace, a checkpoint or an option value is read within stated
limits, and a damaged one is one line naming the file and the field (or the option), exit 2, in
bounded time and memory: never a traceback, a hang, or gigabytes taken.

Each test is a reproducer of the audit (issue 29), with the message the command prints now.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import struct
import subprocess
import sys
import time
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.lib import format as npf

from mitlc import limits
from mitlc.cli import main
from mitlc.errors import InputError
from mitlc.monitor import trace as trace_mod
from tests.conftest import P2_SHORT

S = "pendulum/p2_avoid"
DT = 0.03
N = 101  # samples of the trace: t, q, qdot at dt 0.03


def run(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="mitlc")


def error_line(result) -> str:
    """The command failed with exit 2 and one error line (no traceback, no numpy warning): that line."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output and "Warning" not in result.output, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    lines = result.output.strip().splitlines()
    assert all(line.startswith("  ") for line in lines[1:]), result.output  # a hint or a source line at most
    return lines[0]


def timed(fn, *args, limit_s: float = 20.0, limit_mb: float = 64.0):
    """``fn(*args)``, which must take under ``limit_s`` and allocate (numpy and Python) under ``limit_mb``."""
    tracemalloc.start()
    start = time.perf_counter()
    try:
        out = fn(*args)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    elapsed = time.perf_counter() - start
    assert elapsed < limit_s, f"{elapsed:.1f} s"
    assert peak < limit_mb * 2**20, f"{peak / 2**20:.0f} MiB at the peak"
    return out


# ---------------------------------------------------------------- crafting .npz files


def npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


def npy_header(shape: tuple, descr: str = "<f8") -> bytes:
    """A ``.npy`` header (magic and all) declaring ``shape`` of ``descr``, without the data."""
    buf = io.BytesIO()
    npf.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
    return buf.getvalue()


def write_zip(path: Path, members: dict[str, bytes], bomb: dict[str, bytes] | None = None) -> Path:
    """An archive of ``members`` (``name.npy``: bytes), and for each ``bomb`` member its bytes followed
    by 100 MiB of zeros, deflated (to about 100 KB)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            z.writestr(f"{name}.npy", data)
        for name, head in (bomb or {}).items():
            with z.open(f"{name}.npy", "w", force_zip64=True) as fh:
                fh.write(head)
                block = bytes(1 << 20)
                for _ in range(100):
                    fh.write(block)
    return path


def central_entry(data: bytes, member: str) -> int:
    """Where the central directory's entry of ``member`` starts in the archive's bytes."""
    at = data.index(b"PK\x01\x02")  # the first entry
    while True:
        name_len = struct.unpack("<H", data[at + 28 : at + 30])[0]
        if data[at + 46 : at + 46 + name_len] == member.encode():
            return at
        at = data.index(b"PK\x01\x02", at + 4)


def damage(data: bytes, at: int, xor: int = 0x01) -> bytes:
    out = bytearray(data)
    out[at] ^= xor
    return bytes(out)


@pytest.fixture
def trace_npz(tmp_path: Path) -> Path:
    """A real trace as mitlc writes it (write_trace: what simulate --trace writes): t, q, qdot."""
    t = np.arange(N) * DT
    path = tmp_path / "trace.npz"
    trace_mod.write_trace(path, t, {"q": np.pi - 0.01 * np.arange(N), "qdot": np.zeros(N)})
    return path


# ---------------------------------------------------------------- traces: .npz


def test_a_real_npz_trace_reads(trace_npz):
    r = run("check", S, str(trace_npz))
    assert r.exit_code == 1, r.output  # violated: it never settles
    assert r.output.startswith(f"{trace_npz}: VIOLATED")


@pytest.mark.parametrize(
    "where, xor, message",
    [
        # the zip method of 't.npy' (central directory, offset 10): was NotImplementedError
        (("t.npy", 10), 0x01, "cannot read trace: array 't' is damaged (zip method 1, not stored or deflated)"),
        (("t.npy", 8), 0x01, "cannot read trace: array 't' is damaged (encrypted)"),  # the flag bits: was RuntimeError
        (("q.npy", "data"), 0x01, "cannot read trace: array 'q' is damaged (Bad CRC-32 for file 'q.npy')"),
        (("t.npy", "magic"), 0x01, "cannot read trace: array 't' is damaged (Bad CRC-32 for file 't.npy')"),
    ],
)
def test_a_flipped_byte_in_a_trace_is_one_line(trace_npz, tmp_path, where, xor, message):
    data = trace_npz.read_bytes()
    member, field = where
    if field == "data":
        at = data.index(b"\x93NUMPY", data.index(member.encode())) + 200  # inside the member's data
    elif field == "magic":
        at = data.index(b"\x93NUMPY", data.index(member.encode()))
    else:
        at = central_entry(data, member) + field
    bad = tmp_path / "bad.npz"
    bad.write_bytes(damage(data, at, xor))
    first = error_line(run("check", S, str(bad)))
    assert first.startswith(f"{bad}: error: {message}"), first


def test_a_truncated_trace_is_one_line(trace_npz, tmp_path):
    bad = tmp_path / "cut.npz"
    bad.write_bytes(trace_npz.read_bytes()[:700])
    first = error_line(run("check", S, str(bad)))
    assert first == f"{bad}: error: cannot read trace: not a .npz archive (File is not a zip file)"


def test_a_header_claiming_a_huge_shape_is_refused_before_reading(tmp_path):
    """Was _ArrayMemoryError: numpy allocated the shape the header claimed."""
    bad = write_zip(tmp_path / "huge.npz", {n: npy_header((10**12,)) + bytes(64) for n in ("t", "q", "qdot")})
    first = error_line(timed(run, "check", S, str(bad)))
    assert first == (
        f"{bad}: error: the trace has 1,000,000,000,000 samples, more than the 1,000,001 supported "
        "(1,000,000 time steps)"
    )


def test_twenty_million_samples_are_refused_by_the_sample_limit(tmp_path):
    """Was 33 s and 4.5 GB: the 1,000,000-step limit did not apply to traces. The header says how many
    samples there are: refused before any data is read (the members here hold no data at all)."""
    bad = write_zip(tmp_path / "big.npz", {n: npy_header((20_000_000,)) for n in ("t", "q", "qdot")})
    first = error_line(timed(run, "check", S, str(bad), limit_s=10))
    assert first == (
        f"{bad}: error: the trace has 20,000,000 samples, more than the 1,000,001 supported (1,000,000 time steps)"
    )


def test_the_sample_limit_is_the_limits_module(tmp_path, monkeypatch):
    monkeypatch.setattr(limits, "MAX_STEPS", 99)
    t = np.arange(N) * DT
    path = tmp_path / "t.npz"
    np.savez(path, t=t, q=np.zeros(N), qdot=np.zeros(N))
    first = error_line(run("check", S, str(path)))
    assert first == f"{path}: error: the trace has 101 samples, more than the 100 supported (99 time steps)"
    np.savez(path, t=t[:100], q=np.zeros(100), qdot=np.zeros(100))
    assert run("check", S, str(path)).exit_code in (0, 1)  # 100 samples: read and judged


def test_a_zip_bomb_in_a_trace_is_refused_before_unpacking(tmp_path):
    """Was 73 s and 5.9 GB (5.8 MB of zip holding 6 GB of zeros). Here 'q' declares 101 samples but
    its zip entry unpacks to 100 MiB more: refused from the entry's size, nothing unpacked."""
    t = np.arange(N) * DT
    bomb = write_zip(tmp_path / "bomb.npz", {"t": npy(t), "qdot": npy(np.zeros(N))}, {"q": npy(np.zeros(N))})
    assert bomb.stat().st_size < 1 << 20
    first = error_line(timed(run, "check", S, str(bomb), limit_mb=16))
    size = len(npy(np.zeros(N))) + (100 << 20)
    assert first == (
        f"{bomb}: error: cannot read trace: array 'q' unpacks to {size:,} bytes, its header declares 808 bytes of data"
    )


def test_arrays_a_trace_does_not_need_are_not_read(tmp_path):
    """An archive's other arrays (simulate's 'u', anything) are not unpacked, however large."""
    t = np.arange(N) * DT
    path = write_zip(
        tmp_path / "extra.npz",
        {"t": npy(t), "q": npy(np.pi + 0 * t), "qdot": npy(0 * t), "u": npy_header((10**12,))},
        {"log": npy_header((10**9,), "<f8")},
    )
    r = timed(run, "check", S, str(path), "--json", limit_mb=16)
    assert r.exit_code == 1 and json.loads(r.output)["samples"] == N


@pytest.mark.parametrize(
    "arrays, message",
    [
        ({"t": npy(np.zeros(3, complex))}, "array 't' does not hold real numbers (complex128)"),
        ({"t": npy(np.array(["a", "b"]))}, "array 't' does not hold real numbers (<U1)"),
        ({"t": npy_header((3,), "|O")}, "cannot read trace: array 't' holds Python objects (object), not numbers"),
        ({"t": b"\x93NUMPY\x01\x00\x10\x00{'descr': 1}  \n"}, "cannot read trace: array 't' is damaged ("),
        ({"t": npy(np.zeros((3, 2)))}, "array 't' has shape (3, 2), expected (N+1,)"),
    ],
)
def test_npz_arrays_of_the_wrong_kind_are_one_line(tmp_path, arrays, message):
    path = write_zip(tmp_path / "k.npz", {**arrays, "q": npy(np.zeros(3)), "qdot": npy(np.zeros(3))})
    first = error_line(run("check", S, str(path)))
    assert first.startswith(f"{path}: error: {message}"), first


def test_a_single_npy_is_not_a_trace(tmp_path):
    path = tmp_path / "a.npz"
    path.write_bytes(npy(np.zeros(3)))
    assert error_line(run("check", S, str(path))) == (
        f"{path}: error: cannot read trace: a single .npy array, not a .npz archive"
    )


# ---------------------------------------------------------------- traces: FIFOs, devices, CSV limits


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
@pytest.mark.parametrize("name", ["fifo.csv", "fifo.npz"])
def test_a_fifo_trace_is_refused_not_waited_on(tmp_path, name):
    """Was a hang: the read of a FIFO nobody writes blocks forever (specs refused FIFOs, traces did not)."""
    fifo = tmp_path / name
    os.mkfifo(fifo)
    p = subprocess.run(
        [sys.executable, "-m", "mitlc", "check", S, str(fifo)], capture_output=True, text=True, timeout=60
    )
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip() == f"{fifo}: error: cannot read trace: not a regular file"


@pytest.mark.parametrize(
    "times, message",
    [
        ("-1e308,1e308", "the trace spans t = -1e+308 to 1e+308 s, longer than the longest supported, 1e+09 s"),
        ("-1e308,0,1e308", "the trace spans t = -1e+308 to 1e+308 s, longer than the longest supported, 1e+09 s"),
        ("0,1e300,2e300", "the trace spans t = 0 to 2e+300 s, longer than the longest supported, 1e+09 s"),
    ],
)
@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_times_of_1e308_are_one_line_not_warnings(tmp_path, times, message, suffix):
    """Was 10 lines of numpy RuntimeWarnings (overflow in subtract) before the error."""
    t = np.array([float(x) for x in times.split(",")])
    path = tmp_path / f"t{suffix}"
    trace_mod.write_trace(path, t, {"q": 0 * t, "qdot": 0 * t})
    assert error_line(run("check", S, str(path))) == f"{path}: error: {message}"


def test_a_trace_in_epoch_seconds_reads(tmp_path):
    """The span is limited, not the times: a trace stamped in Unix time (1.7e9 s) is read."""
    path = tmp_path / "epoch.csv"
    path.write_text("t,q,qdot\n" + "".join(f"{1.7e9 + k * DT!r},0,0\n" for k in range(50)))
    r = run("check", S, str(path), "--json")
    assert r.exit_code == 0 and json.loads(r.output)["dt"] == pytest.approx(DT, rel=1e-3)


def wide_csv(path: Path, columns: int, rows: int = 5, duplicate: bool = False) -> Path:
    names = ["t", "q", "qdot", *(f"c{i}" for i in range(columns - 3))]
    if duplicate:
        names[-1] = "c0"
    zeros = ",0" * (columns - 1)
    path.write_text(",".join(names) + "\n" + "".join(f"{k * DT:.2f}{zeros}\n" for k in range(rows)))
    return path


def test_a_csv_of_100k_columns_is_refused_at_once(tmp_path):
    """Was 114 s (a quadratic duplicate-column check). 100,000 columns are more than the columns limit."""
    path = wide_csv(tmp_path / "wide.csv", 100_000)
    first = error_line(timed(run, "check", S, str(path), limit_s=3, limit_mb=128))
    assert first == f"{path}:1: error: the header has 100,000 columns, more than the 10,000 supported"


@pytest.mark.parametrize("duplicate", [False, True])
def test_the_header_check_is_linear(tmp_path, monkeypatch, duplicate):
    """With the columns limit raised, 100,000 columns and 5 rows read in well under the 114 s they took."""
    monkeypatch.setattr(trace_mod, "MAX_COLUMNS", 200_000)
    path = wide_csv(tmp_path / "wide.csv", 100_000, duplicate=duplicate)
    start = time.perf_counter()
    if duplicate:
        with pytest.raises(InputError) as info:
            trace_mod.read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
        assert info.value.headline() == f"{path}:1: error: duplicate column 'c0'"
    else:
        tr, dt = trace_mod.read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
        assert len(tr.t) == 5 and dt == pytest.approx(DT)
    assert time.perf_counter() - start < 3


@pytest.mark.parametrize("reader", ["auto", "numpy"])
@pytest.mark.parametrize("blank", [False, True])
def test_the_sample_limit_applies_to_csv_rows(tmp_path, monkeypatch, reader, blank):
    """A CSV past the limit is refused at the first row past it (the rest is not read), by both readers,
    on the fast path (plain numbers) and row by row (a blank line sends a chunk there)."""
    monkeypatch.setattr(trace_mod, "MAX_STEPS", 99)
    if reader == "numpy":
        monkeypatch.setenv(trace_mod.READER_ENV, "numpy")
    rows = [f"{k * DT!r},0,0\n" for k in range(150)]
    if blank:
        rows.insert(10, "\n")
    path = tmp_path / "long.csv"
    path.write_text("t,q,qdot\n" + "".join(rows))
    first = error_line(run("check", S, str(path)))
    line = 102 + blank  # the header on line 1, sample 101 (the 101st step) on line 102
    assert (
        first == f"{path}:{line}: error: the trace has more than 100 samples (rows), the most supported (99 time steps)"
    )
    path.write_text("t,q,qdot\n" + "".join(rows[: 100 + blank]))
    assert run("check", S, str(path)).exit_code in (0, 1)  # 100 samples: read and judged


def test_a_missing_column_of_a_wide_csv_lists_a_few(tmp_path):
    path = wide_csv(tmp_path / "w.csv", 50)
    path.write_text(path.read_text().replace("t,q,", "t,x,", 1))
    r = run("check", S, str(path))
    assert error_line(r) == f"{path}:1: error: missing column 'q'"
    hint = "  hint: columns: t, x, qdot, " + ", ".join(f"c{i}" for i in range(17)) + ", ... (50 in all)"
    assert r.output.splitlines()[1] == hint


# ---------------------------------------------------------------- checkpoints


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A real SACPN checkpoint: 2 runs x 2 trials of the 1-s problem 2."""
    d = tmp_path_factory.mktemp("ckpt")
    spec = d / "p2_short.mitl"
    spec.write_text(P2_SHORT)
    r = run("train", "--spec", str(spec), "--runs", "2", "--trials", "2", "-q", "--no-plots", "--out", str(d / "p"))
    assert r.exit_code == 0, r.output
    return d / "p" / "params.npz"


def policy(tmp_path: Path, data: bytes, name: str = "p") -> Path:
    folder = tmp_path / name
    folder.mkdir()
    (folder / "params.npz").write_bytes(data)
    return folder


def arrays_of(ckpt: Path) -> tuple[dict[str, np.ndarray], dict]:
    d = dict(np.load(ckpt))
    return d, json.loads(str(d["meta"]))


def with_meta(ckpt: Path, meta: dict | None = None, text: str | None = None, **arrays: np.ndarray) -> bytes:
    d, _ = arrays_of(ckpt)
    d.update(arrays)
    d["meta"] = np.array(text if text is not None else json.dumps(meta))
    buf = io.BytesIO()
    np.savez(buf, **d)
    return buf.getvalue()


def both_commands(folder: Path) -> str:
    """The error line of simulate and of train --resume on ``folder`` (the same one), and load_policy's."""
    ckpt = folder / "params.npz"
    before = sorted(p.name for p in folder.iterdir())
    first = timed(lambda: error_line(run("simulate", "--policy", str(folder))), limit_mb=128)
    again = timed(lambda: error_line(run("train", "--resume", str(folder), "--trials", "3", "-q")), limit_mb=128)
    assert first == again, (first, again)
    assert first.startswith(f"{ckpt}: error: "), first
    from mitlc import load_policy

    with pytest.raises(InputError) as info:
        load_policy(folder)
    assert info.value.headline() == first
    assert sorted(p.name for p in folder.iterdir()) == before  # nothing written
    return first[len(f"{ckpt}: error: ") :]


def test_a_real_checkpoint_loads(trained):
    assert run("simulate", "--policy", str(trained.parent)).exit_code == 0


def mutated(meta: dict, path: str, value) -> dict:
    """``meta`` with the field at ``path`` (``settings.gamma``, ``rng_states.0.state.state``) set to ``value``
    (``...``: removed)."""
    meta = json.loads(json.dumps(meta))
    *head, last = path.split(".")
    node = meta
    for key in head:
        node = node[int(key)] if isinstance(node, list) else node[key]
    key = int(last) if isinstance(node, list) else last
    if value is ...:
        del node[key]
    else:
        node[key] = value
    return meta


@pytest.mark.parametrize(
    "field, value, message",
    [
        # the audit's: OverflowError, ValueError, TypeError, TypeError
        (
            "rng_states.0.state.state",
            2**200,
            "rng_states[0].state.state is an integer of 61 digits, not an integer from 0 to 2^128 - 1",
        ),
        ("settings.rbf", "abc", "settings.rbf is 'abc', not a list of counts"),
        ("settings.gamma", "x", "settings.gamma is 'x', not a number"),
        ("kind", "hyrl", "modes is missing"),
        # and their kin
        ("settings.gamma", 2, "settings.gamma must be in [0, 1], got 2"),
        ("settings.rbf_width", 1e308, "settings.rbf_width must be a number in [0.02, 1000], got 1e+308"),
        ("settings.rbf", [10, 10**6], "settings.rbf[1] is 1000000, not an integer from 1 to 100,000"),
        ("settings.mask", "sideways", "settings: unknown mask 'sideways' (current or next)"),
        (
            "settings.feature_bounds",
            [["qdot", -20]],
            "settings.feature_bounds[0] is a list of 2 items, not [name, lo, hi]",
        ),
        ("settings", 5, "settings is 5, not an object"),
        ("eval_rng_states.1.bit_generator", "MT19937", "eval_rng_states[1].bit_generator is 'MT19937', not 'PCG64'"),
        ("rng_states.1", ..., "rng_states has 1 generator state, not one per run (2)"),
        ("rng_states.0.uinteger", -1, "rng_states[0].uinteger is -1, not an integer from 0 to 4,294,967,295"),
        ("runs", "two", "runs is 'two', not an integer"),
        ("runs", 0, "runs is 0, not an integer of at least 1"),
        ("seed", True, "seed is True, not an integer"),
        ("trial", ..., "trial is missing"),
        ("kind", "ppo", "kind is 'ppo', not one of sacpn, hyrl"),
        ("spec_source", 7, "spec_source is 7, not a string"),
        ("spec_source", "\ud800", "spec_source is not UTF-8 text (it holds a lone surrogate)"),
        ("spec_path", "a\0b", "spec_path holds a NUL character"),
        ("places", "p_kappa", "places is 'p_kappa', not a list of names"),
        ("violations", "sometimes", "violations is 'sometimes', not one of off, permanent, counted"),
        ("diverged", [-1, 99], "diverged[1] is 99, not an integer from -1 to 2"),
        ("ramp_trials", -3, "ramp_trials is -3, not an integer from 0 to 1,000,000,000"),
        ("plant", "pendulum", "plant is 'pendulum', not a plant record"),
        # the checkpoint against itself: its grid and its state, its spec text
        ("settings.rbf", [10], "settings.rbf has 1 count, not one per state variable (q, qdot)"),
        (
            "settings.feature_bounds",
            [["zz", -1, 1]],
            "settings.feature_bounds[0][0] is 'zz', not a state variable (q, qdot)",
        ),
        ("spec_source", "", "spec_source, line 1: the spec has no 'formula' (nor any 'require')"),
        ("spec_source", "plant pendulum\nformula F kapa\n", "spec_source, line 2: undefined proposition 'kapa'"),
    ],
)
def test_a_damaged_meta_field_is_one_line_naming_it(trained, tmp_path, field, value, message):
    _, meta = arrays_of(trained)
    folder = policy(tmp_path, with_meta(trained, mutated(meta, field, value)))
    assert both_commands(folder) == f"damaged checkpoint: {message}"


def test_a_grid_that_does_not_fit_the_spec_is_one_line_without_state_names(trained, tmp_path):
    """A checkpoint from before state_names was recorded is checked against its spec's plant
    (the fuzz family found a one-count grid labelled with the spec's path, not the checkpoint)."""
    _, meta = arrays_of(trained)
    del meta["state_names"]
    meta["settings"]["rbf"] = [1]
    folder = policy(tmp_path, with_meta(trained, meta))
    assert both_commands(folder) == "damaged checkpoint: settings.rbf has 1 count, not one per state variable (q, qdot)"


def test_meta_nested_100k_deep_is_one_line(trained, tmp_path):
    """Was RecursionError."""
    folder = policy(tmp_path, with_meta(trained, text="[" * 100_000))
    assert both_commands(folder) == "damaged checkpoint: its 'meta' record is not JSON (nested too deeply)"


@pytest.mark.parametrize(
    "text, message",
    [
        ("{", "its 'meta' record is not JSON (Expecting property name enclosed in double quotes: line 1 column 2 "),
        ("[1]", "its 'meta' record is not an object"),
        ('{"runs": ' + "9" * 5000 + "}", "its 'meta' record is not JSON (Exceeds the limit (4300 digits) for "),
    ],
)
def test_meta_that_is_not_a_json_object_is_one_line(trained, tmp_path, text, message):
    folder = policy(tmp_path, with_meta(trained, text=text))
    assert both_commands(folder).startswith(f"damaged checkpoint: {message}")


def test_a_spec_source_past_the_spec_limit_is_refused(trained, tmp_path):
    """The 1 MiB spec limit holds for a checkpoint's spec text (a 50 MB one took 32 s and 675 MB)."""
    _, meta = arrays_of(trained)
    big = mutated(meta, "spec_source", meta["spec_source"] + "#" + "x" * (1 << 20) + "\n")
    folder = policy(tmp_path, with_meta(trained, big))
    size = len(big["spec_source"].encode())
    assert (
        both_commands(folder)
        == f"damaged checkpoint: spec_source is {size:,} bytes long, more than the 1,048,576 it may be"
    )


def test_a_meta_record_past_its_limit_is_refused_unread(trained, tmp_path):
    """A 50 MB meta record (its spec text, say) is refused from its header: nothing of it is read."""
    d, _ = arrays_of(trained)
    members = {k: npy(v) for k, v in d.items() if k != "meta"}
    members["meta"] = npy_header((), "<U50000000")
    folder = tmp_path / "p"
    folder.mkdir()
    write_zip(folder / "params.npz", members)
    assert both_commands(folder) == (
        "damaged checkpoint: its 'meta' record is 50,000,000 characters, more than the 16,777,216 supported"
    )


@pytest.mark.parametrize(
    "case, message",
    [
        ("nan", "array 'xi' holds a value that is not a finite number (a checkpoint keeps each run's last finite "),
        ("complex", "array 'theta' holds complex128, not real numbers"),
        ("features", "array 'theta' has shape (2, P, 99), not (2, P, 100) (from 'xi')"),
        ("trials", "array 'returns' has shape (2, 5), not (runs, trial) = (2, 2)"),
        ("runs", "array 'xi' has shape (3, P, 100), not (runs = 2, rows, features)"),
    ],
)
def test_damaged_arrays_are_one_line(trained, tmp_path, case, message):
    d, meta = arrays_of(trained)
    shape = d["xi"].shape
    arrays = {
        "nan": {"xi": np.full(shape, np.nan)},
        "complex": {"theta": np.zeros(shape, complex)},
        "features": {"theta": np.zeros(shape[:2] + (99,))},
        "trials": {"returns": np.zeros((2, 5))},
        "runs": {"xi": np.zeros((3,) + shape[1:])},
    }[case]
    folder = policy(tmp_path, with_meta(trained, meta, **arrays))
    assert both_commands(folder).startswith("damaged checkpoint: " + message.replace("P", str(shape[1])))


def test_a_flipped_byte_in_a_checkpoint_is_one_line(trained, tmp_path):
    """The audit's flipped zip method (NotImplementedError), here in 'meta', and a flipped data byte of 'xi'."""
    data = trained.read_bytes()
    folder = policy(tmp_path, damage(data, central_entry(data, "meta.npy") + 10), "method")
    assert (
        both_commands(folder)
        == "cannot read checkpoint: array 'meta' is damaged (zip method 1, not stored or deflated)"
    )
    at = data.index(b"\x93NUMPY", data.index(b"xi.npy")) + 300  # inside xi's data
    folder = policy(tmp_path, damage(data, at), "crc")
    assert both_commands(folder) == "cannot read checkpoint: array 'xi' is damaged (Bad CRC-32 for file 'xi.npy')"


def test_checkpoint_headers_and_bombs_are_refused_before_reading(trained, tmp_path):
    """Was _ArrayMemoryError (a header claiming 10^12 rows) and 73 s, 5.9 GB (a zip bomb as 'xi')."""
    d, meta = arrays_of(trained)
    members = {k: npy(v) for k, v in d.items()}
    huge = (2, 10**6, 10**4)  # 160 GB of float64, theta as large: shapes that agree, sizes past the limit
    folder = tmp_path / "huge"
    folder.mkdir()
    write_zip(folder / "params.npz", {**members, "xi": npy_header(huge), "theta": npy_header(huge)})
    assert both_commands(folder) == (
        "cannot read checkpoint: array 'xi' of shape (2, 1000000, 10000) (float64) takes 160,000,000,000 bytes, "
        "more than the 1,073,741,824 supported"
    )
    folder = tmp_path / "bomb"
    folder.mkdir()
    xi = members.pop("xi")
    write_zip(folder / "params.npz", members, {"xi": xi})
    assert (folder / "params.npz").stat().st_size < 1 << 20
    assert both_commands(folder) == (
        f"cannot read checkpoint: array 'xi' unpacks to {len(xi) + (100 << 20):,} bytes, its header declares "
        f"{d['xi'].nbytes:,} bytes of data"
    )


def test_a_checkpoint_that_is_not_an_archive_is_one_line(trained, tmp_path):
    folder = policy(tmp_path, trained.read_bytes()[:3000], "cut")
    assert both_commands(folder) == "cannot read checkpoint: not a .npz archive (File is not a zip file)"
    folder = policy(tmp_path, npy(np.arange(3)), "npy")
    assert both_commands(folder) == "cannot read checkpoint: a single .npy array, not a .npz archive"
    d, _ = arrays_of(trained)
    del d["meta"]
    buf = io.BytesIO()
    np.savez(buf, **d)
    folder = policy(tmp_path, buf.getvalue(), "nometa")
    assert both_commands(folder) == "not a mitlc checkpoint: no 'meta' record"


def test_a_metrics_json_nested_100k_deep_does_not_stop_a_resume(trained, tmp_path):
    """train --resume reads the folder's metrics.json for the time trained so far; one that does not
    parse (here 100k nested '[': RecursionError) is no record of it, not a traceback."""
    folder = tmp_path / "p"
    shutil.copytree(trained.parent, folder)
    (folder / "metrics.json").write_text("[" * 100_000)
    r = run("train", "--resume", str(folder), "--trials", "3", "-q", "--no-plots")
    assert r.exit_code == 0 and r.output.startswith("2 runs x 3 trials in "), r.output


@pytest.fixture(scope="module")
def hyrl_ckpt(tmp_path_factory) -> Path:
    """The golden HyRL checkpoint (overshoot, 2 runs x 30 trials)."""
    d = tmp_path_factory.mktemp("hyrl") / "h"
    d.mkdir()
    shutil.copy(Path(__file__).parent / "fixtures/golden/train-hyrl-overshoot.params.npz", d / "params.npz")
    return d / "params.npz"


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("settings.gamma", "x", "settings.gamma is 'x', not a number"),
        ("settings.rbf", [10, 10], "settings.rbf is a list of 2 items, not a list of 3 counts"),
        ("settings.noise_tau", 1e308, "settings.noise_tau must be a number in [0, 1e+09], got 1e+308"),
        ("wall_s", -1, "wall_s is -1, not a time of at least 0"),
        ("modes", ..., "modes is missing"),
        ("kind", "sacpn", "places is missing"),
    ],
)
def test_a_damaged_hyrl_checkpoint_is_one_line(hyrl_ckpt, tmp_path, field, value, message):
    assert run("simulate", "--policy", str(hyrl_ckpt.parent), "--rollouts", "2").exit_code == 0
    _, meta = arrays_of(hyrl_ckpt)
    folder = policy(tmp_path, with_meta(hyrl_ckpt, mutated(meta, field, value)))
    assert both_commands(folder) == f"damaged checkpoint: {message}"


# ---------------------------------------------------------------- option values


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ("--set", "rbf_width=1e308"),
            "--set: error: rbf_width must be a number in [0.02, 1000], got 1e+308",
        ),  # OverflowError
        (
            ("--set", "rbf_width=1e-320"),
            "--set: error: rbf_width must be a number in [0.02, 1000], got 1e-320",
        ),  # ZeroDivisionError
        (("--sigma", "1e308"), "--sigma: error: sigma must be a number in [0, 1e+12], got 1e+308"),  # RuntimeWarning
        (("--set", "sigma=1e308"), "--set: error: sigma must be a number in [0, 1e+12], got 1e+308"),
        (("--set", "sigma_frac=1e308"), "--set: error: sigma_frac must be a number in [0, 1000], got 1e+308"),
        (("--set", "dt=1e308"), "--set: error: dt must be a number in [1e-09, 1e+09], got 1e+308"),  # 16 warning lines
        (("--set", "trial_s=1e-300"), "--set: error: trial_s must be a number in [1e-09, 1e+09], got 1e-300"),
        (
            ("--set", "feature_bounds=qdot:-1e308:1e308"),
            "--set: error: feature_bounds of 'qdot' must lie in [-1e+12, 1e+12] with lo < hi, at least 1e-09 apart, "
            "got [-1e+308, 1e+308]",
        ),
        (
            ("--set", "feature_bounds=qdot:0:1e-300"),
            "--set: error: feature_bounds of 'qdot' must lie in [-1e+12, 1e+12] with lo < hi, at least 1e-09 apart, "
            "got [0, 1e-300]",
        ),
    ],
)
def test_sacpn_option_values_past_their_range_are_one_line(tmp_path, args, message):
    spec = tmp_path / "s.mitl"
    spec.write_text(P2_SHORT)
    r = run("train", "--spec", str(spec), "--runs", "1", "--trials", "1", "-q", "--out", str(tmp_path / "o"), *args)
    assert error_line(r) == message
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (("--set", "rbf_width=1e308"), "--set: error: rbf_width must be a number in [0.02, 1000], got 1e+308"),
        (("--sigma", "1e308"), "--sigma: error: sigma must be a number in [0, 1e+12], got 1e+308"),
        (("--set", "sigma_min=1e308"), "--set: error: sigma_min must be a number in [0, 1e+12], got 1e+308"),
        (("--set", "noise_tau=1e308"), "--set: error: noise_tau must be a number in [0, 1e+09], got 1e+308"),
        (("--set", "qdot_grid=1e-300"), "--set: error: qdot_grid must be a number in [1e-09, 1e+12], got 1e-300"),
        (("--set", "dt=1e308"), "--set: error: dt must be a number in [1e-09, 1e+09], got 1e+308"),
    ],
)
def test_hyrl_option_values_past_their_range_are_one_line(tmp_path, args, message):
    r = run(
        "train",
        "--spec",
        "mass_damper/rise_time",
        "--runs",
        "1",
        "--trials",
        "1",
        "-q",
        "--out",
        str(tmp_path / "o"),
        *args,
    )
    assert error_line(r) == message


@pytest.mark.parametrize(
    "grid, message",
    [
        ("rbf_width=1,1e308", "rbf_width=1e+308: rbf_width must be a number in [0.02, 1000], got 1e+308"),
        ("sigma=1e308", "sigma=1e+308: sigma must be a number in [0, 1e+12], got 1e+308"),
        ("dt=1e308", "dt=1e+308: dt must be a number in [1e-09, 1e+09], got 1e+308"),
    ],
)
def test_sweep_grid_values_take_the_same_checks(tmp_path, grid, message):
    spec = tmp_path / "s.mitl"
    spec.write_text(P2_SHORT)
    r = run(
        "sweep", str(spec), "--grid", grid, "--seeds", "1", "--runs", "1", "--trials", "1", "--out", str(tmp_path / "o")
    )
    assert error_line(r) == f"--grid: error: {message}"


def test_the_narrowest_and_widest_rbf_widths_train(tmp_path):
    """The range's ends are usable: features stay finite (no run diverges from them)."""
    spec = tmp_path / "s.mitl"
    spec.write_text(P2_SHORT)
    for width in ("0.02", "1000"):
        out = tmp_path / f"o{width}"
        r = run("train", "--spec", str(spec), "--runs", "2", "--trials", "2", "-q", "--no-plots", "--out", str(out),
                "--set", f"rbf_width={width}")  # fmt: skip
        assert r.exit_code == 0 and "Warning" not in r.output, r.output
        assert json.loads((out / "metrics.json").read_text())["diverged"] == []
