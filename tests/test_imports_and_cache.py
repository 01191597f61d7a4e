"""A spec never causes an import, and the disk cache is not code (issue 29, items 1 and 5).

* ``plant gym:MODULE:ID`` made Gymnasium import MODULE (``gym:this:Foo-v0`` printed the Zen of
  Python; an ``evilmod.py`` in the current folder ran under ``python -m mitlc``), from a spec file
  or from a checkpoint's ``meta.spec_source``. Now refused at parse time, one located line, exit 2;
  modules are imported only from ``--gym-module`` (and ``--plant-file``, entry points).
* The parser's tables were a pickle in the cache folder, loaded on every command: now JSON data,
  and read (like numba's kernel cache) only from files and folders that are the user's own.
* CR-only line ends read as one line.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mitlc.cli.main import main
from mitlc.plants import gym_env as G

ROOT = Path(__file__).resolve().parents[1]
SPECS = ROOT / "specs"

EVIL = """\
from pathlib import Path
Path({marker!r}).write_text("imported")
"""

# A tiny Gymnasium environment of the user's, registered when its module is imported.
MYENVS = """\
from pathlib import Path

import gymnasium as gym
import numpy as np

Path({marker!r}).write_text("imported")


class Drift(gym.Env):
    metadata = {{"render_modes": []}}
    dt = 0.1

    def __init__(self):
        self.observation_space = gym.spaces.Box(-5.0, 5.0, (1,), dtype=np.float64)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (1,), dtype=np.float64)
        self.x = 0.0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.x = float(self.np_random.uniform(-1.0, 1.0))
        return np.array([self.x]), {{}}

    def step(self, action):
        self.x = float(np.clip(self.x + self.dt * float(np.asarray(action).reshape(-1)[0]), -5.0, 5.0))
        return np.array([self.x]), 0.0, False, False, {{}}


