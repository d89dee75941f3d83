"""Parameter sweeps of a scene on Dask: nexdyn.sweep and `python3 -m nexdyn sweep` (docs/python.md).

A sweep is the product of value lists for dotted keys of a scene ("contact.friction",
"bodies.0.velocity"; parsed and set by nexdyn.sweep_keys), the last key varying fastest. Run k is
the normal output folder OUT/runs/kkkk/ of its own scene.json (the scene with the values set, mesh
paths absolute, time.steps the run's length), stepped in a Dask worker by nexdyn.Simulation with
one thread. OUT/sweep.csv gets one row per run once all are over.

The task of a run is idempotent: a run with stats.csv is read, one with a checkpoint is resumed
from it, any other starts again. So a sweep run again into the same folder only does what is
left, and a run whose worker died is resumed where its last checkpoint left it when Dask gives
the task to another worker. A lock file in the run folder keeps two tasks of one run from
writing it at once (the second waits, then finds the run finished).
"""

from __future__ import annotations

import copy
import csv
import errno
import itertools
import json
import os
import socket
import sys
import tempfile
import time
import uuid
from typing import Any, Callable, Dict, List, Mapping, Optional, Tuple, Union

from . import CheckpointError, SceneError, Simulation, StepFailed, resolve_mesh_paths
from .sweep_keys import parse_set, parse_value, set_key, split_values, value_lists

try:
    import fcntl
except ImportError:  # not POSIX: runs are not locked
    fcntl = None  # type: ignore[assignment]

__all__ = ["sweep", "SchedulerError", "split_values", "parse_value", "parse_set", "set_key"]

# The most steps a run may lose when its worker dies: runs checkpoint at least this often.
MAX_CHECKPOINT_EVERY = 20
# The scene's output.checkpoint_every when it has none (engine/scene: output).
DEFAULT_CHECKPOINT_EVERY = 100
LOCK_FILE = ".sweep.lock"
FIXED_COLUMNS = ("status", "reason", "steps", "wall_seconds")

PathLike = Union[str, "os.PathLike[str]"]


# ----------------------------------------------------------------------------------------------
# The plan: every run's scene, checked before anything is submitted


def _checkpoint_every(scene: Mapping[str, Any]) -> int:
    """The scene's output.checkpoint_every, at most MAX_CHECKPOINT_EVERY (0, only on signals,
    also becomes MAX_CHECKPOINT_EVERY: a sweep needs them to resume)."""
    output = scene.get("output")
    every = output.get("checkpoint_every", DEFAULT_CHECKPOINT_EVERY) if isinstance(output, dict) else DEFAULT_CHECKPOINT_EVERY
    if isinstance(every, bool) or not isinstance(every, int) or every <= 0:
        return MAX_CHECKPOINT_EVERY
    return min(every, MAX_CHECKPOINT_EVERY)


def _json_text(value: Any) -> str:
    return json.dumps(value, separators=(",", ":"))


def _write_json(path: str, document: Any) -> None:
    """As nexdyn.Simulation writes a dict scene's scene.json: temporary file, then rename."""
    temporary = f"{path}.partial-{os.getpid()}"
    with open(temporary, "w", encoding="utf-8") as f:
        json.dump(document, f, indent=1)
        f.write("\n")
    os.replace(temporary, path)


def _difference(here: Any, there: Any, path: str = "") -> str:
    """Where the scene `there` (a run folder's) first differs from `here` (this sweep's), or ""."""
    if isinstance(here, dict) and isinstance(there, dict):
        for key in list(here) + [k for k in there if k not in here]:
            where = f"{path}.{key}" if path else key
            if key not in there:
                return f"{where} is not in the folder's"
            if key not in here:
                return f"{where} is only in the folder's"
            found = _difference(here[key], there[key], where)
            if found:
                return found
        return ""
    if isinstance(here, list) and isinstance(there, list) and len(here) == len(there):
        for index, (a, b) in enumerate(zip(here, there)):
            found = _difference(a, b, f"{path}.{index}" if path else str(index))
            if found:
                return found
        return ""
    if here == there and isinstance(here, bool) == isinstance(there, bool):
        return ""
    return f"{path or 'the scene'} is {_json_text(there)} there, {_json_text(here)} here"


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


