"""Golden outputs of the CLI: what must not change when the code is only moved.

``python tests/golden.py`` (re)writes ``tests/fixtures/golden/``; ``tests/test_golden.py``
runs the same commands and compares. Regenerate only for a change that is meant to alter
these outputs, and say so in the commit.

Each case is a ``mitlc`` command line; ``{out}`` is a fresh folder. A case keeps the
command's standard output (compile, automaton), or the ``metrics.json`` (less its wall
time) and ``params.npz`` a training writes.
"""

from __future__ import annotations

import io
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from click.testing import CliRunner

ROOT = Path(__file__).resolve().parent.parent
GOLDEN = ROOT / "tests" / "fixtures" / "golden"

PENDULUM = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "specs" / "pendulum").rglob("*.mitl"))
MASS_DAMPER = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "specs" / "mass_damper").glob("*.mitl"))

CASES: dict[str, list[str]] = {}
for _spec in PENDULUM:
    _name = _spec.removeprefix("specs/").removesuffix(".mitl").replace("/", "-")
    CASES[f"compile-{_name}"] = ["compile", _spec, "--format", "json"]
    CASES[f"compile-{_name}-permanent"] = ["compile", _spec, "--format", "json", "--violations", "permanent"]
CASES["compile-p4-active-counted"] = [
    "compile",
    "specs/pendulum/p4_alternate.mitl",
    "--format",
    "json",
    "--conjunction",
    "active",
    "--violations",
    "counted",
]
for _spec in MASS_DAMPER:
    _name = _spec.removeprefix("specs/").removesuffix(".mitl").replace("/", "-")
    CASES[f"automaton-{_name}"] = ["automaton", _spec, "--format", "json"]
CASES["train-p1"] = [
    "train",
    "--spec",
    "specs/pendulum/p1_swing_up.mitl",
    "--learner",  # SACPN's numbers: the race of its designs, not the policy search's
    "sacpn",
    "--runs",
    "3",
    "--trials",
    "150",
    "--seed",
    "0",
    "--out",
    "{out}",
]
CASES["train-p2-unit-permanent"] = [
    "train",
    "--spec",
    "specs/pendulum/unit_weights/p2_avoid.mitl",
    "--learner",  # SACPN's numbers: the race of its designs, not the policy search's
    "sacpn",
    "--violations",
    "permanent",
    "--runs",
    "2",
    "--trials",
    "100",
    "--seed",
    "1",
    "--out",
    "{out}",
]
CASES["train-hyrl-overshoot"] = [
    "train",
    "--plant",
    "mass-damper",
    "--spec",
    "specs/mass_damper/overshoot.mitl",
    "--runs",
    "2",
    "--trials",
    "30",
    "--seed",
    "0",
    "--out",
    "{out}",
]

# Fields of metrics.json that measure the machine, not the result.
VOLATILE = {"wall_s"}

# Seeded trainings are chaotic in the last bit of every sin and exp, and numpy picks its
# vector code for those by CPU: AVX-512 machines (with Intel's SVML) round differently from
# AVX2 ones, and 150 trials turn a last-bit difference into another controller. Trainings
# therefore run in a process of their own with numpy held to its x86-64-v2 baseline code,
# which every x86-64 machine runs alike (on this AMD EPYC the baseline and the AVX2 code
# gave the same trainings to the bit), and one BLAS thread.
PORTABLE = {"NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR", "OPENBLAS_NUM_THREADS": "1"}


def run_case(args: list[str]) -> dict[str, object]:
    """Run one case from the repository root (a training in a portable process: PORTABLE); what it produced."""
    import os

    from mitlc.cli import main

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        argv = [a.replace("{out}", str(out)) for a in args]
        if "{out}" not in args:
            cwd = os.getcwd()
            os.chdir(ROOT)
            try:
                res = CliRunner().invoke(main, argv, catch_exceptions=False)
            finally:
                os.chdir(cwd)
            if res.exit_code != 0:
                raise RuntimeError(f"mitlc {' '.join(argv)} exited {res.exit_code}: {res.output}")
            return {"stdout": res.stdout}
        env = {**os.environ, **PORTABLE, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
        run = subprocess.run(
            [sys.executable, "-m", "mitlc", *argv], cwd=ROOT, env=env, capture_output=True, text=True, check=False
        )
        if run.returncode != 0:
            raise RuntimeError(f"mitlc {' '.join(argv)} exited {run.returncode}: {run.stdout}{run.stderr}")
        metrics = json.loads((out / "metrics.json").read_text())
        for k in VOLATILE:
            metrics.pop(k, None)
        for design in (metrics.get("race") or {}).get("designs", ()):  # each raced design's time
            for k in VOLATILE:
                design.pop(k, None)
        with np.load(out / "params.npz") as z:
            params = {k: z[k] for k in z.files}
        if "meta" in params:  # the checkpoint's record, less its wall time
            meta = json.loads(str(params["meta"]))
            params["meta"] = np.array(json.dumps({k: v for k, v in meta.items() if k not in VOLATILE}))
        return {"metrics": metrics, "params": params}


def write(name: str, got: dict[str, object]) -> None:
    if "stdout" in got:
        (GOLDEN / f"{name}.out").write_text(str(got["stdout"]))
        return
    (GOLDEN / f"{name}.metrics.json").write_text(json.dumps(got["metrics"], indent=1, sort_keys=True) + "\n")
    buf = io.BytesIO()
    np.savez_compressed(buf, **got["params"])  # type: ignore[arg-type]
    (GOLDEN / f"{name}.params.npz").write_bytes(buf.getvalue())


def main() -> None:
    GOLDEN.mkdir(parents=True, exist_ok=True)
    names = sys.argv[1:] or list(CASES)
    for name in names:
        write(name, run_case(CASES[name]))
        print(name)


if __name__ == "__main__":
    main()