gym.register(id="MyDrift-v0", entry_point=Drift)
"""

DRIFT_SPEC = """\
plant gym:MyDrift-v0
state x = obs[0]
horizon 1
prop near = abs(x) < 0.5
formula F near
"""


@pytest.fixture(autouse=True)
def _forget_gym_modules():
    before = list(G.GYM_MODULES)
    yield
    G.GYM_MODULES[:] = before


def _python(args: list[str], cwd: Path, extra_path: Path | None = None, **env: str) -> subprocess.CompletedProcess:
    """``python -m mitlc ARGS`` in ``cwd`` (which Python then puts first on sys.path)."""
    paths = [str(p) for p in (extra_path, ROOT) if p is not None]
    full = {**os.environ, "PYTHONPATH": os.pathsep.join(paths), **env}
    return subprocess.run(
        [sys.executable, "-m", "mitlc", *args], cwd=cwd, env=full, capture_output=True, text=True, timeout=300
    )


def _error_lines(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if ": error:" in ln]


# ---------------------------------------------------------------- a spec never causes an import


def test_the_zen_of_python_is_not_printed(tmp_path: Path) -> None:
    (tmp_path / "g.mitl").write_text("plant gym:this:Foo-v0\nformula F true\n")
    r = _python(["compile", "g.mitl"], tmp_path)
    assert r.returncode == 2
    assert "Zen of Python" not in r.stdout + r.stderr and r.stdout == ""
    lines = r.stderr.splitlines()
    assert lines[0] == (
        "g.mitl:1:7: error: 'gym:this:Foo-v0' would import the module 'this': a spec names registered Gymnasium "
        "ids only, and never causes an import; write 'plant gym:Foo-v0' and pass --gym-module this to register "
        "the module's environments"
    )
    assert lines[1:] == ["  plant gym:this:Foo-v0", "        ^"]


def test_a_module_in_the_current_folder_is_not_imported(tmp_path: Path) -> None:
    marker = tmp_path / "evil-ran"
    (tmp_path / "evilmod.py").write_text(EVIL.format(marker=str(marker)))
    (tmp_path / "g.mitl").write_text("# harmless?\nplant gym:evilmod:Foo-v0\nformula F true\n")
    commands = (
        ["compile", "g.mitl"],
        ["check", "g.mitl", "t.csv", "--formula", "true"],
        ["train", "--spec", "g.mitl", "--runs", "1", "--trials", "1", "-q"],
    )
    for args in commands:
        r = _python(args, tmp_path)
        assert r.returncode == 2, (args, r.stderr)
        assert not marker.exists(), args
        assert "Traceback" not in r.stderr
    r = _python(["compile", "g.mitl"], tmp_path)
    assert _error_lines(r.stderr) == [
        "g.mitl:2:7: error: 'gym:evilmod:Foo-v0' would import the module 'evilmod': a spec names registered "
        "Gymnasium ids only, and never causes an import; write 'plant gym:Foo-v0' and pass --gym-module evilmod "
        "to register the module's environments"
    ]


def test_an_unknown_module_is_the_same_refusal_not_a_traceback(tmp_path: Path) -> None:
    spec = tmp_path / "h.mitl"
    spec.write_text("plant gym:nonexistent_mod:Foo-v0\nformula F true\n")
    r = CliRunner().invoke(main, ["compile", str(spec)])
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert _error_lines(r.output) == [
        f"{spec}:1:7: error: 'gym:nonexistent_mod:Foo-v0' would import the module 'nonexistent_mod': a spec names "
        "registered Gymnasium ids only, and never causes an import; write 'plant gym:Foo-v0' and pass --gym-module "
        "nonexistent_mod to register the module's environments"
    ]


@pytest.mark.parametrize(
    "env_id, says",
    [
        ("this:Foo-v0", "would import the module 'this'"),
        ("a.b:Foo", "would import the module 'a.b'"),
        (":Foo-v0", "':' would name a module to import"),
        ("a:b:c", "':' would name a module to import"),
        ("Foo-v0:", "':' would name a module to import"),
        ("x" * 300, "longer than 200 characters"),
    ],
)
def test_no_path_passes_a_module_id_to_gymnasium(env_id: str, says: str) -> None:
    """open_env (gymnasium.make) and GymSimulator (gymnasium.make_vec) refuse such an id themselves."""
    from mitlc.errors import InputError

    with pytest.raises(InputError) as err:
        G.check_env_id(env_id)
    assert says in err.value.message and len(err.value.message) < 400
    with pytest.raises(InputError):
        G.open_env(env_id)
    with pytest.raises(InputError):
        G.GymSimulator(env_id, {}, (), {}, 1.0)
    assert G.check_env_id("ALE/Pong-v5") == "ALE/Pong-v5"


def _checkpoint(folder: Path, spec_source: str, plant: dict | None = None) -> Path:
    """A real one-run checkpoint of a one-variable spec whose meta is then made to carry
    ``spec_source`` (and ``plant``): everything else about it is whole."""
    from mitlc.learn.sacpn import Sacpn
    from mitlc.petri.compile import compile_spec
    from mitlc.spec.parse import parse_spec

    folder.mkdir()
    spec = parse_spec("plant mass-damper\ninit q = 0.5, qdot = 0\nhorizon 0.3\nprop a = q < 1\nformula F a\n")
    agent = Sacpn(compile_spec(spec), runs=1, seed=0)
    agent.train(1)
    agent.save(folder / "params.npz")
    with np.load(folder / "params.npz") as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta"]))
    meta.update(spec_source=spec_source, spec_path="g.mitl")
    if plant is not None:
        meta["plant"] = plant
    arrays["meta"] = np.array(json.dumps(meta))
    np.savez(folder / "params.npz", **arrays)
    return folder


def test_a_checkpoint_spec_never_imports(tmp_path: Path) -> None:
    marker = tmp_path / "evil-ran"
    (tmp_path / "evilmod.py").write_text(EVIL.format(marker=str(marker)))
    _checkpoint(tmp_path / "ck", "plant gym:evilmod:Foo-v0\nstate x = obs[0]\nhorizon 1\nprop a = x < 1\nformula F a\n")
    for args in (["simulate", "--policy", "ck"], ["train", "--resume", "ck", "--trials", "1", "-q"]):
        r = _python(args, tmp_path)
        assert r.returncode == 2, (args, r.stderr)
        assert not marker.exists(), args
        errors = _error_lines(r.stderr)
        assert len(errors) == 1 and errors[0].startswith(
            "ck/params.npz: error: damaged checkpoint: spec_source, line 1: 'gym:evilmod:Foo-v0' would import "
            "the module 'evilmod'"
        ), (args, r.stderr)
        assert "Traceback" not in r.stderr


def test_a_checkpoint_plant_record_names_a_module_it_does_not_import(tmp_path: Path) -> None:
    """A run trained with --gym-module records it; loading the run asks for the option again."""
    marker = tmp_path / "evil-ran"
    (tmp_path / "evilmod.py").write_text(EVIL.format(marker=str(marker)))
    plant = {"name": "gym:EvilEnv-v0", "kind": "gym", "gym_modules": "evilmod"}
    _checkpoint(tmp_path / "ck", "plant gym:EvilEnv-v0\nstate x = obs[0]\nprop a = x < 1\nformula F a\n", plant)
    for args in (["simulate", "--policy", "ck"], ["train", "--resume", "ck", "--trials", "1", "-q"]):
        r = _python(args, tmp_path)
        assert r.returncode == 2 and not marker.exists(), (args, r.stderr)
        assert r.stderr.splitlines()[0] == (
            "ck/params.npz: error: the run's environment 'EvilEnv-v0' was registered by --gym-module evilmod in "
            "its training: pass --gym-module evilmod again (a run folder never imports code)"
        )
    damaged = {"name": "gym:EvilEnv-v0", "kind": "gym", "gym_modules": "os;rm -rf"}
    _checkpoint(tmp_path / "ck2", "plant gym:EvilEnv-v0\nformula F true\n", damaged)
    r = CliRunner().invoke(main, ["simulate", "--policy", str(tmp_path / "ck2")])
    assert r.exit_code == 2 and "its meta 'plant' record is not a plant record" in r.output


def test_plant_file_errors_are_labelled_with_the_option() -> None:
    r = CliRunner().invoke(main, ["plants", "--plant-file", "os:path"])
    assert r.exit_code == 2
    assert r.output.strip() == (
        "--plant-file: error: os:path is not a mitlc Plant (nor a list of them, nor a function returning one)"
    )


@pytest.mark.parametrize(
    "value, first",
    [
        (
            "no_such_module_xyz",
            "--gym-module no_such_module_xyz: error: cannot import module 'no_such_module_xyz': "
            "no module named 'no_such_module_xyz'",
        ),
        ("envs/my.py", "--gym-module envs/my.py: error: not a module name (a dotted Python name such as mypkg.envs)"),
        ("boom_mod_xyz", "--gym-module boom_mod_xyz: error: importing module 'boom_mod_xyz' failed: ValueError: boom"),
        ("exit_mod_xyz", "--gym-module exit_mod_xyz: error: importing module 'exit_mod_xyz' failed: SystemExit: 3"),
    ],
)
def test_a_bad_gym_module_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, value: str, first: str) -> None:
    (tmp_path / "boom_mod_xyz.py").write_text("raise ValueError('boom')\n")
    (tmp_path / "exit_mod_xyz.py").write_text("import sys\nsys.exit(3)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for command in (["compile", "pendulum/p2_avoid"], ["plants"], ["check", "pendulum/p2_avoid", "t.csv"]):
        r = CliRunner().invoke(main, [*command, "--gym-module", value])
        assert r.exit_code == 2 and "Traceback" not in r.output
        assert r.output.splitlines()[0] == first
    assert value not in G.GYM_MODULES


def test_every_command_with_plant_file_takes_gym_module() -> None:
    import click

    ctx = click.Context(main)
    commands = {name: main.get_command(ctx, name) for name in main.list_commands(ctx)}
    with_plant_file = [
        n for n, c in commands.items() if c is not None and any(p.name == "plant_file" for p in c.params)
    ]
    assert {"compile", "check", "train", "simulate", "sweep", "plants"} <= set(with_plant_file)
    for name in with_plant_file:
        cmd = commands[name]
        assert cmd is not None and any(p.name == "gym_module" for p in cmd.params), name


@pytest.fixture
def myenvs(tmp_path: Path) -> tuple[Path, Path]:
    """A folder with ``myenvs.py`` (registers MyDrift-v0, writes ``imported`` on import) and a spec of it."""
    pytest.importorskip("gymnasium")
    lib = tmp_path / "lib"
    lib.mkdir()
    marker = tmp_path / "imported"
    (lib / "myenvs.py").write_text(MYENVS.format(marker=str(marker)))
    (tmp_path / "g.mitl").write_text(DRIFT_SPEC)
    return lib, marker


def test_gym_module_end_to_end(tmp_path: Path, myenvs: tuple[Path, Path]) -> None:
    lib, marker = myenvs
    run = lambda *args: _python(list(args), tmp_path, lib)  # noqa: E731
    r = run("compile", "g.mitl")  # not registered: nothing imports myenvs for the spec
    assert r.returncode == 2 and not marker.exists()
    assert _error_lines(r.stderr)[0].startswith("g.mitl:1:7: error: Gymnasium has no environment 'MyDrift-v0'")
    assert "hint: an environment of your own module is registered by importing it: --gym-module MODULE" in r.stderr

    r = run("compile", "--gym-module", "myenvs", "g.mitl")
    assert r.returncode == 0, r.stderr
    assert marker.exists() and "spec:        g.mitl" in r.stdout

    r = run("train", "--gym-module", "myenvs", "--spec", "g.mitl", "--runs", "2", "--trials", "2", "--out", "o")
    assert r.returncode == 0, r.stderr
    meta = json.loads(str(np.load(tmp_path / "o" / "params.npz")["meta"]))
    assert meta["plant"] == {"name": "gym:MyDrift-v0", "kind": "gym", "gym_modules": "myenvs"}
    manifest = json.loads((tmp_path / "o" / "manifest.json").read_text())
    assert manifest["plant"]["gym_modules"] == "myenvs"

    marker.unlink()
    for args in (("simulate", "--policy", "o"), ("train", "--resume", "o", "--trials", "1", "-q")):
        r = run(*args)  # the run folder names the module; it does not import it
        assert r.returncode == 2 and not marker.exists(), r.stderr
        assert r.stderr.splitlines() == [
            "o/params.npz: error: the run's environment 'MyDrift-v0' was registered by --gym-module myenvs in its "
            "training: pass --gym-module myenvs again (a run folder never imports code)"
        ]
    r = run("simulate", "--policy", "o", "--gym-module", "myenvs", "--rollouts", "3")
    assert r.returncode == 0, r.stderr
    assert "rollouts satisfy F near (fresh resets of the environment, seed 0)" in r.stdout
    r = run("train", "--resume", "o", "--trials", "3", "-q", "--gym-module", "myenvs")  # 3 trials in all
    assert r.returncode == 0, r.stderr
    assert json.loads(str(np.load(tmp_path / "o" / "params.npz")["meta"]))["trial"] == 3


def test_gym_module_reaches_sweep_workers(tmp_path: Path, myenvs: tuple[Path, Path]) -> None:
    lib, marker = myenvs
    args = ["sweep", "g.mitl", "--gym-module", "myenvs", "--grid", "sigma=1", "--seeds", "1", "--runs", "1"]
    r = _python([*args, "--trials", "2", "--workers", "1", "--out", "sw", "--no-plot", "-q"], tmp_path, lib)
    assert r.returncode == 0, r.stderr
    results = json.loads((tmp_path / "sw" / "results.json").read_text())["results"]
    assert len(results) == 1 and results[0]["error"] is None and results[0]["final_return"] is not None


def test_sweep_payload_carries_the_modules() -> None:
    from mitlc.spec.parse import load_spec
    from mitlc.sweep.grid import plan_sweep

    spec = load_spec("pendulum/p2_avoid")
    G.GYM_MODULES[:] = ["myenvs", "other.envs"]  # as --gym-module leaves them (the fixture restores them)
    plan = plan_sweep(spec, ["sigma=1,2"], range(1), runs=1, trials=1)
    assert [t.payload["gym_modules"] for t in plan.tasks] == [["myenvs", "other.envs"]] * 2


# ---------------------------------------------------------------- CR-only line ends


def test_cr_only_line_ends_read_as_lines(tmp_path: Path) -> None:
    good = tmp_path / "cr.mitl"
    good.write_bytes(b"plant pendulum\r# a comment\rprop a = abs(q) < 0.3\rformula F a\r")
    r = CliRunner().invoke(main, ["compile", str(good)])
    assert r.exit_code == 0, r.output
    assert "formula:     F a" in r.output
    bad = tmp_path / "bad.mitl"
    bad.write_bytes(b"plant pendulum\rprop a = abs(q) < 0.3\r# c\rformula F a & G bb\r")
    r = CliRunner().invoke(main, ["compile", str(bad)])
    assert r.exit_code == 2
    assert r.output.splitlines()[:3] == [
        f"{bad}:4:17: error: undefined proposition 'bb'",
        "  formula F a & G bb",
        "                  ^",
    ]


def test_crlf_specs_keep_their_text() -> None:
    """``\\r\\n`` parses as before and the text (whose hash a training records) is unchanged."""
    from mitlc.spec.parse import parse_spec

    text = "plant pendulum\r\nprop a = abs(q) < 0.3\r\nformula F a\r\n"
    assert parse_spec(text).source == text
    assert parse_spec("plant pendulum\rprop a = q < 1\rformula F a").source == (
        "plant pendulum\nprop a = q < 1\nformula F a"
    )


# ---------------------------------------------------------------- the cache is not code


class _Evil:
    def __init__(self, marker: Path) -> None:
        self.marker = str(marker)

    def __reduce__(self):  # what unpickling would run
        return (exec, (f"open({self.marker!r}, 'w').write('pwned')",))


def test_a_pickle_in_the_parser_cache_does_not_run(tmp_path: Path) -> None:
    from mitlc.spec import lark_tables as T

    cache = tmp_path / "cache"
    (cache / "parser").mkdir(parents=True, mode=0o700)
    cache.chmod(0o700)
    marker = tmp_path / "pwned"
    grammar = T._grammar_text()
    evil = pickle.dumps(_Evil(marker))
    for start in ("start", "formula", "pred"):
        key = T._tables_key(grammar, start)
        old = cache / "parser" / f"mitl-{start}-{key[:16]}.lark"  # where lark's pickle was
        old.write_bytes(key.encode() + b"\n" + evil + evil)
        new = cache / "parser" / f"mitl-{start}-{key[:16]}.json"
        new.write_bytes(evil)
        new.chmod(0o600)
    for _ in range(2):
        r = _python(["compile", "pendulum/p2_avoid"], tmp_path, MITLC_CACHE_DIR=str(cache))
        assert r.returncode == 0, r.stderr
        assert not marker.exists()
        assert "formula:     F G kappa & 10 * G !psi" in r.stdout
    kept = (cache / "parser" / f"mitl-start-{T._tables_key(grammar, 'start')[:16]}.json").read_bytes()
    assert kept.startswith(b"mitlc-parser-tables 1 " + T._tables_key(grammar, "start").encode() + b" ")
    json.loads(kept.partition(b"\n")[2])  # plain data


def _parsed(parser, text: str) -> str:
    import lark

    try:
        return repr(parser.parse(text))
    except lark.exceptions.UnexpectedInput as exc:
        return f"{type(exc).__name__} {exc.line}:{exc.column} {sorted(getattr(exc, 'expected', ()) or ())}"
    except Exception as exc:  # a SpecError raised by the transformer
        return f"{type(exc).__name__} {exc}"


def test_tables_from_the_cache_parse_as_built_ones(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from lark import Lark

    from mitlc.spec import lark_tables as T
    from mitlc.spec.transform import Build

    monkeypatch.setenv("MITLC_CACHE_DIR", str(tmp_path / "c"))
    grammar = T._grammar_text()
    texts = [p.read_text() for p in sorted(SPECS.rglob("*.mitl"))]
    texts += [t[: len(t) // 2] for t in texts[:6]] + ["prop = 1", "formula F[2,1] a", "formula G (a -> ", "x" * 5]
    assert len(texts) > 20
    for start in ("start",):
        built = Lark(grammar, parser="lalr", start=start, transformer=Build(), maybe_placeholders=True)
        path = Path(str(T._table_file(grammar, start)))
        T._save_tables(built, path, T._tables_key(grammar, start))
        loaded = T._load_tables(path, T._tables_key(grammar, start))
        assert loaded is not None
        assert [_parsed(loaded, t) for t in texts] == [_parsed(built, t) for t in texts]
        assert T._load_tables(path, "another grammar") is None


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="no user ids on this platform")
def test_cache_files_not_the_users_own_are_not_read(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from lark import Lark

    from mitlc import cachefiles as C
    from mitlc.spec import lark_tables as T
    from mitlc.spec.transform import Build

    root = tmp_path / "c"
    monkeypatch.setenv("MITLC_CACHE_DIR", str(root))
    grammar = T._grammar_text()
    key = T._tables_key(grammar, "pred")
    path = Path(str(T._table_file(grammar, "pred")))
    assert oct(root.stat().st_mode & 0o777) == oct(0o700) and oct(path.parent.stat().st_mode & 0o777) == oct(0o700)
    T._save_tables(Lark(grammar, parser="lalr", start="pred", transformer=Build()), path, key)
    assert T._load_tables(path, key) is not None and C.untrusted(path) is None

    path.chmod(0o666)  # writable by anyone, but in a folder only its owner may enter: still private
    assert C.untrusted(path) is None
    path.parent.chmod(0o755)
    assert C.untrusted(path) == f"writable by others (mode 0666; chmod go-w {path})"
    assert T._load_tables(path, key) is None
    path.chmod(0o600)
    assert T._load_tables(path, key) is not None

    path.parent.chmod(0o775)  # a folder others may write: nothing in it is read, nothing written
    assert T._table_file(grammar, "pred") is False
    folder, why = C.cache_folder("parser")
    assert folder is None and why == f"{path.parent} is writable by others (mode 0775; chmod go-w {path.parent})"
    path.parent.chmod(0o700)
    assert T._table_file(grammar, "pred") == str(path)

    if os.getuid() == 0:  # root can make a file another user's
        os.chown(path, 4321, 4321)
        assert C.untrusted(path) == "owned by user 4321, not by you (0)"
        assert T._load_tables(path, key) is None
        os.chown(path.parent, 4321, 4321)
        assert T._table_file(grammar, "pred") is False


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="no user ids on this platform")
def test_the_kernel_cache_is_used_only_when_it_is_the_users_own(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("numba")
    from mitlc.learn import jitcache as J

    root = tmp_path / "c"
    monkeypatch.setenv("MITLC_CACHE_DIR", str(root))
    monkeypatch.setattr(J, "_LOADED", {})

    def plus_one(x):
        return x + 1.5

    kernel = J.load(plus_one)
    assert kernel is not None and kernel(1.0) == 2.5
    pycache = root / "kernels" / "__pycache__"
    assert oct(pycache.stat().st_mode & 0o777) == oct(0o700)
    files = sorted(p.name for p in pycache.iterdir())
    assert any(f.endswith(".nbi") for f in files) and any(f.endswith(".nbc") for f in files)

    J._LOADED.clear()
    numba_index = next(p for p in pycache.iterdir() if p.name.endswith(".nbi"))
    numba_index.chmod(0o666)
    pycache.chmod(0o755)  # numba's pickle is now anyone's to write: not loaded
    assert J.load(plus_one) is None
    assert f"{numba_index} is writable by others (mode 0666; chmod go-w {numba_index})" == J._REFUSED
    pycache.chmod(0o700)
    assert J.load(plus_one) is not None and J._REFUSED is None

    J._LOADED.clear()
    (root / "kernels").chmod(0o777)
    assert J.load(plus_one) is None
    assert J._REFUSED is not None and "kernels is writable by others (mode 0777" in J._REFUSED
    notes: list[str] = []
    before = J.set_notice(notes.append)
    try:
        from numba import njit

        J.announce(njit(plus_one))
    finally:
        J.set_notice(before)
    assert notes and "the disk cache is not used" in notes[0] and "writable by others" in notes[0]
