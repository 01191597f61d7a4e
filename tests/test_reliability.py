"""The adversarial pass of #16, one reproducer each: bad input is one line and exit 2, limits
are refused before the work, Ctrl-C is exit 130, a killed sweep leaves no workers behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli import main

ROOT = Path(__file__).resolve().parents[1]
P1 = str(ROOT / "specs/pendulum/p1_swing_up.mitl")
P2 = str(ROOT / "specs/pendulum/p2_avoid.mitl")
MITLC = [sys.executable, "-m", "mitlc"]


def one_line_error(result, where: str | None = None) -> str:
    """The result is exit 2 with an error line (and at most its source line, caret and hint)."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output and "Aborted" not in result.output
    first = result.output.strip().splitlines()[0]
    assert ": error: " in first or ": syntax error: " in first, first
    if where is not None:
        assert first.startswith(where), first
    return first


def run(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="mitlc")


def write(tmp_path, name: str, text: str) -> str:
    p = tmp_path / name
    p.write_text(text)
    return str(p)


HEAD = "plant pendulum\nprop kappa = abs(q) < 0.3\nformula F G kappa\n"


@pytest.mark.parametrize(
    "text, message",
    [
        ("plant pendulum\nhorizon " + "+".join(["0.001"] * 1000) + "\nprop k = q < 1\nformula F k\n", "too long"),
        ("plant pendulum\ninit q in [0, " + "+".join(["1"] * 1000) + "]\nprop k = q < 1\nformula F k\n", "too long"),
        ("plant pendulum\nhorizon 1e308\nprop k = q < 1\nformula F k\n", "longest supported"),
        ("plant pendulum\nhorizon 3\ninit qdot in [-1e308, 1e308]\n" + HEAD.split("\n", 1)[1], "its width too"),
        ("plant pendulum\nprop psi = q > 1\nformula 1e200 * 1e200 * G !psi\n", "weights multiply"),
        ("plant pendulum(u_max = 1, u_max = 2)\n" + HEAD.split("\n", 1)[1], "'u_max' given twice"),
        ("plant pendulum\nhorizon 3\nhorizon 4\n" + HEAD.split("\n", 1)[1], "'horizon' given twice"),
    ],
)
def test_specs_that_used_to_crash_are_one_located_line(tmp_path, text, message):
    spec = write(tmp_path, "s.mitl", text)
    first = one_line_error(run("compile", spec), f"{spec}:")
    assert message in first
    assert first.split(":")[1].isdigit()  # a line number, not <spec> or line 1 by default
    ctx = run("compile", spec).output.splitlines()[1]
    assert len(ctx) < 120  # the source line is cut around the column, not printed whole


def test_a_check_line_far_in_the_future_does_not_crash_after_training(tmp_path):
    spec = write(tmp_path, "s.mitl", "plant pendulum\nhorizon 3\nprop k = q < 1\nformula F k\ncheck G[1e308,inf) k\n")
    r = run("train", "--spec", spec, "--runs", "1", "--trials", "1", "-q", "--out", str(tmp_path / "o"))
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "o" / "metrics.json").read_text())["satisfied"] == [True]  # no sample reaches it


def test_traces_and_formulas_with_extreme_times(tmp_path):
    tiny = write(tmp_path, "t.csv", "t,q,qdot\n0,0,0\n5e-324,0.1,0\n")
    assert "smallest supported" in one_line_error(run("check", P1, tiny), f"{tiny}:")
    ok = write(tmp_path, "ok.csv", "t,q,qdot\n0,0,0\n0.03,0.1,0\n")
    r = run("check", P1, ok, "--formula", "G[1e308,1e308] kappa", "--json")
    assert r.exit_code == 0 and json.loads(r.output)["satisfied"] is True
    r = run("check", P1, ok, "--formula", "F[1e308,1e308] kappa", "--json")
    assert r.exit_code == 1 and json.loads(r.output)["satisfied"] is False


@pytest.mark.parametrize(
    "args, where, message",
    [
        (["train", "--spec", P2, "--seed", "-1"], "--seed:", "-1 is not in the range"),
        (["simulate", "--policy", ".", "--seed", "-1"], "--seed:", "-1 is not in the range"),
        (["train", "--spec", P2, "--set", "rbf_width=0"], "--set:", "rbf_width must be a number in [0.02, 1000]"),
        (["train", "--spec", P2, "--set", "rbf=100000x100000"], "--set:", "more than the 100,000 supported"),
        (["train", "--spec", P2, "--set", "feature_bounds=qdot:3:-3"], "--set:", "lo < hi"),
        (["train", "--spec", P2, "--set", "feature_bounds=zz:-1:1"], P2, "does not have"),
        (["train", "--spec", P2, "--set", "dt=1e-9"], P2, "more than the 1,000,000 supported"),
        (["train", "--spec", P2, "--set", "trial_s=1e12"], "--set:", "trial_s must be a number in [1e-09, 1e+09]"),
        (["train", "--spec", P2, "--runs", "10000", "--set", "rbf=300x300"], P2, "GiB of learner arrays"),
        (["sweep", P2, "--grid", "rbf_width=0,1", "--seeds", "1"], "--grid:", "rbf_width must be a number in"),
        (["compile", "/dev/zero"], "/dev/zero:", "not a regular file"),
        (["compile", str(ROOT)], "SPEC:", "is a directory"),
        (["compile"], "SPEC:", "Missing argument"),
        (["compile", P2, "--bogus"], "mitlc compile:", "No such option"),
    ],
)
def test_options_that_used_to_crash_or_hang_are_one_line(tmp_path, args, where, message):
    if args[0] in ("train", "sweep"):
        args = [*args, "--out", str(tmp_path / "o")] + (["-q"] if args[0] == "train" else [])
    first = one_line_error(run(*args), where)
    assert message in first
    assert "<spec>" not in first


