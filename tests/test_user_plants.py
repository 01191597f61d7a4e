"""Plants from the user's own code: --plant-file, module:attribute, entry points, and their errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from mitlc.cli.main import main
from mitlc.plants import PLANTS
from mitlc.plants import user as U

ROOT = Path(__file__).resolve().parent.parent
CART = ROOT / "examples" / "cart" / "cart_plant.py"
CART_SPEC = ROOT / "examples" / "cart" / "cart.mitl"


pytestmark = pytest.mark.usefixtures("forget_user_plants")  # tests/conftest.py


def test_the_cart_example_learns_from_the_command_line(tmp_path) -> None:
    out = tmp_path / "cart"
    args = ["train", "--plant-file", str(CART), "--spec", str(CART_SPEC), "--runs", "10", "--trials", "400"]
    r = CliRunner().invoke(main, [*args, "--out", str(out), "--no-plots", "-q"])
    assert r.exit_code == 0, r.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["success_rate"] >= 0.5  # 0.60 with these seeds; a controller that does nothing gets 0
    listed = CliRunner().invoke(main, ["plants", "--plant-file", str(CART)])
    assert "cart: a cart on a rail" in listed.output and "state  x in [-2, 2]" in listed.output


def test_module_attribute_and_entry_points(tmp_path, monkeypatch) -> None:
    (tmp_path / "my_plants.py").write_text(CART.read_text().replace('name="cart"', 'name="cart2"'))
    monkeypatch.syspath_prepend(str(tmp_path))
    (plant,) = U.load_plants("my_plants:CART")
    assert plant.name == "cart2" and PLANTS["cart2"] is plant

    class EP:
        name, value = "rail", "my_plants:CART"

        def load(self):
            import my_plants

            return lambda: my_plants.CART  # a function returning a Plant works too

    monkeypatch.setattr(U.metadata, "entry_points", lambda group: [EP()] if group == "mitlc.plants" else [])
    monkeypatch.setattr(U, "_discovered", False)
    del PLANTS["cart2"]
    from mitlc.spec.parse import parse_spec

    s = parse_spec("plant cart2\nprop far = x > 1\nformula F far\n")  # found through the entry point
    assert s.plant is not None and s.plant.name == "cart2"


@pytest.mark.parametrize(
    "content, source, message",
    [
        (None, "nope.py", "no such plant file"),
        (
            "import numpy\nraise ValueError('bad mass')\n",
            "bad.py",
            "importing the plant file failed: ValueError: bad mass",
        ),
        ("x = 1\n", "empty.py", "defines no Plant"),
        ("x = 1\n", "empty.py:CART", "has no attribute 'CART'"),
        ("x = 1\n", "empty.py:x", "is not a mitlc Plant"),
        (None, "no_such_module_xyz:CART", "cannot import module 'no_such_module_xyz'"),
    ],
)
def test_bad_plant_sources_are_one_line_and_exit_2(tmp_path, monkeypatch, content, source, message) -> None:
    monkeypatch.chdir(tmp_path)
    if content is not None:
        (tmp_path / source.split(":")[0]).write_text(content)
    r = CliRunner().invoke(main, ["plants", "--plant-file", source])
    assert r.exit_code == 2
    assert message in r.output and "Traceback" not in r.output
    if source == "bad.py":
        assert "bad.py:2: error:" in r.output  # the line of the user's file that raised


def test_an_unknown_plant_says_how_to_bring_one() -> None:
    r = CliRunner().invoke(main, ["compile", str(CART_SPEC)])
    assert r.exit_code == 2
    assert "unknown plant 'cart'" in r.output and "--plant-file FILE.py" in r.output


def test_the_python_blocks_of_plants_md_run(monkeypatch) -> None:
    import re

    monkeypatch.chdir(ROOT)
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "plants.md").read_text(), flags=re.S)
    assert len(blocks) == 4
    for code in blocks:
        exec(compile(code, "docs/plants.md", "exec"), {})
    assert PLANTS["cart"].state_names == ("x", "v")
