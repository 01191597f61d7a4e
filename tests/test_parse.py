"""The spec language: precedence, spellings, intervals, settings and clean errors."""

from __future__ import annotations

import math
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.errors import MitlError, SpecError, SpecSyntaxError
from mitlc.spec import ast as A
from mitlc.spec.parse import MAX_DEPTH, load_spec, parse_formula, parse_predicate, parse_spec

a, b, c, d = (A.Atom(n) for n in "abcd")


# ----------------------------------------------------------------- precedence
PRECEDENCE = [
    ("a & b | c", A.Or(A.And(a, b), c)),
    ("a | b & c", A.Or(a, A.And(b, c))),
    ("a -> b -> c", A.Implies(a, A.Implies(b, c))),
    ("a | b -> c", A.Implies(A.Or(a, b), c)),
    ("a <-> b -> c", A.Iff(a, A.Implies(b, c))),
    ("a <-> b <-> c", A.Iff(A.Iff(a, b), c)),
    ("a & b & c", A.And(A.And(a, b), c)),
    ("a U b U c", A.Until(a, A.Until(b, c))),
    ("a U b & c", A.And(A.Until(a, b), c)),
    ("!a U b", A.Until(A.Not(a), b)),
    ("F a U b", A.Until(A.Eventually(a), b)),
    ("G a & b", A.And(A.Globally(a), b)),
    ("F G a", A.Eventually(A.Globally(a))),
    ("2 * a & b", A.And(A.Weighted(2, a), b)),
    ("2 * (a & b)", A.Weighted(2, A.And(a, b))),
    ("10 * G !a", A.Weighted(10, A.Globally(A.Not(a)))),
    ("2 * !a U[1,2] b", A.Until(A.Weighted(2, A.Not(a)), b, A.Interval(1, 2))),
    ("a R b W c", A.Release(a, A.WeakUntil(b, c))),
    ("!!a", A.Not(A.Not(a))),
    ("(a)", a),
    ("true & false", A.And(A.Const(True), A.Const(False))),
]


@pytest.mark.parametrize("text,want", PRECEDENCE)
def test_precedence(text: str, want: A.Formula) -> None:
    assert parse_formula(text) == want


SPELLINGS = [
    ("!a", ["~a", "not a", "¬a"]),
    ("a & b", ["a && b", "a and b", "a ∧ b", "a /\\ b"]),
    ("a | b", ["a || b", "a or b", "a ∨ b", "a \\/ b"]),
    ("a -> b", ["a => b", "a implies b", "a → b"]),
    ("a <-> b", ["a iff b", "a <=> b", "a ↔ b"]),
    ("F a", ["<> a", "eventually a", "◇a", "◊ a"]),
    ("G a", ["[] a", "always a", "□a"]),
    ("a U b", ["a until b"]),
    ("a R b", ["a release b"]),
    ("a W b", ["a weak_until b"]),
    ("F[1,2] a", ["F[1:2] a", "<>[1, 2] a", "eventually[1.0,2.0] a"]),
    ("G[0,inf) a", ["G[0,infty) a", "G[0, ∞) a", "G a", "G[0,inf] a"]),
]


@pytest.mark.parametrize("canonical,variants", SPELLINGS)
def test_spellings(canonical: str, variants: list[str]) -> None:
    want = parse_formula(canonical)
    for v in variants:
        assert parse_formula(v) == want, v


def test_names_that_start_like_keywords_are_names() -> None:
    assert parse_formula("Fx & notable | Gamma U Until2") == A.Or(
        A.And(A.Atom("Fx"), A.Atom("notable")), A.Until(A.Atom("Gamma"), A.Atom("Until2"))
    )


@pytest.mark.parametrize(
    "text,interval",
    [
        ("F[1,2] a", A.Interval(1, 2, True, True)),
        ("F(1,2] a", A.Interval(1, 2, False, True)),
        ("F[1,2) a", A.Interval(1, 2, True, False)),
        ("F(1,2) a", A.Interval(1, 2, False, False)),
        ("F[0.5,inf) a", A.Interval(0.5, math.inf, True, False)),
        ("F[2:3] a", A.Interval(2, 3, True, True)),
        ("F[1,1] a", A.Interval(1, 1, True, True)),
    ],
)
def test_intervals(text: str, interval: A.Interval) -> None:
    f = parse_formula(text)
    assert isinstance(f, A.Eventually) and f.interval == interval


def test_round_trip_examples() -> None:
    for text in [t for t, _ in PRECEDENCE] + ["2 * !kappa U(1,2] (3 * kappa U(2,inf) G !kappa)"]:
        f = parse_formula(text)
        assert parse_formula(str(f)) == f