class _Plan:
    """What a sweep will run: the keys, each run's values and scene, the output folder."""

    def __init__(self, scene: Union[PathLike, Mapping[str, Any]], params: Mapping[str, Any], out: PathLike,
                 steps: Optional[int], base_dir: Optional[PathLike]) -> None:
        if isinstance(scene, Mapping):
            document = copy.deepcopy(dict(scene))
            self.label = "the scene"
            folder = os.fspath(base_dir) if base_dir is not None else os.getcwd()
        else:
            path = os.fspath(scene)
            self.label = path
            try:
                with open(path, encoding="utf-8") as f:
                    document = json.load(f)
            except OSError as e:
                raise SceneError(f"{path}: cannot open the scene file ({e.strerror})") from None
            except ValueError as e:
                raise SceneError(_one_line(f"{path}: not valid JSON: {e}")) from None
            if not isinstance(document, dict):
                raise SceneError(f"{path}: expected a JSON object at the top level")
            folder = os.fspath(base_dir) if base_dir is not None else os.path.dirname(os.path.abspath(path))
        if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
            raise ValueError(f"sweep: steps must be a positive integer, got {steps!r}")
        lists = value_lists(params)
        self.keys = [key for key, _ in lists]
        if steps is not None and "time.steps" in self.keys:
            raise ValueError("sweep: steps= and the key time.steps both set the runs' length; give one")
        self.out = os.path.abspath(os.fspath(out))
        self.values: List[Tuple[Any, ...]] = list(itertools.product(*(values for _, values in lists)))
        self.scenes: List[Dict[str, Any]] = []
        for values in self.values:
            run = copy.deepcopy(document)
            for key, value in zip(self.keys, values):
                set_key(run, key, value, self.label)
            run = resolve_mesh_paths(run, folder)  # the scene's meshes and those a value names
            if steps is not None:  # the run's length, in its scene.json: `nexdyn run` reproduces it
                if isinstance(run.get("time"), dict):
                    run["time"]["steps"] = steps
                elif "time" not in run:
                    run["time"] = {"steps": steps}
            self.scenes.append(run)

    def __len__(self) -> int:
        return len(self.scenes)

    def run_dir(self, number: int) -> str:
        return os.path.join(self.out, "runs", f"{number:04d}")

    def assignments(self, number: int) -> str:
        return " ".join(f"{key}={_json_text(value)}" for key, value in zip(self.keys, self.values[number]))

    def check_folders(self) -> None:
        """Refuses an output folder whose runs are another sweep's (a run folder whose scene.json
        is not this sweep's run): resuming or skipping them would mix two sweeps."""
        for number, scene in enumerate(self.scenes):
            run_dir = self.run_dir(number)
            scene_file = os.path.join(run_dir, "scene.json")
            if os.path.exists(scene_file):
                try:
                    with open(scene_file, encoding="utf-8") as f:
                        difference = _difference(scene, json.load(f))
                except (OSError, ValueError) as e:
                    difference = _one_line(str(e))
                if difference:
                    raise ValueError(f"{scene_file} is not this sweep's run {number:04d} ({self.assignments(number)}; "
                                     f"{difference}): sweep into another folder or remove {run_dir}")
            elif os.path.exists(os.path.join(run_dir, "stats.csv")) or \
                    os.path.exists(os.path.join(run_dir, "stats.partial.csv")):
                raise ValueError(f"{run_dir} has a run but no scene.json: sweep into another folder or remove it")

    def check_first_run(self) -> None:
        """The engine reads the first run's scene: a scene or value it refuses is refused here,
        in one line, before anything is submitted (SceneError)."""
        with tempfile.TemporaryDirectory(prefix="nexdyn-sweep-") as folder:
            scene_file = os.path.join(folder, "scene.json")
            _write_json(scene_file, self.scenes[0])
            try:
                simulation = Simulation(scene_file, threads=1)
            except SceneError as e:
                where = f"{self.label} as run 0000 ({self.assignments(0)})"
                raise SceneError(_one_line(str(e).replace(scene_file, where))) from None
            del simulation

    def write_scenes(self) -> None:
        for number, scene in enumerate(self.scenes):
            run_dir = self.run_dir(number)
            os.makedirs(run_dir, exist_ok=True)
            scene_file = os.path.join(run_dir, "scene.json")
            if not os.path.exists(scene_file):
                _write_json(scene_file, scene)


# ----------------------------------------------------------------------------------------------
# A run's folder, read


def _read_rows(path: str) -> Tuple[List[str], List[List[str]]]:
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except FileNotFoundError:
        return [], []
    if not rows:
        return [], []
    header = rows[0]
    return header, [row for row in rows[1:] if len(row) == len(header)]  # a cut-off last line is not a row


