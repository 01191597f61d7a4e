"""Fuzzing the command line with damaged inputs: the shipped specs and a trace, mutated.

Whatever the damage, ``mitlc compile`` and ``mitlc check`` end with a valid result
(exit 0, or 1 for a violated trace) or with one error line naming where (exit 2):
never a traceback, never a crash inside mitlc.
"""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.cli import main

ROOT = Path(__file__).resolve().parents[1]
SPECS = sorted(p for p in (ROOT / "specs").rglob("*.mitl") if "gym" not in p.parts)  # gym: needs its env made
TRACE = "t,q,qdot\n" + "".join(f"{k * 0.03:.2f},{3.1 - 0.1 * k:.3f},{-0.5 * k:.3f}\n" for k in range(40))

PIECES = [
    "(", ")", "[", "]", ",", ":", "=", "*", "-", "+", "/", "<", "<=", ">", "&", "|", "!", "->", "<->",
    "F", "G", "U", "R", "W", "inf", "1e308", "-1e308", "0", "5e-324", "nan", "1e999", "q", "qdot", "kappa",
    "prop", "formula", "check", "plant", "init", "horizon", "option", "state", "obs[0]", "abs(", "atan2(",
    "\n", "\t", "\x0c", "\u2028", "\ufeff", "\x00", "é", "#", "//", " and ", " or ", " not ", "10 * ",
]  # fmt: skip
CELLS = ["", "nan", "inf", "-inf", "1e308", "x", "0", "-0", "1e-320", "3", "\ufeff", '"', "1,2"]


@st.composite
def mutated(draw: st.DrawFn, text: str) -> str:
    """``text`` with a few random edits: deletions, insertions of grammar pieces, line swaps."""
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["delete", "insert", "swap", "duplicate"]))
        n = len(text)
        i = draw(st.integers(0, max(0, n - 1)))
        if kind == "delete" and n:
            text = text[:i] + text[i + draw(st.integers(1, 12)) :]
        elif kind == "insert":
            text = text[:i] + draw(st.sampled_from(PIECES)) + text[i:]
        else:
            lines = text.split("\n")
            a, b = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
            if kind == "swap":
                lines[a], lines[b] = lines[b], lines[a]
            else:
                lines.insert(b, lines[a])
            text = "\n".join(lines)
    return text


def assert_clean(result, ok_codes=(0,)) -> None:
    """A result, or one error line: never a traceback or an exception out of mitlc."""
    exc = result.exception
    assert exc is None or isinstance(exc, SystemExit), f"{type(exc).__name__}: {exc}\n{result.output}"
    assert "Traceback" not in result.output
    if result.exit_code == 2:
        first = result.output.strip().splitlines()[0] if result.output.strip() else ""
        assert ": error: " in first or ": syntax error: " in first, result.output
    else:
        assert result.exit_code in ok_codes, result.output


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(st.data())
def test_mutated_specs_compile_or_fail_in_one_line(tmp_path_factory, data):
    source = data.draw(st.sampled_from(SPECS))
    text = data.draw(mutated(source.read_text(encoding="utf-8")))
    path = tmp_path_factory.mktemp("fuzz") / "spec.mitl"
    path.write_text(text, encoding="utf-8")
    fmt = data.draw(st.sampled_from(["text", "json"]))
    r = CliRunner().invoke(main, ["compile", str(path), "--format", fmt], prog_name="mitlc")
    assert_clean(r)
    if r.exit_code == 0 and fmt == "json":
        json.loads(r.stdout, parse_constant=lambda c: (_ for _ in ()).throw(AssertionError(c)))


@st.composite
def mutated_csv(draw: st.DrawFn) -> str:
    rows = [line.split(",") for line in TRACE.strip().split("\n")]
    for _ in range(draw(st.integers(1, 5))):
        kind = draw(st.sampled_from(["cell", "drop_row", "dup_row", "drop_cell", "header"]))
        r = draw(st.integers(0, len(rows) - 1))
        if kind == "cell":
            rows[r][draw(st.integers(0, len(rows[r]) - 1))] = draw(st.sampled_from(CELLS))
        elif kind == "drop_row" and len(rows) > 1:
            del rows[r]
        elif kind == "dup_row":
            rows.insert(r, list(rows[r]))
        elif kind == "drop_cell" and rows[r]:
            del rows[r][draw(st.integers(0, len(rows[r]) - 1))]
        else:
            rows[0][draw(st.integers(0, len(rows[0]) - 1))] = draw(st.sampled_from(["t", "q", "", "T", "qdot", "z"]))
    return "\n".join(",".join(row) for row in rows) + "\n"


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_csv(), st.sampled_from(["pendulum/p1_swing_up", "pendulum/p2_avoid", "pendulum/n3_bounded_response"]))
def test_mutated_traces_check_or_fail_in_one_line(tmp_path_factory, text, spec):
    path = tmp_path_factory.mktemp("fuzz") / "trace.csv"
    path.write_text(text, encoding="utf-8")
    r = CliRunner().invoke(main, ["check", spec, str(path), "--json"], prog_name="mitlc")
    assert_clean(r, ok_codes=(0, 1))
    if r.exit_code in (0, 1):
        out = json.loads(r.stdout, parse_constant=lambda c: (_ for _ in ()).throw(AssertionError(c)))
        assert out["satisfied"] is (r.exit_code == 0)
