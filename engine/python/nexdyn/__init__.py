"""NexDynIPC from Python: step a scene, read its state as NumPy arrays, sweep parameters on Dask.

    import nexdyn
    sim = nexdyn.Simulation("scenes/cube_drop.json")
    row = sim.step(10)        # the last step's stats.csv row, as a dict
    x = sim.positions         # (n, 3) read-only view of the engine's own positions [m]

    nexdyn.sweep("scenes/cube_drop.json", {"contact.friction": [0.1, 0.3]}, out="out/sweep")

Every name is described in docs/python.md.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from typing import Any, Mapping, Optional, Union

from . import _core

__all__ = ["Simulation", "SceneError", "StepFailed", "CheckpointError", "sweep", "resolve_mesh_paths"]


class SceneError(ValueError):
    """A scene that cannot be read: the message names the file, the key and the value."""


class StepFailed(RuntimeError):
    """A step that failed after its halvings. The simulation keeps the state before it."""


class CheckpointError(ValueError):
    """A checkpoint or output folder that cannot be resumed: the message says why."""


_core._set_errors(SceneError, StepFailed, CheckpointError)

PathLike = Union[str, "os.PathLike[str]"]


def resolve_mesh_paths(scene: Any, base_dir: PathLike) -> Any:
    """A copy of the scene `scene` (a dict) with every relative "mesh" path made absolute
    against `base_dir`: the scene can then be written anywhere and still find its meshes."""
    if isinstance(scene, dict):
        resolved = {}
        for key, value in scene.items():
            if key == "mesh" and isinstance(value, str) and not os.path.isabs(value):
                resolved[key] = os.path.abspath(os.path.join(os.fspath(base_dir), value))
            else:
                resolved[key] = resolve_mesh_paths(value, base_dir)
        return resolved
    if isinstance(scene, list):
        return [resolve_mesh_paths(item, base_dir) for item in scene]
    return scene


def _write_json(path: str, document: Any) -> None:
    temporary = path + ".partial"
    with open(temporary, "w", encoding="utf-8") as f:
        json.dump(document, f, indent=1)
        f.write("\n")
    os.replace(temporary, path)


class Simulation:
    """A simulation of one scene, stepped from Python.

    Simulation(scene, out=None, threads=None, *, base_dir=None, steps=None, checkpoint_every=None)

    scene: the path of a scene file, or a dict with the same content; its relative mesh paths
        then resolve against `base_dir` (default: the current folder). Without `out` a dict
        scene is written to $TMPDIR/nexdyn-scenes/, named by its content (its checkpoints name it).
    out: an output folder. With it the simulation writes what `nexdyn run SCENE --out OUT` writes
        (stats.partial.csv, then stats.csv once its steps are done; frames; checkpoints) and a
        dict scene is written there as scene.json. Without it nothing is written.
    threads: worker threads of the engine (default: all cores). Results do not depend on it.
        It limits the whole process while the simulation lives.
    steps: the run's length with an output folder (default: the scene's time.steps); a
        simulation without one steps as long as it is asked to.
    checkpoint_every: steps between the output folder's checkpoints (default: the scene's
        output.checkpoint_every).

    Raises SceneError for a scene that cannot be read, and RuntimeError when another run (of
    this process or another) writes the output folder: one writer per folder.
    """

    def __init__(self, scene: Union[PathLike, Mapping[str, Any]], out: Optional[PathLike] = None,
                 threads: Optional[int] = None, *, base_dir: Optional[PathLike] = None,
                 steps: Optional[int] = None, checkpoint_every: Optional[int] = None,
                 _core_simulation: Optional[Any] = None) -> None:
        if _core_simulation is not None:
            self._core = _core_simulation
            return
        out_dir = "" if out is None else os.fspath(out)
        lock = None  # the output folder's, before the scene file goes into it
        if isinstance(scene, Mapping):
            document = resolve_mesh_paths(dict(scene), base_dir if base_dir is not None else os.getcwd())
            if out_dir:
                os.makedirs(out_dir, exist_ok=True)
                lock = _core._lock_folder(out_dir)
                scene_file = os.path.join(out_dir, "scene.json")
            else:
                # Named by its content, and kept: a checkpoint of this simulation names the file.
                text = json.dumps(document, sort_keys=True)
                folder = os.path.join(tempfile.gettempdir(), "nexdyn-scenes")
                os.makedirs(folder, exist_ok=True)
                scene_file = os.path.join(folder, hashlib.sha256(text.encode()).hexdigest()[:32] + ".json")
            if not os.path.exists(scene_file) or out_dir:
                _write_json(scene_file, document)
        else:
            scene_file = os.fspath(scene)
        self._core = _core._Simulation(scene_file, out_dir, threads, -1 if steps is None else int(steps),
                                       -1 if checkpoint_every is None else int(checkpoint_every), lock)

    @classmethod
    def resume(cls, source: PathLike, threads: Optional[int] = None) -> "Simulation":
        """Continues a run: `source` is an output folder (its newest valid checkpoint; the
        simulation writes on into the folder, as `nexdyn resume` does) or a checkpoint file
        written by checkpoint(path) (stepped without an output folder). The steps that follow
        are bit for bit those the run would have taken. Raises CheckpointError, and RuntimeError
        when another run writes the folder."""
        return cls(None, _core_simulation=_core._Simulation(os.fspath(source), threads))  # type: ignore[arg-type]

    def step(self, n: int = 1) -> dict:
        """Takes n steps and returns the last one's stats.csv row as a dict (the CLI's column
        names). The GIL is released during each step. Ctrl-C (on the main thread) abandons the
        step under way at its next safe point, within a fraction of a second, and raises
        KeyboardInterrupt with the state of the last finished step; the simulation goes on from
        there as if never stopped. Raises StepFailed for a step that failed after its halvings
        (the state is the one before it)."""
        return self._core.step(int(n))

    @property
    def stats(self) -> Optional[dict]:
        """The last step's stats.csv row as a dict, None before this simulation's first step."""
        row = self._core.stats()
        return row if row else None

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return self._core.time()

    @property
    def step_index(self) -> int:
        """Steps done since the run's start (a resumed run counts its earlier steps)."""
        return self._core.step_index()

    @property
    def total_steps(self) -> Optional[int]:
        """The run's length with an output folder, None without one."""
        return self._core.total_steps() if self._core.out_dir() else None

    @property
    def out(self) -> Optional[str]:
        """The output folder, or None."""
        return self._core.out_dir() or None

    @property
    def scene_file(self) -> str:
        """The scene file the simulation was built from (a dict scene's scene.json)."""
        return self._core.scene_file()

    @property
    def positions(self):
        """(n, 3) float64 read-only view of the engine's positions [m], without a copy: an
        array taken before a step shows the new values after it. One row per vertex, the
        scene's bodies in order; an affine body has four more rows after its vertices: its
        centre of mass and its three axis nodes (the columns of A R, R its principal axes at
        rest), which are coordinates, not points of the body. Particle scenes: the particles."""
        return self._core.positions()

    @property
    def velocities(self):
        """(n, 3) float64 read-only view of the engine's velocities [m/s], as positions."""
        return self._core.velocities()

    def set_velocities(self, velocities) -> None:
        """Sets every free vertex's velocity (an (n, 3) array of finite values) before the next
        step: a scripted kick. Held vertices keep their prescribed velocities; an affine body
        takes the velocities of its four coordinate nodes and its surface vertices follow them.
        Sleeping bodies that now move wake. The kinetic energy added is not in the energy
        balance columns: the next row's balance starts from the kicked state."""
        self._core.set_velocities(velocities)

    def checkpoint(self, path: Optional[PathLike] = None) -> str:
        """Writes a checkpoint of the last step and returns its path: into the output folder's
        checkpoints/ (path None; the newest two are kept, as the CLI's), or into the file `path`.
        Simulation.resume continues from either, bit for bit."""
        return self._core.checkpoint("" if path is None else os.fspath(path))

    def close(self) -> None:
        """Ends the run: with every step done, stats.csv and timings.csv take their final names
        (that happens on the last step already). Called on leaving a `with` block."""
        self._core.close()

    def __enter__(self) -> "Simulation":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        where = f", out={self.out!r}" if self.out else ""
        return f"nexdyn.Simulation({self.scene_file!r}{where}, step {self.step_index}, t = {self.time:.6g} s)"


def sweep(scene: Union[PathLike, Mapping[str, Any]], params: Mapping[str, Any], out: PathLike,
          client: Any = None, steps: Optional[int] = None, *, workers: Optional[int] = None,
          base_dir: Optional[PathLike] = None):
    """Runs the product of the parameter lists on a Dask cluster; see nexdyn.sweep_runs.sweep."""
    from .sweep_runs import sweep as run_sweep
    return run_sweep(scene, params, out, client=client, steps=steps, workers=workers, base_dir=base_dir)
