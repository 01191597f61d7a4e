"""Issue 29's reproducers of deep formulas, slow checks, plants, Ray, numpy's warnings and messages:
each one a verdict or one line with exit 2, in bounded time (docs/reliability.md, "Big and deep inputs")."""

from __future__ import annotations

import json
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli import main
from mitlc.errors import InputError
from mitlc.plants import Plant, StateVar
from mitlc.sweep.backends import probe_ray_address

ROOT = Path(__file__).resolve().parents[1]
S = "pendulum/p2_avoid"
HEAD = """\
plant pendulum(u_max = 10)
init q in [2.4, pi], qdot = 0
horizon 3
prop kappa = abs(q) < 0.3
prop psi   = 0.3 < q < pi/2 + 0.5
"""


def run(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="mitlc")


def one_error(r, code: int = 2) -> str:
    """The one line on stderr of a refused command (exit 2, no traceback), which only the offending
    source line with its caret, or a hint, may follow (indented)."""
    assert r.exit_code == code, (r.exit_code, r.output)
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    lines = r.stderr.rstrip("\n").splitlines()
    assert lines and all(ln.startswith("  ") for ln in lines[1:]), r.stderr
    assert "Traceback" not in r.output and "Warning" not in r.stderr, r.stderr
    return lines[0]


@pytest.fixture
def trace(tmp_path: Path) -> Path:
    """101 rows at dt 0.03 s: q = 3 sin(0.05 k) rises through psi (0.3 < q < 2.07) at k = 3."""
    rows = "".join(f"{k * 0.03:.2f},{3.0 * np.sin(0.05 * k):.6f},{0.15 * np.cos(0.05 * k):.6f}\n" for k in range(101))
    p = tmp_path / "trace.csv"
    p.write_text("t,q,qdot\n" + rows)
    return p


def spec_file(tmp_path: Path, formula: str, name: str = "deep.mitl") -> Path:
    p = tmp_path / name
    p.write_text(HEAD + f"formula {formula}\n")
    return p


# ---------------------------------------------------------------- deep formulas


def test_check_of_200_conjuncts_is_a_verdict_not_a_recursion_error(trace):
    formula = " & ".join(["G !psi"] * 200)
    r = run("check", S, str(trace), "--formula", formula, "--json")
    assert r.exit_code == 1, r.output
    out = json.loads(r.stdout)
    assert (out["satisfied"], out["violation_time"], out["failing"]) == (False, 0.09, "!psi")
    q = np.round(3.0 * np.sin(0.05 * np.arange(101)), 6)
    deepest = np.minimum(q - 0.3, np.pi / 2 + 0.5 - q).max()  # psi's robustness where it holds most (q = 1.2)
    assert out["robustness"] == pytest.approx(-deepest, abs=1e-9)


@pytest.mark.parametrize("shape", ["G !psi", "10 * G !psi", "F G[0,{i}] kappa", "kappa R[0,{i}] psi"])
def test_deepest_chain_the_parser_allows_checks_and_compiles(tmp_path, trace, shape):
    n = 250  # 255 operands of depth 1; these operands are 2 or 3 deep
    formula = " & ".join(shape.format(i=i + 1) for i in range(n))
    spec = spec_file(tmp_path, formula)
    r = run("check", str(spec), str(trace))
    assert r.exit_code in (0, 1) and "Traceback" not in r.output, r.output
    start = time.perf_counter()
    r = run("compile", str(spec))
    assert r.exit_code == 0, r.output
    assert time.perf_counter() - start < 20
    assert len(r.stdout) < 2_000_000  # the dense D of 1,752 x 3,002 is summarised, not printed (68 MB)


def test_one_more_operand_is_one_line(tmp_path, trace):
    formula = " & ".join(["G !psi"] * 255)
    line = one_error(run("check", S, str(trace), "--formula", formula))
    assert line.startswith("--formula:1:2285: error: formula too long: its tree is more than 256 operators deep")