def _read_run(run_dir: str) -> Dict[str, Any]:
    """What a run folder says: steps done (stats rows), wall_seconds (the sum of timings.csv's
    total_ms: the steps and their output), the stats header and last row, as text."""
    finished = os.path.exists(os.path.join(run_dir, "stats.csv"))
    suffix = ".csv" if finished else ".partial.csv"
    header, rows = _read_rows(os.path.join(run_dir, "stats" + suffix))
    timings_header, timings = _read_rows(os.path.join(run_dir, "timings.csv"))
    if not timings_header:
        timings_header, timings = _read_rows(os.path.join(run_dir, "timings.partial.csv"))
    wall = 0.0
    if "total_ms" in timings_header:
        column = timings_header.index("total_ms")
        for row in timings:
            try:
                wall += float(row[column])
            except ValueError:
                pass
    last = rows[-1] if rows else []
    steps = 0
    if last and "step" in header:
        try:
            steps = int(last[header.index("step")])
        except ValueError:
            pass
    return {"finished": finished, "steps": steps, "wall_seconds": wall / 1e3, "header": header, "last": last}


class _RunLock:
    """An exclusive lock on a run folder (flock of LOCK_FILE) held by the task that steps the run;
    the file then names the host and process. A file system without locks: no lock."""

    def __init__(self, run_dir: str) -> None:
        self.path = os.path.join(run_dir, LOCK_FILE)
        self.file: Any = None

    def __enter__(self) -> "_RunLock":
        self.file = open(self.path, "a+", encoding="utf-8")
        if fcntl is not None:
            try:
                fcntl.flock(self.file.fileno(), fcntl.LOCK_EX)
            except OSError as e:
                if e.errno not in (errno.ENOLCK, errno.ENOSYS, errno.EOPNOTSUPP, errno.EINVAL):
                    raise
        self.file.seek(0)
        self.file.truncate()
        self.file.write(f"{socket.gethostname()} {os.getpid()}\n")
        self.file.flush()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.file.close()


def _run_task(number: int, run_dir: str, checkpoint_every: int, scene: Dict[str, Any]) -> Dict[str, Any]:
    """Runs (or resumes, or reads) run `number` in `run_dir`, in a Dask worker. Idempotent: a
    finished run is read; a run with a checkpoint continues from it; any other starts again."""
    started = time.monotonic()
    os.makedirs(run_dir, exist_ok=True)
    status, reason = "done", ""
    resumed_from: Optional[int] = None
    skipped = False
    with _RunLock(run_dir):
        scene_file = os.path.join(run_dir, "scene.json")
        if not os.path.exists(scene_file):
            _write_json(scene_file, scene)
        if os.path.exists(os.path.join(run_dir, "stats.csv")):
            skipped = True
        else:
            simulation = None
            try:
                try:
                    simulation = Simulation.resume(run_dir, threads=1)
                    resumed_from = simulation.step_index
                except (CheckpointError, RuntimeError):
                    # No checkpoint yet (or none that fits this scene.json): from the start.
                    simulation = Simulation(scene_file, out=run_dir, threads=1, checkpoint_every=checkpoint_every)
                total = simulation.total_steps
                while simulation.step_index < total:
                    simulation.step(1)
            except (StepFailed, SceneError, CheckpointError) as e:
                status, reason = "failed", _one_line(str(e))
            finally:
                if simulation is not None:
                    simulation.close()
                    del simulation
    result = _read_run(run_dir)
    if status == "done" and not result["finished"]:
        status, reason = "failed", "the run ended without its stats.csv"
    result.update(number=number, status=status, reason=reason, resumed_from=resumed_from, skipped=skipped,
                  host=socket.gethostname(), pid=os.getpid(), task_seconds=time.monotonic() - started)
    return result


# ----------------------------------------------------------------------------------------------
# The sweep


class _MainHidden:
    """Hides the main module from multiprocessing while a local cluster lives. Its worker
    processes are spawned, and a spawned process first imports the parent's main module again
    (by file or by module name): a script without `if __name__ == "__main__":` would start its
    sweep again in every worker, and a script read from stdin names a file "<stdin>" that is not
    there; either way the workers die at birth and are restarted forever. The runs' task lives in
    nexdyn.sweep_runs and needs nothing from the main module."""

    def __init__(self) -> None:
        self.main = sys.modules.get("__main__")
        self.saved = {name: vars(self.main)[name] for name in ("__spec__", "__file__")
                      if self.main is not None and name in vars(self.main)}
        if "__spec__" in self.saved:
            self.main.__spec__ = None  # type: ignore[union-attr]
        if "__file__" in self.saved:
            del self.main.__file__  # type: ignore[union-attr]

    def restore(self) -> None:
        for name, value in self.saved.items():
            setattr(self.main, name, value)
        self.saved = {}


