"""Progress on stderr (mitlc.cli.progress): a bar on a terminal, a few plain lines in a log,
and one line when the training kernel is compiled rather than loaded from the cache."""

from __future__ import annotations

import io
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from mitlc.cli import main
from mitlc.cli.progress import Progress, compile_notice
from mitlc.learn import jitcache

ROOT = Path(__file__).resolve().parent.parent
MITLC = [sys.executable, "-m", "mitlc"]
COMPILING = "compiling the training kernel"
LINE = re.compile(r"^p2_short: trial (\d+)/40 \((\d+)%\), mean return -?\d+\.\d, elapsed \d\d:\d\d(, ETA \d\d:\d\d)?$")


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _lines(total: int, initial: int = 0, quiet: bool = False) -> list[str]:
    out = io.StringIO()
    p = Progress(total, initial, desc="d", quiet=quiet, stream=out)
    for _ in range(total - initial):
        p.update("mean return 1.0")
    p.close()
    return out.getvalue().splitlines()


@pytest.mark.parametrize(
    "total, initial, shown",
    [
        (40, 0, list(range(2, 41, 2))),  # one line per 5 %: every 2 trials
        (500, 0, list(range(25, 501, 25))),
        (7, 0, list(range(1, 8))),  # fewer trials than 20: one line each
        (500, 250, list(range(275, 501, 25))),  # resumed at half: the second half's 10 lines
        (
            30,
            0,
            [2, 3, 5, 6, 8, 9, 11, 12, 14, 15, 17, 18, 20, 21, 23, 24, 26, 27, 29, 30],
        ),  # floor(20 n / 30) steps up
    ],
)
def test_a_log_gets_one_plain_line_per_5_percent(total, initial, shown):
    lines = _lines(total, initial)
    assert [int(re.match(r"d: trial (\d+)/", line).group(1)) for line in lines] == shown
    assert all(f"/{total} (" in line and ", mean return 1.0, elapsed " in line for line in lines)
    assert lines[-1].startswith(f"d: trial {total}/{total} (100%), mean return 1.0, elapsed 00:00, ETA 00:00")


def test_the_first_plain_line_has_no_eta_when_it_is_the_first_step():
    lines = _lines(7)
    assert "ETA" not in lines[0] and lines[1].endswith("ETA 00:00")


def test_steps_added_on_the_way_extend_the_count_and_its_percentages():
    # a search's restarts: 40 generations planned, 20 more once the first search is judged
    out = io.StringIO()
    p = Progress(40, desc="d", unit="generation", stream=out)
    for _ in range(40):
        p.update()
    p.extend(20)
    for g in range(20):
        p.update(f"restarts: generation {g + 1}/20")
    p.close()
    lines = out.getvalue().splitlines()
    counts = [re.match(r"d: generation (\d+)/(\d+) \((\d+)%\)", line).groups() for line in lines]
    assert counts[19] == ("40", "40", "100") and counts[20] == ("42", "60", "70")
    assert counts[-1] == ("60", "60", "100") and lines[-1].endswith("ETA 00:00")
    assert len(lines) == 20 + 7  # one line a 5 % of 60 from 70 % on: 42, 45, ..., 60
    assert all(int(n) <= int(total) for n, total, _ in counts)


def test_quiet_and_no_trials_write_nothing():
    assert _lines(40, quiet=True) == []
    assert _lines(0) == []
    term = Terminal()
    p = Progress(40, desc="d", quiet=True, stream=term)
    p.update()
    p.close()
    assert term.getvalue() == ""


def test_a_terminal_bar_shows_no_eta_before_the_first_step_and_a_rate_without_it_after():
    term = Terminal()
    p = Progress(40, desc="d", stream=term)
    before = term.getvalue()
    assert "0/40 [00:00]" in before and "<" not in before and "trial/s" not in before
    time.sleep(1.0)  # a first trial that compiles the kernel
    p.update("mean return 1.0")
    for _ in range(9):
        time.sleep(0.01)
        p.update("mean return 1.0")
    d = p._bar.format_dict
    # the rate of the 9 steps after the first (about 100/s, tqdm's average over all 10 was about 9/s)
    assert d["rate"] is not None and d["rate"] > 20
    assert d["elapsed"] >= 1.0  # the elapsed time still counts the first step
    p.close()
    last = [frame for frame in term.getvalue().replace("\r", "\n").splitlines() if frame.strip()][-1]
    assert re.search(r" 10/40 \[00:0[12]<00:0\d, +\d+\.\d+trial/s, mean return 1\.0\]", last), last


def test_compile_notice_is_set_while_inside_and_not_when_quiet():
    assert jitcache.set_notice(None) is None
    with compile_notice():
        assert jitcache._NOTICE is not None
    assert jitcache._NOTICE is None
    with compile_notice(quiet=True):
        assert jitcache._NOTICE is None


