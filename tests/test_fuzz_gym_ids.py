"""Fuzzing ``plant gym:ID`` with ids that look like modules, namespaces, versions and worse.

Whatever the id, ``mitlc compile`` ends with one located error line (exit 2) and never imports
a module: Gymnasium reads ``module:Env`` as an order to import ``module``, and a spec never
causes an import (issue 29). Checked in-process, where ``sys.modules`` would show any import,
after a warm-up that imports what a Gymnasium plant needs anyway.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytest.importorskip("gymnasium")

from mitlc.cli import main  # noqa: E402

MODULES = ["this", "__hello__", "antigravity", "evilmod", "os", "os.path", "tabnanny", "json.tool", "a.b", "_x1"]
NAMES = ["Foo", "Pendulum", "CartPole", "MountainCarContinuous", "ALE/Pong", "mitlc/Pendulum", "x", "MyEnv"]
PIECES = [":", "/", "-v", "-v0", "-v1", "-v99999", ".", "-", "_", "0", "::", ":/", "/:", "é", "\u00a0", "ß", "Ж", "😀"]


@st.composite
def gym_ids(draw: st.DrawFn) -> str:
    """An id of module-like names, environment-like names and separators, unicode included."""
    parts = []
    if draw(st.booleans()):
        parts += [draw(st.sampled_from(MODULES)), ":"]
    for _ in range(draw(st.integers(1, 4))):
        parts.append(
            draw(
                st.one_of(
                    st.sampled_from(NAMES),
                    st.sampled_from(PIECES),
                    st.sampled_from(MODULES),
                    st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), min_size=1, max_size=3),
                )
            )
        )
    text = "".join(parts)
    return text.replace("\n", "").replace("\r", "") or "Foo"


def _spec(env_id: str) -> str:
    return f"plant gym:{env_id}\nstate x = obs[0]\nhorizon 1\nprop a = x < 1\nformula F a\n"


@pytest.fixture(scope="module")
def warm(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder to work in, after one of each kind of id was compiled: what Gymnasium imports for
    any id is imported by now, so that a new module in sys.modules is the id's doing."""
    folder = tmp_path_factory.mktemp("gymids")
    for env_id in ("Pendulum-v1", "NoSuch-v0", "NoSuchNs/NoSuch-v0", "Pendulum", "a/b/c", "this:Foo-v0", "é"):
        (folder / "g.mitl").write_text(_spec(env_id), encoding="utf-8")
        CliRunner().invoke(main, ["compile", str(folder / "g.mitl")])
    return folder


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(env_id=gym_ids())
def test_a_gym_id_never_imports_and_is_one_line(warm: Path, env_id: str) -> None:
    spec = warm / "g.mitl"
    spec.write_text(_spec(env_id), encoding="utf-8")
    before = set(sys.modules)
    r = CliRunner().invoke(main, ["compile", str(spec)])
    new = set(sys.modules) - before
    assert not new, f"compiling plant gym:{env_id!r} imported {sorted(new)}"
    exc = r.exception
    assert exc is None or isinstance(exc, SystemExit), f"{type(exc).__name__}: {exc}\n{r.output}"
    assert "Traceback" not in r.output
    token = re.match(r"[A-Za-z0-9_][A-Za-z0-9_\-/.:]*", env_id)  # what the grammar reads as the id
    module_id = token is not None and ":" in token.group(0)
    whole = token is not None and token.group(0) == env_id  # nothing after it to stop the parse first
    if r.exit_code == 0:  # a registered environment (Pendulum-v1): compiled
        assert not module_id and "formula:     F a" in r.output, r.output
        return
    assert r.exit_code == 2, r.output
    errors = [ln for ln in r.output.splitlines() if re.search(r": (syntax )?error: ", ln)]
    assert len(errors) == 1 and re.match(rf"^{re.escape(str(spec))}:[12]:\d+: (syntax )?error: ", errors[0]), r.output
    assert len(errors[0]) < 600 + len(str(spec)), errors[0]
    if module_id and whole and len(env_id) <= 200:
        assert "never causes an import" in errors[0], errors[0]
