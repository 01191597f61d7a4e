"""The specs that ship with mitlc (package data ``mitlc.specs``), found by name.

A shipped spec is named by its path under ``specs/`` without the suffix, e.g.
``pendulum/p2_avoid``; ``pendulum/p2_avoid.mitl`` and ``specs/pendulum/p2_avoid.mitl``
name it too.  :func:`mitlc.spec.parse.load_spec` falls back to these names when
no file of that name exists, so every command takes a name as well as a path.

>>> "pendulum/p2_avoid" in shipped_specs()
True
>>> find("specs/pendulum/p2_avoid.mitl").name
'pendulum/p2_avoid'
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["ShippedSpec", "shipped_specs", "find", "SUFFIX"]

SUFFIX = ".mitl"


@dataclass(frozen=True)
class ShippedSpec:
    """One shipped spec: its name and where its text is read from."""

    name: str
    origin: str
    """How errors and outputs name it: ``mitlc:pendulum/p2_avoid.mitl``."""

    @property
    def path(self) -> Path:
        """The file it is read from (in the checkout, or in the installed package)."""
        return _root().joinpath(*f"{self.name}{SUFFIX}".split("/"))

    def read_text(self) -> str:
        return self.path.read_text(encoding="utf-8")

    def summary(self) -> str:
        """The first comment line of the spec (what it is for), or its formula."""
        lines = self.read_text().splitlines()
        for line in lines:
            s = line.strip()
            if s.startswith(("#", "//")):
                return s.lstrip("#/ ").strip()
            if s:
                break
        return next((line.strip() for line in lines if line.strip().startswith("formula")), "")


def _root() -> Path:
    here = Path(__file__).resolve().parents[1]  # the mitlc package
    local = here.parent / "specs"  # a source checkout (or an editable install)
    if local.is_dir() and (here.parent / "pyproject.toml").is_file():
        return local
    return here / "specs"  # the wheel's copy (package data mitlc.specs, a namespace package)


def shipped_specs() -> dict[str, ShippedSpec]:
    """Every shipped spec by name, sorted."""
    root = _root()
    names = sorted(p.relative_to(root).with_suffix("").as_posix() for p in root.rglob(f"*{SUFFIX}"))
    return {n: ShippedSpec(n, f"mitlc:{n}{SUFFIX}") for n in names}


def find(name: str) -> ShippedSpec | None:
    """The shipped spec that ``name`` names (with or without ``.mitl``, ``specs/`` or ``mitlc:``), if any."""
    n = name.replace("\\", "/").strip()
    for prefix in ("mitlc:", "specs/", "./specs/"):
        if n.startswith(prefix):
            n = n[len(prefix) :]
    if n.endswith(SUFFIX):
        n = n[: -len(SUFFIX)]
    return shipped_specs().get(n)
