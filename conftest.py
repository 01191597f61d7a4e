"""What pytest needs at the repository's root, for the doctests of mitlc/ and the tests alike.

* **Optional modules.** pyproject's ``--doctest-modules`` imports every module of the package
  to collect its doctests. A module that exists to bridge to an optional extra (``mitlc.gym.crm``
  subclasses Stable-Baselines3's replay buffer) cannot be imported without it: its doctests
  are then reported as skipped, with the extra to install, instead of a collection error that
  stops the README's test command.
* **Moved modules.** A deprecation shim left where a module was (``mitlc/crm.py``, now
  ``mitlc.gym.crm``; ``mitlc/learn/runtime.py``, now ``mitlc.runtime``; ...) has no doctests,
  and importing it only warns: it is not collected. tests/test_crm.py and
  tests/test_moved_modules.py import them, to check that they warn and give the same objects.
* **What was skipped.** With ``MITLC_SKIPPED_FILE=PATH`` set, the node ids of every test and
  module that skipped are written to PATH, one per line, at the end of the session. ``.ci/run``
  runs the README's test command first with only ``[test]`` installed, then installs the heavy
  extras and runs exactly those node ids again.
* **Two processes.** pyproject's ``-n auto`` runs the tests in one pytest-xdist worker per core;
  ``-n 0`` runs them in this process, as a debugger wants.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent

# One OpenMP thread for PyTorch (the SB3 tests) and BLAS, in this process and those the tests start:
# the networks are small, and on a 2-core machine with anything else running PyTorch's spinning
# threads made docs/python.md's SB3 examples take 99 s instead of 9 s (measured while another test
# process ran). This file is read before any test or doctest module imports torch.
os.environ.setdefault("OMP_NUM_THREADS", "1")

# module file (relative to the root) -> (the importable it needs, the extra that brings it)
OPTIONAL_MODULES = {
    "mitlc/gym/crm.py": ("stable_baselines3", "sb3"),
}

SHIMS = {"mitlc/crm.py", "mitlc/learn/runtime.py", "mitlc/learn/kernel.py", "mitlc/learn/hyrl_eval.py"}
"""Module files (relative to the root) that only re-export a moved module, with a DeprecationWarning."""


class _NeedsExtra(pytest.File):
    """A module whose extra is missing: collecting it skips, naming the extra."""

    reason = ""

    def collect(self):  # type: ignore[no-untyped-def]
        pytest.skip(self.reason)


@pytest.hookimpl(wrapper=True)
def pytest_collect_file(file_path: Path, parent: pytest.Collector):  # type: ignore[no-untyped-def]
    collected = yield
    try:
        rel = file_path.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        return collected
    if rel in SHIMS:
        return []
    need = OPTIONAL_MODULES.get(rel)
    if need is None or importlib.util.find_spec(need[0]) is not None:
        return collected
    node = _NeedsExtra.from_parent(parent, path=file_path)
    node.reason = f"{rel} needs {need[0]}: pip install '.[{need[1]}]'"
    return [node]


_skipped: list[str] = []


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.skipped and report.nodeid not in _skipped:
        _skipped.append(report.nodeid)


def pytest_collectreport(report: pytest.CollectReport) -> None:
    if report.skipped and report.nodeid and report.nodeid not in _skipped:
        _skipped.append(report.nodeid)


def pytest_sessionfinish(session: pytest.Session) -> None:
    target = os.environ.get("MITLC_SKIPPED_FILE")
    if target and not hasattr(
        session.config, "workerinput"
    ):  # under pytest-xdist: the controller, which hears every worker
        Path(target).write_text("".join(f"{n}\n" for n in _skipped), encoding="utf-8")