def _connect(client: Any, workers: Optional[int]) -> Tuple[Any, Callable[[], None]]:
    """(a distributed.Client, what closes what this function opened)."""
    import logging

    import distributed

    if client is None:
        n = workers if workers is not None else (os.cpu_count() or 1)
        hidden = _MainHidden()
        try:
            cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                               dashboard_address="127.0.0.1:0",
                                               worker_dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
        except BaseException:
            hidden.restore()
            raise
        try:
            local = distributed.Client(cluster)
        except BaseException:
            cluster.close()
            hidden.restore()
            raise

        def close() -> None:
            try:
                local.close()
                cluster.close()
            finally:
                hidden.restore()
        return local, close
    if isinstance(client, (str, os.PathLike)):
        address = os.fspath(client)
        try:
            if "://" not in address and os.path.isfile(address):
                remote = distributed.Client(scheduler_file=address)
            else:
                remote = distributed.Client(address)
        except (OSError, TimeoutError, ValueError) as e:
            raise SchedulerError(_one_line(f"cannot reach the Dask scheduler {address}: {e}")) from None
        return remote, remote.close
    return client, lambda: None


def _failed_result(number: int, run_dir: str, error: BaseException) -> Dict[str, Any]:
    result = _read_run(run_dir)
    reason = f"{type(error).__name__}: {error}"
    if isinstance(error, ModuleNotFoundError) and "nexdyn" in str(error):
        reason += " (start the workers with PYTHONPATH naming the folder of the nexdyn module)"
    result.update(number=number, status="failed", reason=_one_line(reason), resumed_from=None, skipped=False,
                  host="", pid=0, task_seconds=0.0)
    return result


def _number(text: str) -> Union[int, float, str]:
    try:
        return int(text)
    except ValueError:
        try:
            return float(text)
        except ValueError:
            return text


class SchedulerError(OSError):
    """The Dask scheduler given by address or scheduler file cannot be reached."""