def test_a_big_nets_text_summarises_its_matrix_and_json_keeps_it(tmp_path):
    from mitlc.petri.compile import compile_spec
    from mitlc.petri.export import to_dict, to_json
    from mitlc.spec.parse import load_spec

    spec = spec_file(tmp_path, " & ".join(f"F G[0,{i + 1}] kappa" for i in range(250)))
    r = run("compile", str(spec))
    assert "  3,002 x 1,752, too big for a table: each transition's row is its arcs above (6,004 arcs;" in r.stdout
    rs = compile_spec(load_spec(str(spec)))
    d = json.loads(to_json(rs))  # 3,002 x 1,752 is past DENSE_ENTRIES: the arcs only, linear in the net
    assert "D" not in d and "D_minus" not in d
    for key, dense in (("pre", rs.net.D_minus), ("post", rs.net.D_plus)):
        rebuilt = np.zeros_like(dense)
        for t, p, w in d["arcs"][key]:
            rebuilt[t, p] += w
        assert np.array_equal(rebuilt, dense) and len(d["arcs"][key]) == np.count_nonzero(dense)
    start = time.perf_counter()
    text = to_json(rs, "dense")
    assert time.perf_counter() - start < 15  # 14 s and 1.7 GB through the JSON encoder before
    d = json.loads(text)
    assert np.array_equal(np.array(d["D"]), rs.net.D) and np.array_equal(np.array(d["D_minus"]), rs.net.D_minus)
    small = compile_spec(load_spec("pendulum/n1_reach_in_time"))
    assert json.loads(to_json(small)) == to_dict(small)


def test_nested_iff_is_refused_before_its_normal_form_explodes(tmp_path, trace):
    f = "psi"
    for _ in range(60):
        f = f"kappa <-> ({f})"
    spec = spec_file(tmp_path, f"F ({f})")
    start = time.perf_counter()
    line = one_error(run("compile", str(spec)))
    assert time.perf_counter() - start < 10  # it never ended before
    assert line == (
        f"{spec}: error: the formula's normal form would have 9,223,372,036,854,775,802 operators, more than the "
        "10,000 supported: each '<->' and 'W' repeats its operands, so nesting them multiplies the formula; "
        "nest fewer, or give the repeated parts their own propositions"
    )
    r = run("check", str(spec), str(trace))  # the monitor reads <-> as it is
    assert r.exit_code == 0 and "satisfied" in r.stdout


# ---------------------------------------------------------------- check --net


def _reference_net_view(spec, tr, dt):
    """What check --net reported before: the net stepped one sample at a time."""
    from mitlc.monitor.offline import state_columns
    from mitlc.petri import reward as R
    from mitlc.petri.compile import CompileOptions, compile_spec
    from mitlc.runtime import NetRuntime

    mode = None if spec.option("violations") != "off" else "permanent"
    rs = compile_spec(spec, CompileOptions.from_spec(spec, violations=mode))
    cols = state_columns(spec)
    x = np.stack([tr.columns[c] for c in cols], axis=1)
    rt = NetRuntime(rs, cols, dt=dt, steps=len(x) - 1)
    watched, stack = [], [rs.charge] if rs.charge is not None else []
    while stack:
        e = stack.pop()
        watched += list(e.names) if isinstance(e, R.Tokens) else []
        stack.extend(e.children)
    idx = [rs.net.place_index(p) for p in dict.fromkeys(watched)]
    M = rt.reset(x[:1])
    for k in range(len(x)):
        if k:
            M = rt.step(M, x[k : k + 1], k * dt)
        marked = [rs.net.places[i].name for i in idx if M[0, i]]
        if marked:
            return float(tr.t[k]), marked
    return None, []


@pytest.mark.parametrize(
    "formula,violations,recorded",
    [
        ("F G kappa & 10 * G !psi", "permanent", 3.0),
        ("F[0,1] kappa & G[0,2] !psi", "counted", None),
        ("kappa U[0,2] psi", "permanent", 0.15),
        ("F kappa & F psi & G (kappa | !psi)", "counted", 3.0),
        ("!psi W[0,2] kappa", "permanent", None),
        ("G[0,1] !psi & F[0,4] kappa", "permanent", None),
    ],
)
def test_check_net_steps_the_table_as_the_runtime_steps_it(tmp_path, formula, violations, recorded):
    from mitlc.cli.check import _net_view
    from mitlc.monitor.trace import read_trace
    from mitlc.spec.parse import load_spec

    rng = np.random.default_rng(7)
    q = np.clip(np.cumsum(rng.normal(0, 0.15, 400)), -3, 3)
    rows = "".join(f"{k * 0.03:.2f},{v:.6f},{rng.normal():.6f}\n" for k, v in enumerate(q))
    (tmp_path / "t.csv").write_text("t,q,qdot\n" + rows)
    spec = tmp_path / "s.mitl"
    spec.write_text(HEAD + f"option violations = {violations}\nformula {formula}\n")
    s = load_spec(str(spec))
    tr, dt = read_trace(str(tmp_path / "t.csv"), ("q", "qdot"), ("q", "qdot"))
    got = _net_view(s, tr, dt)
    assert (got["violation_time"], got["violated"]) == _reference_net_view(s, tr, dt)
    assert got["violation_time"] == recorded


