"""Modules moved by issue 30 keep their old import paths for one release: importing one warns
with a DeprecationWarning that names the new place, and gives the very same objects."""

from __future__ import annotations

import importlib
import sys

import pytest

MOVED = {
    "mitlc.learn.runtime": ("mitlc.runtime", ["NetRuntime"]),
    "mitlc.learn.hyrl_eval": (
        "mitlc.learn.hyrl.evaluation",
        ["HANDOVER_SIGMA", "STABLE_FRACTION", "ComposedController", "Evaluation", "brake_bound", "compose", "evaluate"],
    ),
    "mitlc.learn.kernel": ("mitlc.learn.sacpn.kernel", ["jit", "numba_available", "trial_kernel", "unsupported"]),
}


@pytest.mark.parametrize("old", sorted(MOVED))
def test_an_old_path_warns_and_gives_the_same_objects(old: str) -> None:
    new, names = MOVED[old]
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=new.replace(".", r"\.")):
        module = importlib.import_module(old)
    target = importlib.import_module(new)
    for name in names:
        assert getattr(module, name) is getattr(target, name), name
    assert set(names) <= set(module.__all__)


def test_the_kernel_shim_also_gives_the_atoms() -> None:
    from mitlc.runtime import atoms

    sys.modules.pop("mitlc.learn.kernel", None)
    with pytest.warns(DeprecationWarning, match=r"mitlc\.runtime\.atoms"):
        module = importlib.import_module("mitlc.learn.kernel")
    assert module.atom_source is atoms.atom_source and module.scalar_atoms is atoms.scalar_atoms


def test_the_package_paths_did_not_move() -> None:
    """``mitlc.learn.sacpn`` and ``mitlc.learn.hyrl`` are folders now; their documented names import
    from the same paths, without a warning."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        from mitlc.learn import NetRuntime, Sacpn
        from mitlc.learn.hyrl import HyrlSettings, brake_bound, evaluate, train_hybrid
        from mitlc.learn.sacpn import Rollout, SacpnSettings, read_meta
        from mitlc.runtime import NetRuntime as RT

    assert NetRuntime is RT
    assert Sacpn.__module__ == "mitlc.learn.sacpn.sacpn" and SacpnSettings.__module__ == Sacpn.__module__
    assert Rollout.__module__ == Sacpn.__module__ and read_meta.__module__ == Sacpn.__module__
    assert train_hybrid.__module__ == HyrlSettings.__module__ == "mitlc.learn.hyrl.hyrl"
    assert evaluate.__module__ == brake_bound.__module__ == "mitlc.learn.hyrl.evaluation"