# ----------------------------------------------------------------- predicates
def test_predicate_printing_and_chains() -> None:
    p = parse_predicate("0.3 < q < pi/2 + 0.5 and not abs(qdot) >= 10 or q == -1")
    assert str(p) == "0.3 < q < pi / 2 + 0.5 and not abs(qdot) >= 10 or q == -1"
    assert parse_predicate(str(p)) == p


# ----------------------------------------------------------------- specs
SPEC = """\
# a comment
plant pendulum(u_max = 10)   // another comment
init q in [2.4, pi], qdot = 0
horizon 3
option conjunction = active
prop kappa = abs(q) < 0.3
prop psi = 0.3 < q < pi/2 + 0.5
formula F G kappa & 10 * G !psi
check F G kappa & G !psi
"""


def test_spec_settings() -> None:
    s = parse_spec(SPEC, "p2.mitl")
    assert s.plant_name == "pendulum" and s.param("u_max") == 10.0 and s.param("dt") == 0.03
    assert [(r.var, r.lo, r.hi) for r in s.init] == [("q", 2.4, math.pi), ("qdot", 0.0, 0.0)]
    assert s.horizon == 3.0
    assert s.option("conjunction") == "active"
    assert str(s.monitor_formula) == "F G kappa & G !psi"
    assert s.warnings == ()


def test_unused_proposition_is_a_warning() -> None:
    s = parse_spec("prop a = x < 1\nprop b = x > 2\nformula G a\n", "w.mitl")
    assert s.warnings == ("w.mitl:2:6: warning: proposition 'b' is never used",)


def test_thesis_specs_load(spec_dir) -> None:
    for path in sorted((spec_dir / "pendulum").glob("*.mitl")):
        s = load_spec(path)
        assert s.plant_name == "pendulum" and s.horizon == 3.0 and not s.warnings


# ----------------------------------------------------------------- errors
ERRORS = [
    ("formula F G kapa\nprop kappa = q < 1", SpecError, 1, 13, "undefined proposition 'kapa'"),
    ("prop k = q < 1\nformula F[2,1] k", SpecError, 2, 11, "inverted interval [2,1]"),
    ("prop k = q < 1\nformula F(1,1] k", SpecError, 2, 11, "empty interval (1,1]"),
    ("prop k = q < 1\nformula 0 * k", SpecError, 2, 9, "weight 0 must be positive"),
    ("prop k = q < 1\nformula G[1,2 k", SpecSyntaxError, 2, 15, "expected"),
    ("prop k = q < 1\nformula k &", SpecSyntaxError, 2, 12, "unexpected end of input"),
    ("prop k = q < 1\nformula k $ k", SpecSyntaxError, 2, 11, "unexpected character '$'"),
    ("plant pendulum\nprop k = theta < 1\nformula G k", SpecError, 2, 10, "unknown state variable 'theta'"),
    ("plant rocket\nprop k = q < 1\nformula G k", SpecError, 1, 7, "unknown plant 'rocket'"),
    ("plant pendulum(mass = 2)\nprop k = q < 1\nformula G k", SpecError, 1, 16, "no parameter 'mass'"),
    ("prop k = q + 1\nformula G k", SpecError, 1, 6, "must be a condition"),
    ("prop k = foo(q) < 1\nformula G k", SpecError, 1, 10, "unknown function 'foo'"),
    ("prop k = q < 1\nprop k = q > 1\nformula G k", SpecError, 2, 6, "defined twice"),
    ("prop F = q < 1\nformula G a", SpecError, 1, 6, "reserved word"),
    ("prop k = q < 1", SpecError, 1, 1, "no 'formula'"),
    ("prop k = q < 1\nformula G k\nformula F k", SpecError, 3, 9, "more than one 'formula'"),
    ("plant pendulum\ninit q in [1, 0]\nprop k = q < 1\nformula G k", SpecError, 2, 6, "inverted initial range"),
    ("prop k = q < 1\noption conjunction = mean\nformula G k", SpecError, 2, 8, "must be one of"),
]


@pytest.mark.parametrize("text,cls,line,col,message", ERRORS)
def test_errors_are_located(text: str, cls: type, line: int, col: int, message: str) -> None:
    with pytest.raises(cls) as info:
        parse_spec(text, "bad.mitl")
    err = info.value
    assert (err.file, err.line, err.column) == ("bad.mitl", line, col)
    assert message in err.message
    assert err.headline().startswith(f"bad.mitl:{line}:{col}: ")