def test_check_net_on_a_million_rows_is_within_a_small_factor_of_check(tmp_path):
    n = 1_000_000
    t = np.arange(n) * 0.03
    table = np.column_stack([t, 3 * np.sin(t * 0.01), np.cos(t)])
    path = tmp_path / "big.csv"
    with open(path, "w") as fh:
        fh.write("t,q,qdot\n")
        np.savetxt(fh, table, delimiter=",", fmt="%.6f")
    start = time.perf_counter()
    plain = run("check", S, str(path))
    plain_s = time.perf_counter() - start
    start = time.perf_counter()
    net = run("check", S, str(path), "--net")
    net_s = time.perf_counter() - start
    assert plain.exit_code == net.exit_code == 1
    assert "  net: violation recorded at t = 10.02 s in p_violated_G_not_psi, p_violated_FG_kappa" in net.stdout
    assert net_s < 4 * plain_s + 5, (plain_s, net_s)  # 235 s before, against 3.7 s


def test_check_net_refuses_a_long_trace_it_would_step_one_sample_at_a_time(tmp_path):
    rows = "".join(f"{k * 0.03:.2f},0.1,0.0\n" for k in range(10_001))
    (tmp_path / "t.csv").write_text("t,q,qdot\n" + rows)
    line = one_error(run("check", "pendulum/n3_bounded_response", str(tmp_path / "t.csv"), "--net"))
    assert line == (
        "--net: error: the spec's net has timed obligations (nested intervals), whose steps grow with the trace's "
        "length: --net steps such a net one sample at a time, at most 10,000 samples, and the trace has 10,001 "
        "(check without --net, or a shorter trace)"
    )


def test_check_net_refuses_a_big_timed_net_it_would_step_for_minutes(tmp_path):
    spec = spec_file(tmp_path, " & ".join(f"G (kappa -> F[0,{i + 1}] psi)" for i in range(120)))
    rows = "".join(f"{k * 0.03:.2f},{3.0 * np.sin(0.05 * k):.6f},0.0\n" for k in range(1000))
    (tmp_path / "t.csv").write_text("t,q,qdot\n" + rows)
    start = time.perf_counter()
    line = one_error(run("check", str(spec), str(tmp_path / "t.csv"), "--net"))
    assert time.perf_counter() - start < 10
    assert line == (
        "--net: error: the spec's net has timed obligations (nested intervals), whose steps grow with the trace's "
        "length: --net steps such a net one sample at a time, at most 580 samples of this net (1,446 transitions, "
        "600 obligation nodes), and the trace has 1,000 (check without --net, or a shorter trace)"
    )


# ---------------------------------------------------------------- Ray


def test_ray_addresses_no_ray_can_answer_at_are_refused_at_once():
    with pytest.raises(InputError, match=r"^--address: error: cannot reach Ray at bogus:1: unknown host 'bogus'"):
        probe_ray_address("bogus:1")
    with pytest.raises(InputError, match=r"not HOST:PORT, ray://HOST:PORT or auto"):
        probe_ray_address("bogus:99999")
    closed = socket.socket()
    closed.bind(("127.0.0.1", 0))
    port = closed.getsockname()[1]
    closed.close()  # a port nobody listens on
    with pytest.raises(
        InputError, match=rf"^--address: error: cannot reach Ray at 127.0.0.1:{port}: connection refused"
    ):
        probe_ray_address(f"127.0.0.1:{port}")


def _server(reply: bytes | None) -> tuple[socket.socket, int]:
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)

    def serve() -> None:
        conn, _ = srv.accept()
        conn.recv(100)
        if reply is not None:
            conn.sendall(reply)
        time.sleep(1.5)
        conn.close()

    threading.Thread(target=serve, daemon=True).start()
    return srv, srv.getsockname()[1]


