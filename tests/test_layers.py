"""The package's layout is the pipeline: no module imports a later stage.

Each subpackage of ``mitlc`` is one stage; a module may import its own stage and the
stages listed for it in ``ALLOWED`` (the same lists stand in each ``__init__``'s
docstring). Imports inside functions count too: a lazy import of a later stage is
still a dependency on it.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "mitlc"

BASE = {"errors", "fileio", "limits"}
ALLOWED: dict[str, set[str]] = {
    "errors": set(),
    "limits": set(),
    "cmaes": set(),
    "fileio": {"errors"},
    "cachefiles": {"errors", "fileio"},
    "npzfile": {"errors"},
    "plants": BASE,
    "spec": BASE | {"plants", "cachefiles"},
    "petri": BASE | {"plants", "spec"},
    "hybrid": BASE | {"plants", "spec"},
    "monitor": BASE | {"npzfile", "plants", "spec"},
    "runtime": BASE | {"cachefiles", "npzfile", "spec", "petri"},
    "learn": BASE | {"cmaes", "cachefiles", "npzfile", "plants", "spec", "petri", "hybrid", "runtime"},
    "sweep": BASE | {"plants", "spec", "petri", "hybrid", "monitor", "learn"},
    "gym": BASE | {"plants", "spec", "petri", "monitor", "runtime", "learn"},
    "verify": BASE | {"cmaes", "plants", "spec", "monitor"},
    "cli": BASE
    | {"cmaes", "plants", "spec", "petri", "hybrid", "monitor", "runtime", "learn", "sweep", "gym", "verify"},
    "crm": {"gym"},  # mitlc/crm.py, the deprecation shim of mitlc.gym.crm: no stage imports it
}
"""Stage -> the stages it may import."""

FACADE = {"__init__", "__main__"}
"""``mitlc/__init__.py`` (the public API) and ``__main__`` may import any stage."""


def stage_of_module(dotted: str) -> str | None:
    """``mitlc.petri.net`` -> ``petri``; ``mitlc`` itself -> ``""``; not ours -> None."""
    parts = dotted.split(".")
    if parts[0] != "mitlc":
        return None
    return parts[1] if len(parts) > 1 else ""


def modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def stage_of_file(path: Path) -> str:
    rel = path.relative_to(PACKAGE)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def imported(path: Path) -> list[tuple[int, str, bool]]:
    """(line, dotted module, by importlib) of every absolute import of a ``mitlc`` module in
    ``path`` (docs/make_architecture.py draws the ``importlib.import_module`` ones dashed)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out: list[tuple[int, str, bool]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name, False) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path}:{node.lineno}: use absolute imports"
            if node.module == "mitlc":  # from mitlc import x: x is a stage or a name of the facade
                out += [(node.lineno, f"mitlc.{a.name}", False) for a in node.names]
            elif node.module:
                out.append((node.lineno, node.module, False))
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):  # importlib.import_module("mitlc.x"): a dependency all the same
            out.append((node.lineno, node.args[0].value, True))
    return [t for t in out if t[1].split(".")[0] == "mitlc"]


def test_every_file_has_a_stage() -> None:
    stages = {stage_of_file(p) for p in modules()} - FACADE
    assert stages == set(ALLOWED), stages ^ set(ALLOWED)


@pytest.mark.parametrize("path", modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_import_of_a_later_stage(path: Path) -> None:
    own = stage_of_file(path)
    if own in FACADE:
        return
    bad = []
    for line, dotted, _ in imported(path):
        other = stage_of_module(dotted)
        if other == "__version__" or other == own:
            continue
        if other == "":  # the facade: importing it pulls in petri and spec
            bad.append(f"line {line}: {dotted} (the facade; import the stage's module)")
        elif other not in ALLOWED[own]:
            bad.append(f"line {line}: {dotted} ({other} is not an earlier stage of {own})")
    assert not bad, f"{path.relative_to(PACKAGE.parent)}:\n" + "\n".join(bad)


def test_the_checker_sees_a_violation(tmp_path: Path) -> None:
    """The import scan catches a lazy import inside a function (so the test above can fail)."""
    f = tmp_path / "m.py"
    f.write_text(
        "def f():\n    from mitlc.cli.main import main\n    import mitlc.learn.sacpn\n"
        "    importlib.import_module('mitlc.sweep.run')\n"
    )
    assert imported(f) == [(2, "mitlc.cli.main", False), (3, "mitlc.learn.sacpn", False), (4, "mitlc.sweep.run", True)]


@pytest.mark.parametrize("stage", sorted(s for s in ALLOWED if (PACKAGE / s).is_dir()))
def test_each_stage_says_what_it_may_import(stage: str) -> None:
    """Each subpackage's docstring names what goes in, what comes out, and what it may import."""
    doc = importlib.import_module(f"mitlc.{stage}").__doc__ or ""
    assert "In:" in doc and "Out:" in doc and "May import:" in doc, stage
    # the stages named under "May import" are the ones ALLOWED lists
    said = doc.split("May import:")[1].split("\n\n")[0]
    named = {s for s in ALLOWED if f"mitlc.{s}`" in said}
    assert named == ALLOWED[stage] or said.strip().startswith("every stage"), (stage, named ^ ALLOWED[stage])


def test_every_stage_ships_in_the_wheel() -> None:
    """pyproject.toml lists packages explicitly: a new subpackage must be added there."""
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    present = {".".join(("mitlc", *p.parent.relative_to(PACKAGE).parts)) for p in PACKAGE.rglob("__init__.py")}
    assert present <= listed, present - listed


def private_names(folder: Path) -> set[str]:
    """Underscore names a stage keeps to itself: its modules' private functions, classes and
    module-level names, and the private attributes its classes set or define (dunders aside)."""
    names: set[str] = set()
    for path in folder.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                name = node.name
            elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "self":
                name = node.attr
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                name = node.id
            else:
                continue
            if name.startswith("_") and not name.startswith("__"):
                names.add(name)
    return names


RUNTIME_PRIVATE = private_names(PACKAGE / "runtime")


def private_reads(path: Path, private: set[str], stage: str) -> list[str]:
    """Where ``path`` imports an underscore name of ``mitlc.<stage>`` or reads one of ``private`` as an
    attribute of anything but ``self``/``cls`` (its own class's attributes may share a name)."""
    bad = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(f"mitlc.{stage}"):
            bad += [f"line {node.lineno}: imports {a.name}" for a in node.names if a.name.startswith("_")]
        elif (
            isinstance(node, ast.Attribute)
            and node.attr in private
            and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))
        ):
            bad.append(f"line {node.lineno}: reads .{node.attr}")
    return bad


@pytest.mark.parametrize(
    "path",
    [p for p in modules() if stage_of_file(p) != "runtime"],
    ids=lambda p: str(p.relative_to(PACKAGE)),
)
def test_no_module_reads_the_runtimes_private_names(path: Path) -> None:
    """The runtime is used through its public names only (``NetRuntime``'s methods and attributes)."""
    bad = private_reads(path, RUNTIME_PRIVATE, "runtime")
    assert not bad, f"{path.relative_to(PACKAGE.parent)}:\n" + "\n".join(bad)


def test_the_private_name_check_sees_a_read(tmp_path: Path) -> None:
    f = tmp_path / "m.py"
    f.write_text("from mitlc.runtime.tables import _x\ndef f(rt):\n    return rt._radix, self._radix\n")
    assert "_radix" in RUNTIME_PRIVATE
    assert private_reads(f, RUNTIME_PRIVATE, "runtime") == ["line 1: imports _x", "line 3: reads ._radix"]