def test_a_fifo_as_spec_is_refused_without_waiting(tmp_path):
    fifo = tmp_path / "spec.mitl"
    os.mkfifo(fifo)
    start = time.perf_counter()
    one_line_error(run("compile", str(fifo)), f"{fifo}:")
    assert time.perf_counter() - start < 5


def test_a_spec_larger_than_the_limit_is_refused(tmp_path):
    big = write(tmp_path, "big.mitl", HEAD + "# " + "x" * (1 << 20) + "\n")
    assert "larger than 1024 KiB" in one_line_error(run("compile", big), f"{big}:")


def _checkpoint(tmp_path) -> Path:
    out = tmp_path / "good"
    assert run("train", "--spec", P2, "--runs", "2", "--trials", "2", "-q", "--out", str(out)).exit_code == 0
    return out


def test_damaged_checkpoints_are_one_line(tmp_path):
    good = _checkpoint(tmp_path) / "params.npz"
    cases = {}
    cases["truncated"] = good.read_bytes()[:3000]
    np.save(tmp_path / "arr.npy", np.arange(3))
    cases["npy"] = (tmp_path / "arr.npy").read_bytes()
    d = dict(np.load(good))
    meta = json.loads(str(d["meta"]))
    for name, m in (("empty", {}), ("types", {**meta, "runs": "two"}), ("settings", {**meta, "settings": 5})):
        import io

        buf = io.BytesIO()
        np.savez(buf, **{**d, "meta": np.array(json.dumps(m))})
        cases[name] = buf.getvalue()
    for name, data in cases.items():
        folder = tmp_path / name
        folder.mkdir()
        (folder / "params.npz").write_bytes(data)
        ckpt = str(folder / "params.npz")
        one_line_error(run("simulate", "--policy", str(folder)), f"{ckpt}:")
        one_line_error(run("train", "--resume", str(folder), "--trials", "3", "-q"), f"{ckpt}:")
        from mitlc import load_policy
        from mitlc.errors import InputError

        with pytest.raises(InputError):
            load_policy(folder)


def test_a_sweep_record_without_task_is_one_line(tmp_path):
    out = tmp_path / "sw"
    r = run("sweep", P2, "--grid", "sigma=1", "--seeds", "1", "--runs", "1", "--trials", "1", "--out", str(out))
    assert r.exit_code == 0, r.output
    data = json.loads((out / "results.json").read_text())
    del data["results"][0]["task"]
    (out / "results.json").write_text(json.dumps(data))
    r = run("sweep", P2, "--grid", "sigma=1", "--seeds", "1", "--runs", "1", "--trials", "1", "--out", str(out))
    assert "has no 'task' key" in one_line_error(r, f"{out / 'results.json'}:")


def test_strict_json_everywhere(tmp_path):
    spec = write(tmp_path, "s.mitl", "plant pendulum\nhorizon 3\nprop a = q < 1\nformula F[0,1] G[1,inf) a\n")
    for text in (
        run("compile", spec, "--format", "json").output,
        run("automaton", "mass_damper/overshoot", "--format", "json").output,
    ):
        json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    ok = write(tmp_path, "ok.csv", "t,q,qdot\n0,0,0\n0.03,0.1,0\n")
    r = run("check", spec, ok, "--json", "--formula", "G[5,6] a")  # robustness +inf: no sample decides it
    assert json.loads(r.output, parse_constant=lambda c: pytest.fail(c))["robustness"] is None


def test_bom_form_feed_and_flat_chains(tmp_path):
    bom = tmp_path / "bom.mitl"
    bom.write_bytes(b"\xef\xbb\xbf" + HEAD.encode())
    assert run("compile", str(bom)).exit_code == 0
    csv = tmp_path / "bom.csv"
    csv.write_bytes(b"\xef\xbb\xbft,q,qdot\n0,0,0\n0.03,0.1,0\n")
    assert run("check", P1, str(csv)).exit_code == 0
    ff = write(tmp_path, "ff.mitl", "plant pendulum\n\x0cprop k = q < 1\nformula F kk\n")
    lines = run("compile", ff).output.splitlines()
    assert lines[0].startswith(f"{ff}:3:11:") and lines[1].strip() == "formula F kk"  # the caret's own line
    flat = write(tmp_path, "flat.mitl", "plant pendulum\nprop a = q < 1\nformula " + " & ".join(["F a"] * 65) + "\n")
    assert run("compile", flat).exit_code == 0  # 65 operands of one & are one level, not 65
    deep = write(tmp_path, "deep.mitl", "plant pendulum\nprop a = q < 1\nformula " + "!" * 65 + "a\n")
    assert "nesting too deep (more than 64 levels)" in one_line_error(run("compile", deep))


