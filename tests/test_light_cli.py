"""A light command line (issue #17, part 3): ``mitlc check`` loads no trainer, plotter or graph
library, ``mitlc --help`` lists every command without importing one, and the chunked numpy CSV
reader reads every file exactly as the old row-by-row reader did (values, lines, errors)."""

from __future__ import annotations

import importlib
import importlib.util
import json
import os
import pkgutil
import subprocess
import sys
from pathlib import Path

import click
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mitlc.cli
from mitlc.cli.main import COMMANDS
from mitlc.errors import InputError
from mitlc.monitor import trace as trace_mod
from mitlc.monitor.trace import read_trace

ROOT = Path(__file__).resolve().parent.parent
SPEC = str(ROOT / "specs" / "pendulum" / "p3_avoid_speed_limit.mitl")
HEAVY = (
    "matplotlib",
    "graphviz",
    "networkx",
    "gymnasium",
    "torch",
    "pandas",  # pyarrow's to_numpy loads it; the pyarrow reader reads its buffers in place
    "importlib.metadata",  # the plant entry points, looked up only for a plant mitlc does not know
    "mitlc.learn",
    "mitlc.petri",
    "mitlc.sweep",
    "mitlc.cli.train",
    "mitlc.cli.hybrid",
    "mitlc.cli.sweep",
    "mitlc.cli.compile",
)
"""What ``mitlc check`` (without --net) needs none of."""


def _old_read_csv():
    spec = importlib.util.spec_from_file_location("bench_check", ROOT / "bench" / "bench_check.py")
    assert spec is not None and spec.loader is not None
    sys.path.insert(0, str(ROOT / "bench"))  # for its `from _timing import timed`
    try:
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(ROOT / "bench"))
    return module.old_read_csv


old_read_csv = _old_read_csv()


def loaded_after(args: list[str]) -> dict:
    """Run ``main(args)`` in a fresh interpreter; what it printed and which modules it loaded."""
    code = (
        "import json, sys\nfrom mitlc.cli.main import main\n"
        "try:\n    main(sys.argv[1:], standalone_mode=False)\nexcept SystemExit:\n    pass\n"
        "sys.stderr.write(json.dumps(sorted(sys.modules)) + '\\n')\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True, text=True, check=True)
    return {"out": r.stdout, "modules": json.loads(r.stderr.splitlines()[-1])}


def heavy_in(modules: list[str]) -> list[str]:
    return [m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY)]


def test_check_loads_no_heavy_module(tmp_path: Path) -> None:
    trace = tmp_path / "t.csv"
    t = (np.arange(61) * 0.05).tolist()
    rows = "".join(f"{a!r},{0.1 * float(np.sin(a))!r},0.0\n" for a in t)
    trace.write_text("t,q,qdot\n" + rows, encoding="utf-8")
    got = loaded_after(["check", SPEC, str(trace)])
    assert got["out"].startswith(f"{trace}: satisfied"), got["out"]
    assert "mitlc.cli.check" in got["modules"] and "mitlc.monitor.offline" in got["modules"]
    assert heavy_in(got["modules"]) == []


def test_check_net_loads_only_the_net(tmp_path: Path) -> None:
    """``check --net`` loads the compiler and the runtime, and of the heavy modules no more (its tables'
    key reads the net as data: no networkx, which only ``to_networkx`` needs)."""
    trace = tmp_path / "t.csv"
    t = (np.arange(61) * 0.05).tolist()
    trace.write_text("t,q,qdot\n" + "".join(f"{a!r},0.0,0.0\n" for a in t), encoding="utf-8")
    got = loaded_after(["check", "--net", "pendulum/n1_reach_in_time", str(trace)])
    assert "net: " in got["out"], got["out"]
    assert "mitlc.runtime.tablefile" in got["modules"] and "mitlc.petri.export" in got["modules"]
    assert heavy_in([m for m in got["modules"] if m.split(".")[:2] != ["mitlc", "petri"]]) == []


def test_help_lists_every_command_and_imports_none() -> None:
    got = loaded_after(["--help"])
    listed = [line.split()[0] for line in got["out"].split("Commands:\n")[1].splitlines() if line.strip()]
    assert listed == sorted(COMMANDS), got["out"]
    commands = [
        m for m in got["modules"] if m.startswith("mitlc.cli.") and m not in ("mitlc.cli.main", "mitlc.cli.interrupt")
    ]
    assert commands == [], commands
    assert heavy_in(got["modules"]) == []