def test_syntax_error_shows_line_and_caret() -> None:
    with pytest.raises(SpecSyntaxError) as info:
        parse_spec("prop k = q < 1\nformula G[1,2 k\n", "bad.mitl")
    assert info.value.render().splitlines() == [
        "bad.mitl:2:15: syntax error: unexpected 'k', expected ')', ',' or ':', ']'",
        "  formula G[1,2 k",
        "                ^",
    ]
    assert "expected" in info.value.message and "']'" in info.value.message


def test_nesting_too_deep() -> None:
    text = "prop k = q < 1\nformula " + "!" * (MAX_DEPTH + 5) + "k"
    with pytest.raises(SpecError, match="nesting too deep"):
        parse_spec(text)
    deep = "prop k = q < 1\nformula " + "(" * 5000 + "k" + ")" * 5000
    parse_spec(deep)  # parentheses alone do not nest the tree


# ----------------------------------------------------------------- fuzz
VALID = SPEC


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=200))
def test_fuzz_arbitrary_text(text: str) -> None:
    try:
        spec = parse_spec(text, "fuzz.mitl")
    except MitlError as err:
        assert err.headline().startswith("fuzz.mitl")
        _located_in(err, text)
        return
    _round_trips(spec)


def _located_in(err: MitlError, text: str) -> None:
    """An error's line and column lie in the text (the column may be one past a line's end); a lone
    carriage return ends a line as a line feed does (old Mac line ends)."""
    lines = re.sub(r"\r(?!\n)", "\n", text).split("\n")
    if err.line is not None:
        assert 1 <= err.line <= len(lines), (err.line, len(lines))
        if err.column is not None:
            assert 1 <= err.column <= len(lines[err.line - 1]) + 1


def _round_trips(spec) -> None:
    """What parsed prints back to text that parses to the same trees: a wrong parse would not."""
    for f in (spec.formula, spec.check):
        if f is not None:
            assert parse_formula(str(f)) == f
    for p in spec.props:
        assert str(parse_predicate(str(p.pred))) == str(p.pred)
    defined = {p.name for p in spec.props}
    for f in (spec.formula, spec.check):
        if f is not None:
            assert set(A.atoms(f)) <= defined


@settings(max_examples=400, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.integers(0, len(VALID) - 1),
            st.sampled_from(["del", "ins", "rep"]),
            st.sampled_from(list("()[],:!&|<>-=*/. \n#FGURW0123456789aqkp") + ["inf", "prop", "U[", "¬", "\t"]),
        ),
        min_size=1,
        max_size=4,
    )
)
def test_fuzz_mutated_specs(mutations) -> None:
    text = VALID
    for pos, op, piece in mutations:
        pos = min(pos, len(text))
        if op == "del":
            text = text[:pos] + text[pos + 1 :]
        elif op == "ins":
            text = text[:pos] + piece + text[pos:]
        else:
            text = text[:pos] + piece + text[pos + len(piece) :]
    try:
        spec = parse_spec(text, "m.mitl")
    except MitlError as err:
        assert err.headline().startswith("m.mitl")
        _located_in(err, text)
        return
    _round_trips(spec)


# ----------------------------------------------------------------- classical criteria (chapter 3)
def test_requirements() -> None:
    s = parse_spec(
        "plant mass-damper\ninit q in [-1, -0.5], qdot = 0\nhorizon 3\nsetpoint 0.5\n"
        "require overshoot <= 0\nrequire rise_time in [0.6, 0.8]\n"
        "require settling_time <= 2 band 0.05\nrequire steady_state_error < 0.02\n"
    )
    assert s.formula is None and s.setpoint == 0.5 and s.plant_name == "mass-damper"
    assert [(r.name, r.lo, r.hi, r.band) for r in s.requirements] == [
        ("overshoot", 0.0, 0.0, None),
        ("rise_time", 0.6, 0.8, None),
        ("settling_time", 0.0, 2.0, 0.05),
        ("steady_state_error", 0.0, 0.02, None),
    ]


@pytest.mark.parametrize(
    "line,message",
    [
        ("require overshot <= 0", "unknown criterion 'overshot'"),
        ("require overshoot >= 0", "upper bound"),
        ("require rise_time in [0.8, 0.6]", "0 <= lower <= upper"),
        ("require overshoot <= 0 band 0.1", "only settling_time takes a band"),
        ("require settling_time <= 2 band 5", "band must be a fraction"),
    ],
)
def test_requirement_errors(line: str, message: str) -> None:
    with pytest.raises(SpecError, match=message):
        parse_spec(f"plant mass-damper\n{line}\n")


