"""Fuzzing ``check`` and ``compile`` with formulas as wide and deep as the parser takes, and past it.

Random formulas of n-ary ``&`` / ``|`` chains up to 300 operands (the parser takes 255 operands of
depth 1), unary and binary temporal nesting up to 70 levels (it takes 64), inline predicates and
nested ``<->`` (whose normal form doubles per level): whatever is drawn, ``mitlc check`` gives a
verdict (exit 0 or 1) and ``mitlc compile`` a net (exit 0), or either says in one line why not (exit
2), never a traceback or ``RecursionError``, and in bounded time (docs/reliability.md, "Big and deep
inputs").
"""

from __future__ import annotations

import time
from pathlib import Path

from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.cli import main

HEAD = """\
plant pendulum(u_max = 10)
init q in [2.4, pi], qdot = 0
horizon 3
prop kappa = abs(q) < 0.3
prop psi   = 0.3 < q < pi/2 + 0.5
"""
TRACE = "t,q,qdot\n" + "".join(f"{k * 0.03:.2f},{3.1 - 0.06 * k:.3f},{-0.5 + 0.01 * k:.3f}\n" for k in range(101))
SECONDS = 90.0
"""What one command may take on a loaded two-core machine (check --net of a big timed net stepped one
sample at a time: up to some 40 s)."""

ATOMS = ["kappa", "psi", "(abs(q) < 0.3)", "(qdot > -0.2)", "true", "false"]
UNARY = ["F {}", "G {}", "!{}", "F[0,1] {}", "G[0.5,2] {}", "F[0,0.3) {}", "2 * {}"]
BINARY = ["{} U[0,1] {}", "{} R[0,2] {}", "{} W[0,1] {}", "{} -> {}", "{} <-> {}", "{} U {}"]


def _paren(f: str) -> str:
    return f if f.isidentifier() or (f.startswith("(") and f.endswith(")")) else f"({f})"


@st.composite
def small(draw: st.DrawFn) -> str:
    """An operand of depth 1 to 3."""
    f = draw(st.sampled_from(ATOMS))
    for _ in range(draw(st.integers(0, 2))):
        f = draw(st.sampled_from(UNARY)).format(_paren(f))
    return f


@st.composite
def chain(draw: st.DrawFn, operand: st.SearchStrategy[str]) -> str:
    """An n-ary ``&`` or ``|`` chain, 2 to 300 operands (past 255 the parser refuses it)."""
    n = draw(st.one_of(st.integers(2, 20), st.integers(200, 300)))
    op = draw(st.sampled_from([" & ", " | "]))
    first = draw(operand)
    rest = draw(st.lists(operand, min_size=0, max_size=8))
    return op.join(_paren(first if i == 0 else rest[i % len(rest)] if rest else first) for i in range(n))


@st.composite
def nested(draw: st.DrawFn) -> str:
    """Unary or binary operators nested 1 to 70 levels (past 64 the parser refuses them)."""
    f = draw(small())
    for _ in range(draw(st.one_of(st.integers(1, 10), st.integers(55, 70)))):
        if draw(st.booleans()):
            f = draw(st.sampled_from(UNARY)).format(_paren(f))
        else:
            other = draw(small())
            a, b = (f, other) if draw(st.booleans()) else (other, f)
            f = draw(st.sampled_from(BINARY)).format(_paren(a), _paren(b))
    return f


def formulas() -> st.SearchStrategy[str]:
    return st.one_of(chain(small()), nested(), chain(nested()), nested().map(lambda f: f"F ({f}) & G !psi"))


def _clean(result, ok: tuple[int, ...]) -> None:
    exc = result.exception
    assert exc is None or isinstance(exc, SystemExit), f"{type(exc).__name__}: {exc}"
    assert "Traceback" not in result.output and "RecursionError" not in result.output
    if result.exit_code == 2:
        lines = [ln for ln in result.stderr.rstrip("\n").splitlines() if ": warning: " not in ln]  # unused props
        assert lines and (": error: " in lines[0] or ": syntax error: " in lines[0]), result.stderr
        assert all(ln.startswith("  ") for ln in lines[1:]), result.stderr  # only the source line, caret, hint
    else:
        assert result.exit_code in ok, result.output


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(formula=formulas(), net=st.booleans())
def test_wide_and_deep_formulas_check_and_compile_or_fail_in_one_line(tmp_path_factory, formula, net):
    d: Path = tmp_path_factory.mktemp("deep")
    (d / "trace.csv").write_text(TRACE)
    (d / "s.mitl").write_text(HEAD + f"formula {formula}\n")
    runs = [
        (["check", "pendulum/p2_avoid", str(d / "trace.csv"), "--formula", formula], (0, 1)),
        (["check", str(d / "s.mitl"), str(d / "trace.csv"), *(["--net"] if net else [])], (0, 1)),
        (["compile", str(d / "s.mitl")], (0,)),
    ]
    for args, ok in runs:
        start = time.perf_counter()
        r = CliRunner().invoke(main, args, prog_name="mitlc")
        took = time.perf_counter() - start
        _clean(r, ok)
        assert took < SECONDS, (args[0], took)