def test_a_port_that_is_silent_or_not_grpc_is_not_ray():
    srv, port = _server(None)
    with pytest.raises(InputError, match=r"cannot reach Ray at 127.0.0.1:\d+: no answer within 0.5 s$"):
        probe_ray_address(f"127.0.0.1:{port}", timeout=0.5)
    srv.close()
    srv, port = _server(b"HTTP/1.1 400 Bad Request\r\n\r\n")
    with pytest.raises(InputError, match=r"the port answers, but not as Ray does \(gRPC\)$"):
        probe_ray_address(f"ray://127.0.0.1:{port}")
    srv.close()
    srv, port = _server(b"\x00\x00\x18\x04\x00\x00\x00\x00\x00")  # an HTTP/2 SETTINGS frame, as Ray's GCS sends
    probe_ray_address(f"127.0.0.1:{port}")
    srv.close()


def test_sweep_on_a_bogus_ray_address_is_one_line_in_seconds(tmp_path):
    pytest.importorskip("ray")
    start = time.perf_counter()
    r = run(
        "sweep", S, "--backend", "ray", "--address", "bogus:1", "--seeds", "1", "--runs", "1", "--trials", "1",
        "-q", "--out", str(tmp_path / "sw"),
    )  # fmt: skip
    assert time.perf_counter() - start < 20  # endless retry warnings, > 410 s, before
    assert one_error(r).startswith("--address: error: cannot reach Ray at bogus:1: unknown host 'bogus'")


# ---------------------------------------------------------------- plants


def _plant(**kw):
    args = {
        "name": "cart",
        "state": (StateVar("x", -2.0, 2.0), StateVar("v", -3.0, 3.0)),
        "defaults": {"u_max": 2.0, "dt": 0.05},
        "dynamics": lambda x, u, p: x,
    }
    return Plant(**{**args, **kw})


DT, U_MAX = "parameter 'dt' (seconds per step)", "parameter 'u_max' (the input bound, |u| <= u_max)"


@pytest.mark.parametrize(
    "kw,message",
    [
        ({"defaults": {"dt": 0, "u_max": -2}}, f"plant 'cart': {DT} must be a positive number, got 0"),
        ({"defaults": {"dt": 0.1, "u_max": -2}}, f"plant 'cart': {U_MAX} must be 0 or more, got -2"),
        ({"defaults": {"dt": 0.1}}, f"plant 'cart': {U_MAX} is missing from defaults"),
        ({"defaults": {"dt": 0.1, "u_max": 1, "m": float("nan")}}, "plant 'cart': parameter 'm' must be a finite "
         "number, got nan"),
        ({"state": ()}, "plant 'cart': state must be a non-empty sequence of StateVar, got ()"),
        ({"state": (StateVar("x", 0, 1), StateVar("x", 0, 1))}, "plant 'cart': state variable 'x' is given twice"),
        ({"clip": ("y",)}, "plant 'cart': clip names 'y', not among its state ['x', 'v']"),
        ({"dynamics": 3}, "plant 'cart': dynamics must be a function dynamics(x, u, params) -> xdot"),
    ],
)  # fmt: skip
def test_a_plant_that_would_fail_later_is_refused_when_built(kw, message):
    with pytest.raises(ValueError) as err:
        _plant(**kw)
    assert str(err.value) == message


def test_a_state_variable_needs_finite_ordered_bounds():
    with pytest.raises(
        ValueError, match=r"^state variable 'v': its bounds must be finite numbers with lo < hi, got \[0, inf\]$"
    ):
        StateVar("v", 0.0, float("inf"))


PLANT_FILE = """\
import numpy as np
from mitlc.plants import Plant, StateVar


def boom(x, u, p):
    return x / 0 if False else 1 // 0


def flat(x, u, p):
    return x[:, 1]


BOOM = Plant(name="boomcart", state=(StateVar("x", -2.0, 2.0), StateVar("v", -3.0, 3.0)),
             defaults={"u_max": 2.0, "dt": 0.05}, dynamics=boom)
FLAT = Plant(name="flatcart", state=(StateVar("x", -2.0, 2.0), StateVar("v", -3.0, 3.0)),
             defaults={"u_max": 2.0, "dt": 0.05}, dynamics=flat)
"""