class _Sweep:
    """A sweep checked (the constructor: nothing is written or submitted when it raises), then
    run (run)."""

    def __init__(self, scene: Union[PathLike, Mapping[str, Any]], params: Mapping[str, Any], out: PathLike,
                 steps: Optional[int], base_dir: Optional[PathLike], client: Any = None,
                 workers: Optional[int] = None) -> None:
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ValueError(f"sweep: workers must be a positive integer, got {workers!r}")
        if client is not None and workers is not None:
            raise ValueError("sweep: workers= sizes a local cluster; with a client or a scheduler address, "
                             "the cluster's own workers run the sweep")
        if client is not None and not isinstance(client, (str, os.PathLike)) and not hasattr(client, "submit"):
            raise ValueError(f"sweep: client must be a distributed.Client, a scheduler address or None, not {client!r}")
        self.client, self.workers = client, workers
        self.plan = _Plan(scene, params, out, steps, base_dir)
        self.plan.check_folders()
        self.plan.check_first_run()

    def run(self, progress: Optional[Callable[[int, int, str, Dict[str, Any]], None]] = None) -> List[Dict[str, Any]]:
        """Runs what is left; calls progress(k, n, "key=value ...", result) as each run ends."""
        plan = self.plan
        n = len(plan)
        plan.write_scenes()
        results: List[Optional[Dict[str, Any]]] = [None] * n
        done = 0

        def report(result: Dict[str, Any]) -> None:
            nonlocal done
            done += 1
            results[result["number"]] = result
            if progress is not None:
                progress(done, n, plan.assignments(result["number"]), result)

        pending = []
        for number in range(n):
            run_dir = plan.run_dir(number)
            if os.path.exists(os.path.join(run_dir, "stats.csv")):
                result = _read_run(run_dir)
                result.update(number=number, status="done", reason="", resumed_from=None, skipped=True,
                              host="", pid=0, task_seconds=0.0)
                report(result)
            else:
                pending.append(number)
        if pending:
            import distributed

            dask_client, close = _connect(self.client, self.workers)
            try:
                token = uuid.uuid4().hex[:12]
                futures = {}
                for number in pending:
                    future = dask_client.submit(_run_task, number, plan.run_dir(number),
                                                _checkpoint_every(plan.scenes[number]), plan.scenes[number],
                                                key=f"nexdyn-run-{number:04d}-{token}", pure=False)
                    futures[future] = number
                for future in distributed.as_completed(list(futures)):
                    number = futures[future]
                    if future.status == "finished":
                        result = future.result()
                    else:
                        try:
                            error = future.exception()
                        except BaseException as e:  # cancelled
                            error = e
                        result = _failed_result(number, plan.run_dir(number), error)
                    report(result)
                    future.release()
            finally:
                close()
        rows = self._rows([r for r in results if r is not None])
        self._write_csv(rows)
        return rows

    def _rows(self, results: List[Dict[str, Any]]) -> List[Dict[str, Any]]:
        rows = []
        for result in sorted(results, key=lambda r: r["number"]):
            number = result["number"]
            stats = {name: _number(text) for name, text in zip(result["header"], result["last"])}
            rows.append({
                "run": number,
                "dir": self.plan.run_dir(number),
                "params": dict(zip(self.plan.keys, self.plan.values[number])),
                "status": result["status"],
                "reason": result["reason"],
                "steps": result["steps"],
                "wall_seconds": result["wall_seconds"],
                "stats": stats,
                "resumed_from": result["resumed_from"],
                "skipped": result["skipped"],
                "_stats_text": dict(zip(result["header"], result["last"])),
            })
        return rows

    def _write_csv(self, rows: List[Dict[str, Any]]) -> None:
        plan = self.plan
        taken = set(plan.keys) | set(FIXED_COLUMNS)
        stats_columns: List[str] = []
        for row in rows:
            for name in row["_stats_text"]:
                if name not in stats_columns:
                    stats_columns.append(name)
        names = {}
        for name in stats_columns:
            column = name
            while column in taken:  # wall_seconds: the run's is first; the last step's is last_wall_seconds
                column = "last_" + column
            taken.add(column)
            names[name] = column
        header = list(plan.keys) + list(FIXED_COLUMNS) + [names[name] for name in stats_columns]
        path = os.path.join(plan.out, "sweep.csv")
        temporary = f"{path}.partial-{os.getpid()}"
        with open(temporary, "w", newline="", encoding="utf-8") as f:
            writer = csv.writer(f, lineterminator="\n")
            writer.writerow(header)
            for row in rows:
                text = row.pop("_stats_text")
                writer.writerow([_json_text(row["params"][key]) for key in plan.keys] +
                                [row["status"], row["reason"], row["steps"], f"{row['wall_seconds']:.6f}"] +
                                [text.get(name, "") for name in stats_columns])
        os.replace(temporary, path)


def sweep(scene: Union[PathLike, Mapping[str, Any]], params: Mapping[str, Any], out: PathLike,
          client: Any = None, steps: Optional[int] = None, *, workers: Optional[int] = None,
          base_dir: Optional[PathLike] = None) -> List[Dict[str, Any]]:
    """Runs the product of the parameter lists on a Dask cluster, one output folder per run.

    scene: a scene file, or a dict (its relative mesh paths resolve against `base_dir`, default
        the current folder; a file's against its own folder, or `base_dir`).
    params: {dotted key: [values]}, e.g. {"contact.friction": [0.1, 0.3], "bodies.0.velocity":
        [[0, -1, 0], [0, -2, 0]]}; the runs are the product of the lists, in this order, the last
        key varying fastest. A key indexes lists with integers; every component but the last must
        exist in the scene. A value that is not a list is one value.
    out: the sweep's folder: run k in out/runs/kkkk/ (its scene.json, then what `nexdyn run`
        writes), out/sweep.csv once every run is over.
    client: None (a distributed.LocalCluster of `workers` processes of one thread, default
        os.cpu_count(), made and closed here), a distributed.Client, or a scheduler's address
        ("tcp://host:8786") or scheduler file.
    steps: every run's length (written into its scene.json as time.steps); default the scene's.

    Runs already finished in `out` (stats.csv) are read, not run again; interrupted ones resume
    from their newest checkpoint (runs checkpoint every output.checkpoint_every steps, at most
    20). Raises SceneError (one line, naming the key or the scene's problem) or ValueError
    before anything is submitted. Returns a list of dicts, one per run in run order: run,
    dir, params, status ("done" or "failed"), reason, steps, wall_seconds, stats (the last
    stats.csv row), resumed_from (the step a resumed run started from, else None), skipped
    (finished before this call).
    """
    return _Sweep(scene, params, out, steps, base_dir, client, workers).run()
