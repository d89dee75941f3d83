"""Fixtures shared by the Python tests (run them with the module built into build/python):

    PYTHONPATH=build/python /usr/bin/python3 -m pytest tests/python -q

NEXDYN_BUILD_DIR names another build folder (default: build/ of the clone holding this file)."""

import csv
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("NEXDYN_BUILD_DIR", ROOT / "build"))


@pytest.fixture(scope="session")
def build_dir():
    """The build folder: its nexdyn CLI and its python/ folder (the module under test)."""
    return BUILD


@pytest.fixture(scope="session")
def nexdyn_cli():
    """The CLI, build/nexdyn."""
    cli = BUILD / "nexdyn"
    if not cli.is_file():
        pytest.fail(f"{cli} is missing: build it with `ninja -C {BUILD} nexdyn`")
    return cli


@pytest.fixture(scope="session")
def cube_drop_scene():
    """scenes/cube_drop.json: a box dropped on a plane, 100 steps of a few milliseconds."""
    return ROOT / "scenes" / "cube_drop.json"


@pytest.fixture(scope="session")
def cli_run(nexdyn_cli):
    """cli_run(scene, out, steps=None): `nexdyn run SCENE --out OUT --quiet [--steps N]`."""
    def run(scene, out, steps=None):
        command = [str(nexdyn_cli), "run", str(scene), "--out", str(out), "--quiet"]
        if steps is not None:
            command += ["--steps", str(steps)]
        subprocess.run(command, check=True)
    return run


@pytest.fixture(scope="session")
def stats_without_wall_time():
    """stats_without_wall_time(path): a stats.csv's rows (lists of cells, header first) with the
    wall_seconds cells blanked, the one column that differs between two runs of a scene."""
    def read(path):
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
        wall = rows[0].index("wall_seconds")
        for row in rows[1:]:
            row[wall] = ""
        return rows
    return read