@pytest.mark.usefixtures("forget_user_plants")
@pytest.mark.parametrize(
    "plant,line,message",
    [
        ("boomcart", 6, "plant 'boomcart': its dynamics raised ZeroDivisionError: integer division or modulo by zero"),
        # the race's first design meets it: the plain search, its 16 candidates x 4 starts on 1 run
        ("flatcart", 9, "plant 'flatcart': its dynamics returned an array of shape (64,) and dtype float64; expected a "
         "float array of shape (64, 2) (one row per copy, one column per state variable: x, v)"),
    ],
)  # fmt: skip
def test_dynamics_that_raise_or_return_the_wrong_shape_are_one_line_naming_plant_and_file(
    tmp_path, plant, line, message
):
    path = tmp_path / "carts.py"
    path.write_text(PLANT_FILE)
    spec = tmp_path / "c.mitl"
    spec.write_text(
        f"plant {plant}\ninit x in [-0.2, 0.2], v = 0\nhorizon 1\nprop there = abs(x - 1) < 0.5\nformula F there\n"
    )
    r = run("train", "--plant-file", str(path), "--spec", str(spec), "--runs", "2", "--trials", "2", "-q", "--no-plots",
            "--out", str(tmp_path / "out"))  # fmt: skip
    assert one_error(r) == f"{path.resolve()}:{line}: error: {message}"


@pytest.mark.usefixtures("forget_user_plants")
def test_a_plant_file_building_a_bad_plant_is_one_line_naming_it(tmp_path):
    path = tmp_path / "bad.py"
    path.write_text(
        "from mitlc.plants import Plant, StateVar\n"
        "P = Plant(name='c', state=(StateVar('x', -2.0, 2.0),), defaults={'dt': 0, 'u_max': -2}, dynamics=abs)\n"
    )
    line = one_error(run("plants", "--plant-file", str(path)))
    assert line == (
        f"{path.resolve()}:2: error: importing the plant file failed: ValueError: plant 'c': parameter 'dt' "
        "(seconds per step) must be a positive number, got 0"
    )
    path.write_text(
        "from mitlc.plants import Plant, StateVar\n"
        "def make():\n"
        "    return Plant(name='c', state=(StateVar('x', -2.0, 2.0),), defaults={'dt': 1, 'u_max': -2}, dynamics=abs)\n"
    )
    line = one_error(run("plants", "--plant-file", f"{path}:make"))
    assert line.endswith(
        "bad.py:make: error: calling it failed: ValueError: plant 'c': parameter 'u_max' (the input bound, "
        "|u| <= u_max) must be 0 or more, got -2"
    )


# ---------------------------------------------------------------- numpy's warnings


OVERFLOWING_PLANT = """\
import numpy as np
from mitlc.plants import Plant, StateVar


def dynamics(x, u, p):
    damping = 1.0 / (1.0 + np.exp(1000.0 + 0.0 * x[:, 1]))  # exp overflows to inf: no damping, finite
    return np.stack([x[:, 1], u - damping * x[:, 1]], axis=1)


SLED = Plant(name="sled", state=(StateVar("x", -2.0, 2.0), StateVar("v", -3.0, 3.0)),
             defaults={"u_max": 2.0, "dt": 0.05}, dynamics=dynamics)
"""


@pytest.mark.usefixtures("forget_user_plants")
def test_an_overflow_in_training_is_said_once(tmp_path):
    plant = tmp_path / "sled.py"
    plant.write_text(OVERFLOWING_PLANT)
    spec = tmp_path / "sled.mitl"
    spec.write_text("plant sled\ninit x in [-0.2, 0.2], v = 0\nhorizon 1\nprop there = abs(x - 1) < 0.5\n")
    spec.write_text(spec.read_text() + "formula F there\n")
    r = run("train", "--plant-file", str(plant), "--spec", str(spec), "--runs", "2", "--trials", "3", "-q",
            "--no-plots", "--out", str(tmp_path / "o"))  # fmt: skip
    assert r.exit_code == 0, r.output
    assert r.stderr.splitlines() == [  # numpy printed a warning, two lines, at every step before
        "mitlc: warning: numbers left float64's range on the way; what was computed from them rests on inf or nan "
        f"(overflow encountered in exp, at {plant.resolve()}:6)"
    ]


