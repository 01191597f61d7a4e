"""The two CSV trace readers (issue #17, part 3): pyarrow's (the ``fast`` extra) and the chunked
numpy one, which stays the reference. On the same file they give the same arrays to the bit and
the same source lines, and every error is the numpy reader's one located line, whichever reader
was chosen (the pyarrow path hands every doubt to the numpy reader)."""

from __future__ import annotations

import struct
import sys

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.errors import InputError
from mitlc.monitor import trace as trace_mod
from mitlc.monitor.trace import READER_ENV, read_trace

HAVE_ARROW = trace_mod._pyarrow() is not None
needs_arrow = pytest.mark.skipif(not HAVE_ARROW, reason="pyarrow is not installed (the fast extra)")


@pytest.fixture(params=["numpy", "pyarrow"])
def reader(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """read_trace with one reader: numpy's (MITLC_CSV_READER=numpy) or pyarrow's where it reads."""
    if request.param == "numpy":
        monkeypatch.setenv(READER_ENV, "numpy")
    else:
        if not HAVE_ARROW:
            pytest.skip("pyarrow is not installed (the fast extra)")
        monkeypatch.delenv(READER_ENV, raising=False)
        monkeypatch.setattr(trace_mod, "ARROW_MIN_BYTES", 0)  # pyarrow reads small files too
    return request.param


def bits(values) -> list[bytes]:
    return [struct.pack("<d", float(v)) for v in values]


AWKWARD = [
    "0.1",
    "0.30000000000000004",  # 17 significant digits
    "2.7182818284590451",
    "-1.2345678901234567e-89",
    "6.0221407599999999e+23",
    "1E+5",
    "1e0000000000000000000005",
    "-0",
    "-0.0",
    "0.0",
    "+1",
    ".5",
    "5.",
    "-.5e-3",
    " 3 ",  # whitespace around a number (float() and pyarrow both strip spaces and tabs)
    "\t4",
    "4.9406564584124654e-324",  # the smallest subnormal
    "2.5e-324",  # rounds up to it
    "2.4703282292062328e-324",  # rounds up to it too (just above half)
    "2.4703282292062327e-324",  # rounds down to 0 (just below half)
    "2.2250738585072011e-308",  # the largest subnormal
    "2.2250738585072014e-308",  # the smallest normal
    "1e-400",  # underflows to 0
    "1.7976931348623157e308",
    "9007199254740993",  # 2**53 + 1: a tie, to even
    "1.00000000000000011102230246251565404236316680908203125",  # exactly half an ulp above 1: to even (1)
    "1.00000000000000011102230246251565404236316680908203126",  # just above: up
    "0.1000000000000000055511151231257827021181583404541015625",
    "123456789012345678901234567890",
]


def awkward_file(tmp_path, cells: list[str]):
    """A trace whose q column holds ``cells`` (t uniform, qdot repr of a random float)."""
    rng = np.random.default_rng(5)
    qdot = (rng.standard_normal(len(cells)) * 10.0 ** rng.integers(-300, 300, len(cells))).tolist()
    rows = [f"{k * 0.05!r},{c},{v!r}" for k, (c, v) in enumerate(zip(cells, qdot, strict=True))]
    path = tmp_path / "awkward.csv"
    path.write_text("t,q,qdot\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path, qdot


def test_awkward_floats_read_as_float_reads_them(tmp_path, reader: str) -> None:
    path, qdot = awkward_file(tmp_path, AWKWARD)
    tr, dt = read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
    assert bits(tr.columns["q"]) == bits(float(c) for c in AWKWARD)
    assert bits(tr.columns["qdot"]) == bits(qdot)
    assert bits(tr.t) == bits(k * 0.05 for k in range(len(AWKWARD)))
    assert dt == pytest.approx(0.05) and [tr.line(k) for k in (0, 1, len(AWKWARD) - 1)] == [2, 3, len(AWKWARD) + 1]
    assert struct.pack("<d", tr.columns["q"][AWKWARD.index("-0")]) == struct.pack("<d", -0.0)
    assert tr.columns["q"][AWKWARD.index("4.9406564584124654e-324")] == 5e-324
    assert tr.columns["q"][AWKWARD.index("9007199254740993")] == 2.0**53
    assert tr.columns["q"][AWKWARD.index("1.00000000000000011102230246251565404236316680908203126")] == 1 + 2**-52


@needs_arrow
def test_pyarrow_reads_them_itself_to_the_same_bits(tmp_path) -> None:
    """The pyarrow path takes this file (it returns a trace, not None) and agrees with numpy's reader."""
    path, _ = awkward_file(tmp_path, AWKWARD)
    fast = trace_mod._read_csv_arrow(str(path), ("q", "qdot"))
    ref = trace_mod._read_csv_numpy(str(path), ("q", "qdot"))
    assert fast is not None
    assert fast.t.tobytes() == ref.t.tobytes() and fast.t.dtype == np.float64
    assert {k: v.tobytes() for k, v in fast.columns.items()} == {k: v.tobytes() for k, v in ref.columns.items()}
    assert all(v.flags.c_contiguous and v.flags.writeable for v in [fast.t, *fast.columns.values()])
    assert [fast.line(k) for k in range(len(fast.t))] == [ref.line(k) for k in range(len(ref.t))]


@needs_arrow
def test_random_doubles_in_every_format(tmp_path) -> None:
    """20,000 random doubles over the whole exponent range, as repr, %.17e and %.25g write them."""
    rng = np.random.default_rng(11)
    x = rng.standard_normal(20_000) * 10.0 ** rng.integers(-320, 308, 20_000)
    raw = rng.integers(0, 2**63, 2_000, dtype=np.uint64).view(np.float64)  # any bit pattern, subnormals too
    x = np.concatenate([x, raw[np.isfinite(raw)]])
    formats = [repr, lambda v: f"{v:.17e}", lambda v: f"{v:.25g}"]
    cells = [formats[k % 3](v) for k, v in enumerate(x.tolist())]
    path, _ = awkward_file(tmp_path, cells)
    fast = trace_mod._read_csv_arrow(str(path), ("q", "qdot"))
    assert fast is not None
    assert fast.columns["q"].tobytes() == np.array([float(c) for c in cells]).tobytes() == x.tobytes()
    assert fast.columns["q"].tobytes() == trace_mod._read_csv_numpy(str(path), ("q", "qdot")).columns["q"].tobytes()


BAD = {
    "bad cell": ("t,q,qdot\n0,0,0\n0.05,zero,0\n", ":3: error: not a number: 'zero' (column q)"),
    "empty cell": ("t,q,qdot\n0,0,0\n0.05,,0\n", ":3: error: not a number: '' (column q)"),
    "nan": ("t,q,qdot\n0,0,0\n0.05,nan,0\n", ":3: error: not a finite number: 'nan' (column q)"),
    "inf": ("t,q,qdot\n0,0,0\n0.05,0,-inf\n", ":3: error: not a finite number: '-inf' (column qdot)"),
    "overflow": ("t,q,qdot\n0,0,0\n0.05,1e400,0\n", ":3: error: not a finite number: '1e400' (column q)"),
    "short row": ("t,q,qdot\n0,0,0\n0.05,0\n", ":3: error: row has 2 fields, the header has 3"),
    "long row": ("t,q,qdot\n0,0,0\n0.05,0,0,0\n", ":3: error: row has 4 fields, the header has 3"),
    "missing column": ("t,q\n0,0\n0.05,0\n", ":1: error: missing column 'qdot'"),
    "duplicate column": ("t,q,qdot,q\n0,0,0,0\n", ":1: error: duplicate column 'q'"),
    "empty file": ("", ": error: trace file is empty"),
    "blank file": ("\n  \n,,\n", ": error: trace file is empty"),
    "header only": ("t,q,qdot\n", ": error: a trace needs at least 2 samples to tell the time step, got 0"),
    "one sample": ("t,q,qdot\n0,0,0\n", ": error: a trace needs at least 2 samples to tell the time step, got 1"),
    "not utf-8": (b"t,q,qdot\n0,0,0\n0.05,\xff,0\n", ": error: cannot read trace: not UTF-8 text"),
    "bad cell before a bad byte": (
        b"t,q,qdot\n0,zero,0\n0.05,0,0\n0.1,\xff,0\n",
        ": error: cannot read trace: not UTF-8 text",
    ),
    "backwards": ("t,q,qdot\n0,0,0\n0.05,0,0\n0.04,0,0\n", ":4: error: time must increase: t = 0.04 after t = 0.05"),
    "uneven": ("t,q,qdot\n0,0,0\n0.05,0,0\n0.2,0,0\n", ":4: error: time step is not uniform: t goes from 0.05 to 0.2"),
    "late row after a blank line": ("t,q,qdot\n\n0,0,0\n0.05,x,0\n", ":4: error: not a number: 'x' (column q)"),
    "bad cell in an ignored column": ("t,q,qdot,z\n0,0,0,0\n0.05,0,0,oops,1\n", ":3: error: row has 5 fields"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_every_error_is_the_same_located_line(tmp_path, reader: str, name: str) -> None:
    text, expected = BAD[name]
    path = tmp_path / "bad.csv"
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
    with pytest.raises(InputError) as info:
        read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
    rendered = info.value.render()
    assert rendered.startswith(f"{path}{expected}"), rendered
    assert len(rendered.splitlines()) <= 2  # one line, and at most a hint


ODD_BUT_VALID = {
    "quoted number": ('t,q,qdot\n0,"1.5",0\n0.05,0,0\n', [1.5, 0.0], [2, 3]),
    "underscore": ("t,q,qdot\n0,1_0,0\n0.05,0,0\n", [10.0, 0.0], [2, 3]),
    "blank line": ("t,q,qdot\n0,1,0\n\n0.05,2,0\n", [1.0, 2.0], [2, 4]),
    "commas only": ("t,q,qdot\n0,1,0\n,,\n0.05,2,0\n", [1.0, 2.0], [2, 4]),
    "CR line ends": ("t,q,qdot\r0,1,0\r0.05,2,0\r", [1.0, 2.0], [2, 3]),
    "CRLF": ("t,q,qdot\r\n0,1,0\r\n0.05,2,0\r\n", [1.0, 2.0], [2, 3]),
    "BOM and blank lines first": ("\ufeff\n\nt , q,qdot\n0,1,0\n0.05,2,0", [1.0, 2.0], [4, 5]),
    "text in an ignored column": ("t,q,qdot,note\n0,1,0,start\n0.05,2,0,end\n", [1.0, 2.0], [2, 3]),
    "unicode space": ("t,q,qdot\n0,1\u00a0,0\n0.05,2,0\n", [1.0, 2.0], [2, 3]),
    "form feed": ("t,q,qdot\n0,1,0\x0c0.05,2,0\n", [1.0, 2.0], [2, 3]),
}


@pytest.mark.parametrize("name", sorted(ODD_BUT_VALID))
def test_odd_files_read_the_same(tmp_path, reader: str, name: str) -> None:
    """Files the pyarrow path leaves to the numpy reader (or reads itself) give the same trace."""
    text, q, lines = ODD_BUT_VALID[name]
    path = tmp_path / "odd.csv"
    path.write_text(text, encoding="utf-8")
    tr, dt = read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
    assert tr.columns["q"].tolist() == q and tr.t.tolist() == [0.0, 0.05] and dt == 0.05
    assert [tr.line(k) for k in range(2)] == lines


@needs_arrow
def test_a_bom_after_the_header_is_a_bad_cell(tmp_path) -> None:
    """pyarrow drops a byte-order mark at the start of what it reads; float() does not take one."""
    path = tmp_path / "bom.csv"
    path.write_text("t,q,qdot\n\ufeff0,0,0\n0.05,0,0\n", encoding="utf-8")
    assert trace_mod._read_csv_arrow(str(path), ("q", "qdot")) is None
    with pytest.raises(InputError, match="not a number: '\ufeff0' \\(column t\\)"):
        read_trace(str(path), ("q", "qdot"), ("q", "qdot"))


CELLS = ["0", "1.5", "-2", "1e3", "-0", ".5", "5.", "+1", " 3 ", "\t4", "1_0", "nan", "inf", "", "x", '"2"', "1e400"]
CELLS += ["2.5e-324", "0.30000000000000004", "\u00a01", "1\x0c"]


@st.composite
def csv_texts(draw: st.DrawFn) -> str:
    cols = draw(
        st.sampled_from([["t", "q", "qdot"], ["t", "q", "qdot", "z"], ["q", "t", "qdot"], [" t", "q ", "qdot"]])
    )
    lines = [",".join(cols)]
    for k in range(draw(st.integers(0, 12))):
        if draw(st.integers(0, 12)) == 0:
            lines.append(draw(st.sampled_from(["", "  ", ",,"])))
            continue
        row = [repr(k * 0.5), repr(draw(st.floats(allow_nan=False, allow_infinity=False))), "0.0", "7"][: len(cols)]
        if draw(st.integers(0, 4)) == 0:
            row[draw(st.integers(0, len(row) - 1))] = draw(st.sampled_from(CELLS))
        if draw(st.integers(0, 15)) == 0:
            row = row[:-1] if draw(st.booleans()) else [*row, "1"]
        lines.append(",".join(row))
    end = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    text = end.join(lines) + (end if draw(st.booleans()) else "")
    return ("\ufeff" if draw(st.integers(0, 5)) == 0 else "") + text


def outcome(path) -> tuple:
    try:
        tr, dt = read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
    except InputError as exc:
        return ("error", exc.render())
    return (
        "ok",
        tr.t.tobytes(),
        {k: v.tobytes() for k, v in tr.columns.items()},
        dt,
        list(map(tr.line, range(len(tr.t)))),
    )


@needs_arrow
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(csv_texts())
def test_both_readers_agree(tmp_path, monkeypatch: pytest.MonkeyPatch, text: str) -> None:
    path = tmp_path / "t.csv"
    path.write_bytes(text.encode("utf-8"))
    monkeypatch.delenv(READER_ENV, raising=False)
    monkeypatch.setattr(trace_mod, "ARROW_MIN_BYTES", 0)
    fast = outcome(path)
    monkeypatch.setenv(READER_ENV, "numpy")
    assert fast == outcome(path), text


def test_the_time_checks_in_blocks_find_the_first_bad_sample(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    """read_trace checks the time column in blocks: the error is the first one, at any block size."""
    t = (np.arange(40) * 0.25).tolist()
    cases = {
        "backwards after an uneven step": ({9: 2.3, 30: 7.0}, ":32: error: time must increase: t = 7 after t = 7.25"),
        "backwards late": ({33: 8.0}, ":35: error: time must increase: t = 8 after t = 8"),
        "uneven at a block's start": ({16: 4.1}, ":18: error: time step is not uniform: t goes from 3.75 to 4.1"),
        "drift": (None, ":5: error: time step is not uniform: t = 0.75 is off the grid t0 + k * 0.250115 s"),
    }
    drift = [k * 0.25 for k in range(20)] + [4.75 + k * 0.25 * (1 + 9e-4) for k in range(1, 21)]
    dt = (drift[-1] - drift[0]) / 39  # the first sample off the grid, by hand: sample 3, on line 5
    assert [k for k, v in enumerate(drift) if abs(v - k * dt) > 1e-3 * dt][0] == 3
    for name, (change, expected) in cases.items():
        times = list(t)
        if change is None:  # the steps of the second half a little long: only the grid test sees it
            times = drift
        else:
            for k, v in change.items():
                times[k] = v
        path = tmp_path / f"{name}.csv"
        path.write_text("t,q,qdot\n" + "".join(f"{v!r},0,0\n" for v in times), encoding="utf-8")
        got = []
        for block in (1, 7, 16, 1 << 20):
            monkeypatch.setattr(trace_mod, "_BLOCK", block)
            with pytest.raises(InputError) as info:
                read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
            got.append(info.value.render())
        assert got[0].startswith(f"{path}{expected}"), (name, got[0])
        assert len(set(got)) == 1, (name, got)


def test_check_prints_the_same_with_either_reader(tmp_path, reader: str) -> None:
    from mitlc.cli.main import main

    spec = str(trace_mod.Path(__file__).resolve().parent.parent / "specs" / "pendulum" / "p3_avoid_speed_limit.mitl")
    t = np.arange(200) * 0.05
    path = tmp_path / "run.csv"
    path.write_text(
        "t,q,qdot\n" + "".join(f"{a!r},{0.1 * float(np.sin(a))!r},{0.5 * float(np.cos(a))!r}\n" for a in t.tolist()),
        encoding="utf-8",
    )
    r = CliRunner().invoke(main, ["check", "--json", spec, str(path)])
    assert r.exit_code in (0, 1), r.output
    assert '"samples": 200' in r.output and '"dt": 0.05' in r.output


def test_without_pyarrow_the_numpy_reader_reads(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Where pyarrow is not installed (or does not load), the numpy reader reads, to the same values."""
    monkeypatch.delenv(READER_ENV, raising=False)
    monkeypatch.setattr(trace_mod, "_pyarrow", lambda: None)
    path, qdot = awkward_file(tmp_path, AWKWARD)
    assert trace_mod._read_csv_arrow(str(path), ("q", "qdot")) is None
    tr, _ = read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
    assert bits(tr.columns["q"]) == bits(float(c) for c in AWKWARD) and bits(tr.columns["qdot"]) == bits(qdot)


def test_pyarrow_reads_only_files_that_pay_for_its_import(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Below ARROW_MIN_BYTES, while pyarrow is not imported, the numpy reader reads (importing pyarrow
    costs more than it saves there); at or above it, or once pyarrow is imported, pyarrow's reader is
    tried first."""
    path = tmp_path / "t.csv"
    path.write_text("t,q\n0,1\n0.5,2\n")
    tried: list[str] = []
    monkeypatch.delenv(READER_ENV, raising=False)
    monkeypatch.setattr(trace_mod, "_read_csv_arrow", lambda p, needed: tried.append(p))
    monkeypatch.delitem(sys.modules, "pyarrow.csv", raising=False)
    small = trace_mod._read_csv(str(path), ("t", "q"))
    assert tried == [] and small.t.tolist() == [0.0, 0.5]
    monkeypatch.setattr(trace_mod, "ARROW_MIN_BYTES", path.stat().st_size)
    assert trace_mod._read_csv(str(path), ("t", "q")).t.tolist() == [0.0, 0.5] and tried == [str(path)]
    monkeypatch.setattr(trace_mod, "ARROW_MIN_BYTES", path.stat().st_size + 1)
    monkeypatch.setitem(sys.modules, "pyarrow.csv", object())
    trace_mod._read_csv(str(path), ("t", "q"))
    assert tried == [str(path)] * 2