def test_boundaries_of_what_is_accepted():
    """Each limit on its edge: accepted at it, refused one past it."""
    base = "plant pendulum\nprop a = q > 0\n"
    assert parse_spec(base + "horizon 0.5\nformula 0.5 * G a\n").horizon == 0.5  # positive, below 1
    deep = "!" * 63 + "a"  # 64 levels: the deepest accepted
    assert parse_spec(base + f"formula {deep}\n")
    with pytest.raises(SpecError, match="more than 64 levels"):
        parse_spec(base + f"formula !{deep}\n")
    gym = "plant gym:Pendulum-v1\nstate x = obs[{i}]\nprop b = x > 0\nformula F b\n"
    pytest.importorskip("gymnasium")
    with pytest.raises(SpecError, match="observation index is a whole number"):
        parse_spec(gym.format(i=2**31))
    with pytest.raises(SpecError, match="outside the observation"):
        parse_spec(gym.format(i=2**31 - 1))


def test_statements_errors_are_located_on_their_own_line():
    def error(text: str) -> MitlError:
        with pytest.raises(MitlError) as err:
            parse_spec(text, "s.mitl")
        return err.value

    tail = "prop a = q > 0\nformula F a\n"
    e = error("plant pendulum\nhorizon 3\n\nhorizon -1\n" + tail)
    assert (e.line, e.column) == (4, 1) and "positive" in e.message
    e = error("plant pendulum\nsetpoint 1\n  setpoint 2\n" + tail)
    assert (e.line, e.column) == (3, 3) and "'setpoint' given twice" in e.message
    e = error("plant pendulum(u_max = -1)\n" + tail)
    assert (e.line, e.column) == (1, 16) and "must be positive" in e.message
    e = error("plant pendulum\nplant pendulum\n" + tail)
    assert e.line == 2 and "'plant' given twice" in e.message
    long_chain = "prop a = q > 0\nformula " + " & ".join(["a"] * 256) + "\n"
    assert parse_spec("plant pendulum\n" + long_chain)  # a tree 256 deep: the deepest accepted
    e = error("plant pendulum\nprop a = q > 0\nformula " + " & ".join(["a"] * 257) + "\n")
    assert "more than 256 operators deep" in e.message


def test_intervals_closed_at_infinity_read_as_open():
    f = parse_formula("F[1,inf] a & G[1,2] a")
    ev, gl = f.left, f.right
    assert (ev.interval.hi_closed, gl.interval.hi_closed, gl.interval.lo_closed) == (False, True, True)
    assert str(f) == "F[1,inf) a & G[1,2] a"


def test_gym_statements_are_checked():
    pytest.importorskip("gymnasium")
    base = "plant gym:Pendulum-v1\n{state}\nprop b = x > 0\nformula F b\n"
    for state, message in (
        ("state pi = obs[0], x = obs[1]", "reserved word"),
        ("state prop = obs[0], x = obs[1]", None),  # a keyword: not even a name
        ("state x = obs[0] in [2, 1]", "lower < upper"),
    ):
        with pytest.raises(MitlError) as err:
            parse_spec(base.format(state=state))
        if message is not None:
            assert message in err.value.message
    spec = parse_spec(base.format(state="state x = obs[0] + 1 in [0, 2]") + "horizon 1\n")
    assert (spec.plant.var("x").lo, spec.plant.var("x").hi) == (0.0, 2.0)
    with pytest.raises(MitlError, match="'plant' given twice"):
        parse_spec("plant gym:Pendulum-v1\nplant gym:Pendulum-v1\nstate x = obs[0]\nprop b = x > 0\nformula F b\n")


@pytest.mark.parametrize(
    ("text", "expected"),
    [("prop = x > 1", "expected a name"), ("formula F (a", "unexpected end of input, expected ')'")],
)
def test_expected_tokens_are_said_in_words(text: str, expected: str) -> None:
    with pytest.raises(SpecSyntaxError) as info:
        parse_spec(text)
    assert expected in str(info.value)


def test_error_lines_count_only_newlines() -> None:
    """A NEL or a line separator inside a comment is not a line break for the parser, nor for the
    error's position (hypothesis found '#\\x850' reported on line 2 of a one-line text)."""
    for text in ("#\x850", "# a\u2028b", "#\x0c\n"):
        with pytest.raises(MitlError) as err:
            parse_spec(text, "fuzz.mitl")
        assert (err.value.line, err.value.column) == (1, 1)