def test_a_time_step_that_overflows_is_one_line(tmp_path):
    r = run("train", "--spec", S, "--runs", "2", "--trials", "3", "-q", "--no-plots", "--set", "dt=1e308",
            "--out", str(tmp_path / "o"))  # fmt: skip
    assert r.exit_code == 2 and "Warning" not in r.stderr
    assert ": error: " in r.stderr.splitlines()[0]


def test_times_of_1e308_are_one_line(tmp_path):
    rows = "".join(f"{-1e308 if k == 0 else 1e308!r},{0.01 * k},0.0\n" for k in range(101))
    (tmp_path / "t.csv").write_text("t,q,qdot\n" + rows)
    line = one_error(run("check", S, str(tmp_path / "t.csv")))  # numpy printed 3 warnings, 6 lines, before it
    assert line.startswith(f"{tmp_path / 't.csv'}:4: error: ")  # the step from -1e308 to 1e308 overflows


def test_a_predicate_whose_value_is_inf_is_arithmetic_not_a_warning(tmp_path, trace):
    spec = tmp_path / "e.mitl"
    spec.write_text("plant pendulum\ninit q in [2.4, pi], qdot = 0\nhorizon 3\nprop big = exp(exp(exp(q))) > 5\n")
    spec.write_text(spec.read_text() + "formula F big\n")
    for args in (["compile", str(spec)], ["check", str(spec), str(trace)], ["check", str(spec), str(trace), "--net"]):
        r = run(*args)
        assert r.exit_code == 0 and r.stderr == "", (args, r.stderr)
    assert "robustness: inf" in run("check", str(spec), str(trace)).stdout  # exp(exp(exp(3))) - 5


def test_checkpoint_parameters_that_are_complex_or_nan_are_named(tmp_path):
    out = tmp_path / "run"
    r = run("train", "--spec", S, "--runs", "2", "--trials", "2", "-q", "--no-plots", "--out", str(out))
    assert r.exit_code == 0, r.output
    ckpt = out / "params.npz"
    good = dict(np.load(ckpt))
    np.savez(ckpt, **{**good, "xi": good["xi"] + 1j})  # numpy's ComplexWarning, then a policy of real parts
    assert one_error(run("simulate", "--policy", str(out))) == (
        f"{ckpt}: error: damaged checkpoint: array 'xi' holds complex128, not real numbers"
    )
    np.savez(ckpt, **{**good, "theta": good["theta"] * np.nan})  # was "<spec>: error: state variable 'q' ..."
    assert one_error(run("simulate", "--policy", str(out))) == (
        f"{ckpt}: error: damaged checkpoint: array 'theta' holds a value that is not a finite number (a checkpoint "
        "keeps each run's last finite parameters)"
    )


# ---------------------------------------------------------------- messages


def test_a_formula_of_constants_judges_the_trace_by_its_length(trace):
    r = run("check", S, str(trace), "--formula", "true", "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["samples"] == 101 and json.loads(r.stdout)["robustness"] is None  # +inf


def test_inline_predicates_work_in_formula(trace):
    r = run("check", S, str(trace), "--formula", "abs(q) < 0.3 U[0,1] (qdot > 1)", "--json")
    assert r.exit_code == 1, r.output
    out = json.loads(r.stdout)
    assert (out["violation_time"], out["failing"]) == (0.09, "(abs(q) < 0.3)")  # q = 0.448 at k = 3
    assert out["robustness"] == pytest.approx(0.15 - 1)  # qdot > 1 by at best 0.15 - 1
    line = one_error(run("check", S, str(trace), "--formula", "F (x > 1)"))
    assert line == "--formula:1:4: error: unknown state variable 'x' (plant 'pendulum' has: q, qdot)"
    line = one_error(run("check", S, str(trace), "--formula", "F (kappa > 1)"))
    assert line == "--formula:1:4: error: 'kappa' is a proposition, not a number: a comparison compares state variables"


def test_a_long_identifier_is_cut_in_the_message(tmp_path):
    spec = tmp_path / "long.mitl"
    spec.write_text(HEAD + "formula F kappa & G " + "a" * 900_000 + "\n")
    r = run("compile", str(spec))
    assert r.exit_code == 2 and len(r.stderr) < 400
    assert r.stderr.splitlines()[0] == f"{spec}:6:21: error: undefined proposition '{'a' * 57}...'"
