# Type stub of the Python module nexdyn (docs/python.md): what editors and type checkers see.
import os
from typing import Any, Mapping, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

PathLike = Union[str, os.PathLike[str]]

class SceneError(ValueError):
    """A scene that cannot be read: the message names the file, the key and the value."""

class StepFailed(RuntimeError):
    """A step that failed after its halvings. The simulation keeps the state before it."""

class CheckpointError(ValueError):
    """A checkpoint or output folder that cannot be resumed: the message says why."""

def resolve_mesh_paths(scene: Any, base_dir: PathLike) -> Any:
    """A copy of the scene dict with every relative "mesh" path made absolute against base_dir."""

class Simulation:
    """A simulation of one scene, stepped from Python."""

    def __init__(
        self,
        scene: Union[PathLike, Mapping[str, Any]],
        out: Optional[PathLike] = None,
        threads: Optional[int] = None,
        *,
        base_dir: Optional[PathLike] = None,
        steps: Optional[int] = None,
        checkpoint_every: Optional[int] = None,
    ) -> None: ...
    @classmethod
    def resume(cls, source: PathLike, threads: Optional[int] = None) -> Simulation:
        """Continues a run from an output folder or a checkpoint file, bit for bit."""
    def step(self, n: int = 1) -> dict[str, Union[int, float]]:
        """Takes n steps; the last one's stats.csv row."""
    @property
    def stats(self) -> Optional[dict[str, Union[int, float]]]:
        """The last step's stats.csv row, None before the first step."""
    @property
    def time(self) -> float:
        """Simulated time [s]."""
    @property
    def step_index(self) -> int:
        """Steps done since the run's start."""
    @property
    def total_steps(self) -> Optional[int]:
        """The run's length with an output folder, None without one."""
    @property
    def out(self) -> Optional[str]:
        """The output folder, or None."""
    @property
    def scene_file(self) -> str:
        """The scene file the simulation was built from."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """(n, 3) read-only view of the engine's positions [m]."""
    @property
    def velocities(self) -> npt.NDArray[np.float64]:
        """(n, 3) read-only view of the engine's velocities [m/s]."""
    def set_velocities(self, velocities: npt.ArrayLike) -> None:
        """Sets every free vertex's velocity before the next step (a scripted kick)."""
    def checkpoint(self, path: Optional[PathLike] = None) -> str:
        """Writes a checkpoint of the last step; its path."""
    def close(self) -> None:
        """Ends the run."""
    def __enter__(self) -> Simulation: ...
    def __exit__(self, *exc: Any) -> None: ...

def sweep(
    scene: Union[PathLike, Mapping[str, Any]],
    params: Mapping[str, Sequence[Any]],
    out: PathLike,
    client: Any = None,
    steps: Optional[int] = None,
    *,
    workers: Optional[int] = None,
    base_dir: Optional[PathLike] = None,
) -> Any:
    """Runs the product of the parameter lists on a Dask cluster, one output folder per run."""