def test_will_compile_is_false_for_plain_python_and_compiled_dispatchers():
    numba = pytest.importorskip("numba")

    def plain(x):
        return x + 1

    assert not jitcache.will_compile(plain)
    fn = numba.njit(plain)
    assert jitcache.will_compile(fn)  # in memory, not compiled yet
    told: list[str] = []
    before = jitcache.set_notice(told.append)
    try:
        jitcache.announce(fn)
        fn(1)
        jitcache.announce(fn)  # compiled now: nothing more
    finally:
        jitcache.set_notice(before)
    assert not jitcache.will_compile(fn)
    assert len(told) == 1 and told[0].startswith(COMPILING)


def _train(spec: Path, out: Path, err: Path, *args: str, cache: str | None = None) -> str:
    env = dict(os.environ)
    if cache is not None:
        env["MITLC_CACHE_DIR"] = cache
    with err.open("w") as fh:  # a file: stderr is not a terminal
        proc = subprocess.run(
            [*MITLC, "train", "--spec", str(spec), "--runs", "2", "--no-plots", "--out", str(out), *args],
            stdout=subprocess.PIPE,
            stderr=fh,
            text=True,
            env=env,
            timeout=300,
        )
    assert proc.returncode == 0, err.read_text()
    return proc.stdout


def test_a_training_logged_to_a_file_writes_20_plain_lines_and_no_frames(short_spec, tmp_path):
    err = tmp_path / "log"
    # SACPN's race (the policy search's designs race too by default: tests/test_search.py)
    stdout = _train(short_spec, tmp_path / "o", err, "--trials", "40", "--learner", "sacpn")
    assert stdout.startswith("2 runs x 40 trials in ")
    data = err.read_bytes()
    assert b"\r" not in data
    lines = data.decode().splitlines()
    race = [line for line in lines if ": race " in line or line.startswith("race (")]
    progress = [line for line in lines if not line.startswith(COMPILING) and line not in race]
    assert len(lines) - len(progress) - len(race) <= 1  # the compile line, where this session had not compiled it yet
    # the race: a line as each of the 5 designs starts, then the result
    starts = ["1/5 (20%)", "2/5 (40%)", "3/5 (60%)", "4/5 (80%)", "5/5 (100%"]
    assert [line.split(": race ")[1][:9] for line in race[:5]] == starts
    assert race[5].startswith("race (1 runs x 20 trials each, success by the monitor): ") and " won" in race[5]
    assert [int(LINE.match(line).group(1)) for line in progress] == list(range(2, 41, 2))
    assert all(", ETA " in line for line in progress)
    assert len(data) < 2500  # was 78 KB of frames for a 500-trial training


def test_the_compile_line_comes_once_per_cache(short_spec, tmp_path):
    pytest.importorskip("numba")
    cache = str(tmp_path / "cache")
    err = tmp_path / "log"
    # SACPN's kernel is compiled (the default race may choose the search, which compiles none)
    _train(short_spec, tmp_path / "o", err, "--trials", "2", "--learner", "sacpn", cache=cache)
    told = [line for line in err.read_text().splitlines() if line.startswith(COMPILING)]
    assert len(told) == 1 and "cached in" in told[0] and str(Path(cache, "kernels")) in told[0]
    _train(short_spec, tmp_path / "o2", err, "--trials", "2", "--learner", "sacpn", cache=cache)
    text = err.read_text()
    assert COMPILING not in text and "p2_short: trial 2/2 (100%)" in text


def test_quiet_training_writes_only_the_final_line(short_spec, tmp_path):
    res = CliRunner().invoke(
        main,
        [
            "train",
            "--spec",
            str(short_spec),
            "--runs",
            "2",
            "--trials",
            "40",
            "--learner",
            "sacpn",
            "-q",
            "--no-plots",
            "--out",
            str(tmp_path / "o"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert res.stderr == ""
    assert res.stdout.count("\n") == 1 and res.stdout.startswith("2 runs x 40 trials in ")


def test_a_hyrl_training_logs_plain_lines(tmp_path):
    res = CliRunner().invoke(
        main,
        [
            "train",
            "--spec",
            str(ROOT / "specs/mass_damper/settling_time.mitl"),
            "--runs",
            "1",
            "--trials",
            "20",
            "--no-plots",
            "--out",
            str(tmp_path / "o"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "\r" not in res.stderr
    shown = [
        int(m.group(1)) for m in re.finditer(r"^settling_time: trial (\d+)/20 \(\d+%\), mean return ", res.stderr, re.M)
    ]
    assert shown == list(range(1, 21))


def test_a_sweep_logs_one_plain_line_per_task(short_spec, tmp_path):
    res = CliRunner().invoke(
        main,
        ["sweep", str(short_spec), "--grid", "sigma=1,3", "--runs", "1", "--trials", "2"]
        + ["--seeds", "1", "--workers", "1", "--no-plot", "--out", str(tmp_path / "o")],
    )
    assert res.exit_code == 0, res.output
    assert "\r" not in res.stderr
    lines = [line for line in res.stderr.splitlines() if line.startswith("p2_short: task")]
    assert [line.split(",")[0] for line in lines] == ["p2_short: task 1/2 (50%)", "p2_short: task 2/2 (100%)"]
    assert re.match(r"p2_short: task 1/2 \(50%\), sigma=[13] seed 0: success \d\.\d\d, elapsed \d\d:\d\d$", lines[0])
    assert lines[1].endswith(", ETA 00:00")