def test_the_table_matches_the_commands() -> None:
    """Every click command of mitlc.cli's modules is in COMMANDS, under its own name, and the table's
    short help is the start of its docstring."""
    found: dict[str, click.Command] = {}
    for info in pkgutil.iter_modules(mitlc.cli.__path__):
        module = importlib.import_module(f"mitlc.cli.{info.name}")
        for attr, value in vars(module).items():
            if isinstance(value, click.Command) and not isinstance(value, click.Group) and value.__module__ != "click":
                found[value.name or attr] = value
                if value.name in COMMANDS:
                    assert COMMANDS[value.name][:2] == (info.name, attr), value.name
    assert set(found) == set(COMMANDS)
    for name, (_, _, short) in COMMANDS.items():
        assert " ".join((found[name].help or "").split()).startswith(short.rstrip(".")), name


def test_help_names_each_command_with_its_short_help() -> None:
    from click.testing import CliRunner

    from mitlc.cli.main import main

    out = CliRunner().invoke(main, ["--help"], terminal_width=200).output
    for name, (_, _, short) in COMMANDS.items():
        assert any(line.split() == [name, *short.split()] for line in out.splitlines()), (name, out)


# --- the reader against the old one -------------------------------------------------------------

CELLS = ["0", "1.5", "-2", "1e3", "1E-2", ".5", "5.", "+1", " 3 ", "\t4", "1_0", "0x1", "nan", "inf", "-Infinity"]
CELLS += [
    "",
    " ",
    "abc",
    '"2"',
    "1e",
    "-",
    "1.2.3",
    "\u0661",
    "1e400",
    "2.5e-324",
    "0.1000000000000000055511151231257827",
]
ENDS = ["\n", "\n", "\n", "\r\n", "\r", "\x0c", "\u2028"]


@st.composite
def csv_texts(draw: st.DrawFn) -> str:
    cols = draw(st.sampled_from([["t", "q", "qdot"], ["t", "q", "qdot", "z"], ["q", "t", "qdot"], ["t", "q"]]))
    lines = [",".join(cols)]
    n = draw(st.integers(0, 12))
    for k in range(n):
        if draw(st.integers(0, 9)) == 0:
            lines.append(draw(st.sampled_from(["", "  ", ",,"])))
            continue
        row = [repr(k * 0.5), repr(float(draw(st.integers(-3, 3)))), "0.0", "7"][: len(cols)]
        if draw(st.integers(0, 3)) == 0:
            row[draw(st.integers(0, len(row) - 1))] = draw(st.sampled_from(CELLS))
        if draw(st.integers(0, 15)) == 0:
            row = row[:-1] if draw(st.booleans()) else [*row, "1"]
        lines.append(",".join(row))
    if draw(st.integers(0, 5)) == 0:
        lines.insert(0, "")
    ends = [draw(st.sampled_from(ENDS)) for _ in lines]
    text = "".join(line + end for line, end in zip(lines, ends, strict=True))
    return ("\ufeff" if draw(st.integers(0, 5)) == 0 else "") + (text if draw(st.booleans()) else text.rstrip())


def outcome(path: Path) -> tuple:
    try:
        tr, dt = read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
    except InputError as exc:
        return ("error", exc.render())
    cols = {k: v.tobytes() for k, v in tr.columns.items()}
    return ("ok", tr.t.tobytes(), cols, dt, [tr.line(k) for k in range(len(tr.t))])