def _default_sigint() -> None:
    """A child as a shell starts it: Ctrl-C not ignored, whatever this test process inherited or set."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupted_training(tmp_path, delay: float) -> tuple[int, str]:
    """A long ``mitlc train`` sent SIGINT after ``delay`` seconds: its status and stderr."""
    proc = subprocess.Popen(
        [*MITLC, "train", "--spec", P2, "--runs", "2", "--trials", "100000", "-q", "--out", str(tmp_path / "o")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_default_sigint,
    )
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    return proc.returncode, err


@pytest.fixture(scope="module")
def cli_import_s() -> float:
    """How long this machine, as loaded as it is now, takes to import the command line: a
    SIGINT before that lands in Python's own start-up, which mitlc cannot handle."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import mitlc.cli"], check=True)
    return time.perf_counter() - t0


def test_ctrl_c_at_start_up_is_exit_130(tmp_path, cli_import_s):
    # after loading the command line and compiling the spec
    status, err = _interrupted_training(tmp_path, max(0.4, 1.2 * cli_import_s))
    assert status == 130, err
    assert "Traceback" not in err and "Aborted" not in err


@pytest.mark.parametrize("after", [0.0, 0.15, 0.35, 0.6, 1.0])
def test_ctrl_c_at_any_moment_of_start_up_is_exit_130(tmp_path, after, cli_import_s):
    """While modules load, a SIGINT may land in a weakref callback (Python drops it) or in a
    dataclass's exec() (CPython then exits by SIGINT, status -2, though mitlc handled it):
    either way the status is 130 and the training does not run on."""
    status, err = _interrupted_training(tmp_path, 1.2 * cli_import_s + after)
    assert status == 130, err
    assert "Traceback" not in err and "interrupted" in err


def test_a_swallowed_interrupt_is_raised_again() -> None:
    """The handler remembers the signal; the trainers' callbacks check it."""
    from mitlc.cli import interrupt

    before, was = signal.getsignal(signal.SIGINT), interrupt._seen
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)  # as a program starts
        interrupt.install()
        assert signal.getsignal(signal.SIGINT) is interrupt._handler
        interrupt._seen = False
        interrupt.check()  # nothing pending: no raise
        with pytest.raises(KeyboardInterrupt):
            interrupt._handler(signal.SIGINT, None)
        assert interrupt.pending()
        with pytest.raises(KeyboardInterrupt):  # as if the first raise had been dropped
            interrupt.check()
    finally:
        interrupt._seen = was
        signal.signal(signal.SIGINT, before)


def test_ctrl_c_while_writing_keeps_a_checkpoint_to_resume(tmp_path, monkeypatch):
    import mitlc.cli.outputs as outputs

    real = outputs.OutputSet._write_into

    def interrupted(self, out, payload, order, info):
        from mitlc.fileio import atomic_write

        atomic_write(out / "params.npz", payload["params.npz"])
        raise KeyboardInterrupt

    monkeypatch.setattr(outputs.OutputSet, "_write_into", interrupted)
    out = tmp_path / "o"
    r = run("train", "--spec", P2, "--runs", "2", "--trials", "3", "-q", "--out", str(out))
    assert r.exit_code == 130 and f"continue with: mitlc train --resume {out} --trials 3" in r.output
    monkeypatch.setattr(outputs.OutputSet, "_write_into", real)
    assert run("train", "--resume", str(out), "--trials", "4", "-q").exit_code == 0
    assert json.loads((out / "metrics.json").read_text())["trials"] == 4


def test_a_killed_sweep_leaves_no_workers(tmp_path):
    proc = subprocess.Popen(
        [*MITLC, "sweep", P2, "--grid", "sigma=1,2", "--seeds", "2", "--runs", "4", "--trials", "100000"]
        + ["--workers", "2", "--out", str(tmp_path / "sw")],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    kids: list[int] = []
    deadline = time.time() + 60
    while time.time() < deadline and len(kids) < 2:  # the workers (and the resource tracker) are up
        time.sleep(0.5)
        kids = [int(p) for p in _children(proc.pid)]
    assert len(kids) >= 2
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    deadline = time.time() + 20
    while time.time() < deadline and any(_alive(k) for k in kids):
        time.sleep(0.2)
    assert not any(_alive(k) for k in kids)


def _children(pid: int) -> list[str]:
    try:
        return Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return []


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"
