"""scripts/make_pile.py: the shipped piles come out of it as committed (the figures of
docs/performance.md are theirs), and the layouts it writes start with every body apart from its
neighbours (the engine refuses a scene whose bodies touch at the start)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "make_pile.py"


def generate(tmp_path, *args):
    out = tmp_path / "pile.json"
    subprocess.run([sys.executable, str(SCRIPT), *args, "--out", str(out)], check=True, capture_output=True)
    return out, json.loads(out.read_text())


@pytest.mark.parametrize("name, args", [
    ("pile_100", ["100"]),
    ("pile_1000", ["1000"]),
    ("pile_1000_affine", ["1000", "--affine", "--integrator", "default", "--steps", "300",
                          "--friction-iterations", "1"]),
])
def test_the_shipped_piles_come_out_of_the_generator_as_committed(tmp_path, name, args):
    _, scene = generate(tmp_path, *args)
    shipped = json.loads((ROOT / "scenes" / "stress" / f"{name}.json").read_text())
    assert len(scene["bodies"]) == len(shipped["bodies"])
    for made, committed in zip(scene["bodies"], shipped["bodies"]):
        # (mesh paths are relative to the output file, so they differ here)
        made.pop("mesh", None)
        committed.pop("mesh", None)
        assert made == committed
    for key in ("time", "solver", "contact", "materials", "obstacles"):
        assert scene[key] == shipped[key]


# Two 0.1 m boxes turned corner to corner reach 0.173 m along the axis between them, more than
# the grid's 0.16 m: with an even number of columns a side, boxes sit on boxes, and 1,000 bodies
# in 4 or 10 layers started with two of them overlapping before the generator checked.
@pytest.mark.parametrize("count, layers", [(1000, 4), (1000, 10), (100, 2)])
def test_every_layout_starts_with_its_bodies_apart(tmp_path, nexdyn_cli, count, layers):
    out, _ = generate(tmp_path, str(count), "--affine", "--layers", str(layers), "--steps", "1")
    run = subprocess.run([str(nexdyn_cli), "run", str(out), "--out", str(tmp_path / "run"), "--quiet"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