def both(path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[tuple, tuple]:
    new = outcome(path)
    with monkeypatch.context() as m:
        m.setattr(trace_mod, "_read_csv", old_read_csv)
        old = outcome(path)
    return new, old


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(csv_texts(), st.sampled_from([7, 40, 1 << 24]))
def test_reader_agrees_with_the_old_one(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, text: str, chunk: int):
    """Same values (to the bit), same source line of every sample, same error line for every file;
    in chunks of a few bytes too, so that numpy-read and row-by-row chunks mix."""
    path = tmp_path / "t.csv"
    path.write_bytes(text.encode("utf-8"))
    monkeypatch.setattr(trace_mod, "CHUNK_BYTES", chunk)
    new, old = both(path, monkeypatch)
    assert new == old, text


@pytest.mark.parametrize("chunk", [16, 1 << 24])
def test_a_long_trace_reads_as_before(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, chunk: int) -> None:
    """Thousands of rows as repr writes them, a blank line, CRLF in part, then a late step error:
    the same arrays and the same located error as the old reader."""
    t = (np.arange(3000) * 0.05).tolist()
    rows = [f"{a!r},{float(np.sin(a))!r},{float(np.cos(a))!r}" for a in t]
    rows.insert(1500, "")  # skipped, but counted: sample k >= 1500 is on line k + 3
    text = "t,q,qdot\n" + "\r\n".join(rows[:100]) + "\r\n" + "\n".join(rows[100:]) + "\n"
    path = tmp_path / "long.csv"
    path.write_text(text, encoding="utf-8")
    monkeypatch.setattr(trace_mod, "CHUNK_BYTES", chunk)
    new, old = both(path, monkeypatch)
    assert new[0] == "ok" and new == old
    rows[2901] = f"{t[2900] + 0.01!r},0,0"  # sample 2900
    path.write_text("t,q,qdot\n" + "\n".join(rows) + "\n", encoding="utf-8")
    new, old = both(path, monkeypatch)
    assert new == old and new[0] == "error" and new[1].startswith(f"{path}:2903: error: time step is not uniform")


def test_a_bad_row_after_a_bad_byte_is_still_not_utf8(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The old reader decoded the whole file first: bytes that are not UTF-8 anywhere come before a bad
    number on an earlier line."""
    path = tmp_path / "t.csv"
    path.write_bytes(b"t,q,qdot\n0,zero,0\n" + b"0.5,0,0\n" * 50 + b"1,\xff,0\n")
    monkeypatch.setattr(trace_mod, "CHUNK_BYTES", 32)
    new, old = both(path, monkeypatch)
    assert new == old and "not UTF-8 text" in new[1]


def test_a_csv_error_is_one_located_line(tmp_path: Path) -> None:
    """A field past csv's size limit (the old reader let csv.Error out as a traceback)."""
    path = tmp_path / "t.csv"
    path.write_text("t,q,qdot\n0,0,0\n" + '"' + "1" * 200_000 + '",0,0\n', encoding="utf-8")
    with pytest.raises(InputError) as info:
        read_trace(str(path), ("q", "qdot"), ("q", "qdot"))
    assert info.value.render().startswith(f"{path}:3: error: cannot read trace: field larger than field limit")


def test_the_parser_tables_are_kept_on_disk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Building the LALR tables was most of a short check's start-up: lark keeps them in mitlc's cache
    folder, and a parser loaded from there parses as a built one does; MITLC_CACHE_DIR= turns it off."""
    from mitlc.spec import lark_tables as T
    from mitlc.spec import parse as P

    text = "[] (a -> <>[0:2.5] b) && !c"
    built = str(P.parse_formula(text))
    monkeypatch.setenv("MITLC_CACHE_DIR", str(tmp_path))
    T.parser_for.cache_clear()
    try:
        assert str(P.parse_formula(text)) == built == "G (a -> F[0,2.5] b) & !c"
        files = list((tmp_path / "parser").iterdir())
        assert [f.name[:13] for f in files] == ["mitl-formula-"] and files[0].stat().st_size > 1000
        T.parser_for.cache_clear()
        assert str(P.parse_formula(text)) == built  # from the file this time
        assert list((tmp_path / "parser").iterdir()) == files
        monkeypatch.setenv("MITLC_CACHE_DIR", "")
        assert T._table_file("grammar", "start") is False
    finally:
        T.parser_for.cache_clear()


FAULTS = """
import resource, sys
import numpy as np
from mitlc.cli.memory import keep_freed_memory
from mitlc.monitor.kernels import window
print(keep_freed_memory() if sys.argv[1] == "1" else False)
x = np.random.default_rng(0).standard_normal((512, 451))
window(x, 0, 80, np.maximum, -np.inf)
r0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(20):
    window(x, 0, 80, np.maximum, -np.inf)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - r0)
"""


def test_a_training_process_keeps_freed_memory() -> None:
    """mitlc train, sweep and verify tune glibc's malloc (mitlc.cli.memory): a monitor's windows over
    512 rollouts, made and dropped 20 times, fault their pages in every time without it, never with it."""
    import platform

    pytest.importorskip("resource")
    glibc = sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"
    runs = [subprocess.run([sys.executable, "-c", FAULTS, flag], capture_output=True, text=True) for flag in "01"]
    (off, faults_off), (on, faults_on) = [r.stdout.split() for r in runs]
    assert off == "False" and on == str(glibc)
    if glibc:
        assert int(faults_off) > 5000 and int(faults_on) < 500
    for name in ("train", "sweep", "verify"):
        source = (Path(__file__).resolve().parent.parent / "mitlc" / "cli" / f"{name}.py").read_text()
        assert "keep_freed_memory()" in source, name
