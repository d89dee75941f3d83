"""nexdyn.sweep and `python3 -m nexdyn sweep` (issue 41, point 2): the runs of a sweep on a local
Dask cluster and on a real dask-scheduler with dask-workers, each run equal to the same scene run
alone with the CLI; a sweep run again starts nothing; interrupted runs and runs whose worker was
killed resume from their checkpoints; a bad key or scene is refused before anything is submitted.

The runs are short pieces of scenes/cube_drop.json (its steps take a few milliseconds); nothing
here depends on the machine's speed: the killed worker is chosen by watching a run's rows grow."""

import csv
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import nexdyn
from nexdyn.sweep_runs import parse_set, split_values

# distributed 2022.12 starts its event loop the way tornado 6.2 deprecates.
pytestmark = pytest.mark.filterwarnings("ignore:make_current is deprecated:DeprecationWarning")

STEPS = 30
FRICTIONS = [0.0, 0.3]
TRANSLATES = [[0, 0.15, 0], [0, 0.12, 0]]


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.reader(f))


def json_text(value):
    return json.dumps(value, separators=(",", ":"))


def frames(folder):
    """{file name: bytes} of a run's frames/."""
    return {p.name: p.read_bytes() for p in sorted((Path(folder) / "frames").iterdir())}


def sweep_cli(build_dir, *arguments, **kwargs):
    """`python3 -m nexdyn sweep ARGUMENTS`, with the build's module."""
    env = dict(os.environ, PYTHONPATH=str(build_dir / "python"))
    return subprocess.run([sys.executable, "-m", "nexdyn", "sweep", *map(str, arguments)], env=env,
                          capture_output=True, text=True, **kwargs)


def assert_same_run_as_cli(run_dir, reference, cli_run, stats_without_wall_time, steps):
    """The run folder holds what `nexdyn run run_dir/scene.json` writes alone: stats.csv but for
    wall_seconds, and the frames, byte for byte."""
    cli_run(Path(run_dir) / "scene.json", reference, steps)
    assert stats_without_wall_time(Path(run_dir) / "stats.csv") == stats_without_wall_time(reference / "stats.csv")
    assert frames(run_dir) == frames(reference)
    assert not (Path(run_dir) / "stats.partial.csv").exists()


def file_times(folder):
    """{path: (size, mtime_ns)} of every file under `folder` but the runs' lock files."""
    times = {}
    for path in sorted(Path(folder).rglob("*")):
        if path.is_file() and path.name != ".sweep.lock":
            stat = path.stat()
            times[str(path.relative_to(folder))] = (stat.st_size, stat.st_mtime_ns)
    return times


# ---------------------------------------------------------------------------------------------
# KEY=V1,V2,... (no cluster)


def test_values_are_split_on_the_commas_outside_brackets_and_strings():
    assert split_values("0.1,0.3, 1e-3") == ["0.1", "0.3", "1e-3"]
    assert parse_set("bodies.0.velocity=[0,-1,0],[0,-2,0]") == ("bodies.0.velocity", [[0, -1, 0], [0, -2, 0]])
    assert parse_set('output.camera={"a":[1,2]},{"a":3}') == ("output.camera", [{"a": [1, 2]}, {"a": 3}])
    assert parse_set('name="a,b",c') == ("name", ["a,b", "c"])
    assert parse_set("materials.rubber.model=stvk,neohookean") == ("materials.rubber.model", ["stvk", "neohookean"])
    assert parse_set("solver.sleep=true,false") == ("solver.sleep", [True, False])
    assert parse_set("time.dt=0.01") == ("time.dt", [0.01])
    for argument, message in [("time.dt=0.1,,0.2", "value 2 .* is empty"), ("time.dt=0.1,", "value 2 .* is empty"),
                              ("bodies.0.velocity=[0,-1,0", "unclosed bracket"), ("k=[0]]", "unbalanced"),
                              ("k=[0,x,0]", "not valid JSON"), ('k="a', "unterminated string"),
                              ("time.dt", "expected KEY=V1,V2"), ("=1", "expected KEY=V1,V2")]:
        with pytest.raises(ValueError, match=message):
            parse_set(argument)


def test_each_run_s_scene_has_its_values_and_absolute_mesh_paths(tmp_path):
    # The plan alone (nothing runs): a scene with a mesh, and a value that names another mesh.
    from nexdyn.sweep_runs import _Plan
    scenes = Path(__file__).resolve().parents[2] / "scenes"
    scene = json.loads((scenes / "mixed_drop.json").read_text())
    body = next(k for k, b in enumerate(scene["bodies"]) if "mesh" in b)
    plan = _Plan(scenes / "mixed_drop.json", {f"bodies.{body}.mesh": ["meshes/cube.msh", scene["bodies"][body]["mesh"]],
                                              "time.dt": [0.01, 0.02]}, tmp_path / "out", 7, None)
    assert plan.values == [("meshes/cube.msh", 0.01), ("meshes/cube.msh", 0.02),
                           (scene["bodies"][body]["mesh"], 0.01), (scene["bodies"][body]["mesh"], 0.02)]
    for (mesh, dt), run in zip(plan.values, plan.scenes):
        assert run["bodies"][body]["mesh"] == str(scenes / mesh) and run["time"]["dt"] == dt
        assert run["time"]["steps"] == 7
        assert all(os.path.isabs(b["mesh"]) for b in run["bodies"] if "mesh" in b)
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------------------------
# (a) and (b): a 2 x 2 sweep on a local cluster of 2 workers, then the same sweep again


@pytest.fixture(scope="module")
def swept(tmp_path_factory, cube_drop_scene):
    out = tmp_path_factory.mktemp("sweep") / "out"
    rows = nexdyn.sweep(cube_drop_scene, {"contact.friction": FRICTIONS, "bodies.0.translate": TRANSLATES},
                        out, steps=STEPS, workers=2)
    return out, rows


def test_a_sweep_runs_the_product_each_run_as_the_cli_runs_it_alone(swept, cube_drop_scene, tmp_path, cli_run,
                                                                     stats_without_wall_time):
    out, rows = swept
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["0000", "0001", "0002", "0003"]
    base = json.loads(cube_drop_scene.read_text())
    runs = [(friction, translate) for friction in FRICTIONS for translate in TRANSLATES]  # the last key fastest
    stats_header = read_csv(out / "runs" / "0000" / "stats.csv")[0]
    header, *lines = read_csv(out / "sweep.csv")
    assert header == ["contact.friction", "bodies.0.translate", "status", "reason", "steps", "wall_seconds"] + \
        [name if name != "wall_seconds" else "last_wall_seconds" for name in stats_header]
    assert len(lines) == len(rows) == 4
    for number, ((friction, translate), line, row) in enumerate(zip(runs, lines, rows)):
        run_dir = out / "runs" / f"{number:04d}"
        # Its scene.json: the scene with the values set and the run's length, nothing else changed.
        scene = json.loads((run_dir / "scene.json").read_text())
        assert scene["contact"]["friction"] == friction and scene["bodies"][0]["translate"] == translate
        assert scene["time"]["steps"] == STEPS
        scene["contact"].pop("friction")
        scene["bodies"][0]["translate"] = base["bodies"][0]["translate"]
        scene["time"]["steps"] = base["time"]["steps"]
        assert scene == base
        # Its sweep.csv row: the values as JSON, done, the steps, then the last stats.csv row.
        last = read_csv(run_dir / "stats.csv")[-1]
        assert line[:5] == [json_text(friction), json_text(translate), "done", "", str(STEPS)]
        assert float(line[5]) > 0
        assert line[6:] == last
        assert row["run"] == number and row["dir"] == str(run_dir) and row["status"] == "done"
        assert row["params"] == {"contact.friction": friction, "bodies.0.translate": translate}
        assert row["steps"] == STEPS and row["stats"]["step"] == STEPS and row["resumed_from"] is None
        assert not row["skipped"]
        assert_same_run_as_cli(run_dir, tmp_path / f"cli{number}", cli_run, stats_without_wall_time, STEPS)


def test_b_the_same_sweep_again_starts_no_run(swept, cube_drop_scene, build_dir):
    out, _ = swept
    before = file_times(out / "runs")
    first_csv = (out / "sweep.csv").read_bytes()
    # The same sweep from the CLI (its values as the command line writes them), and without a
    # scheduler to reach: it must not need one.
    result = sweep_cli(build_dir, cube_drop_scene, "--set", "contact.friction=0.0,0.3",
                       "--set", "bodies.0.translate=[0,0.15,0],[0,0.12,0]", "--out", out, "--steps", STEPS,
                       "--scheduler", "tcp://127.0.0.1:9", timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("finished before") == 4, result.stdout
    assert file_times(out / "runs") == before
    assert (out / "sweep.csv").read_bytes() == first_csv


# ---------------------------------------------------------------------------------------------
# (c) a run interrupted part way is resumed from its checkpoint


def test_c_an_interrupted_run_is_resumed_from_its_checkpoint(tmp_path, cube_drop_scene, cli_run,
                                                             stats_without_wall_time):
    out = tmp_path / "out"
    run_dir = out / "runs" / "0000"
    # Run 0000 of the sweep below, started by hand: 13 steps, a checkpoint, 4 more steps, then
    # dropped without closing (as a killed process leaves it).
    scene = json.loads(cube_drop_scene.read_text())
    scene["contact"]["friction"] = 0.3
    scene["time"]["steps"] = 40
    simulation = nexdyn.Simulation(scene, out=run_dir, threads=1, checkpoint_every=20)
    simulation.step(13)
    simulation.checkpoint()
    simulation.step(4)
    del simulation
    before = read_csv(run_dir / "stats.partial.csv")
    assert len(before) == 1 + 17 and not (run_dir / "stats.csv").exists()

    rows = nexdyn.sweep(cube_drop_scene, {"contact.friction": [0.3, 0.0]}, out, steps=40, workers=1)
    assert [row["status"] for row in rows] == ["done", "done"]
    assert rows[0]["resumed_from"] == 13 and rows[1]["resumed_from"] is None
    # The 13 rows before the checkpoint are the interrupted run's own (their wall times too): the
    # run went on from the checkpoint, it did not start again.
    after = read_csv(run_dir / "stats.csv")
    assert after[:14] == before[:14] and len(after) == 41
    for number in range(2):
        assert_same_run_as_cli(out / "runs" / f"{number:04d}", tmp_path / f"cli{number}", cli_run,
                               stats_without_wall_time, 40)


# ---------------------------------------------------------------------------------------------
# (d) a real scheduler and two workers, one killed with SIGKILL in the middle of a run


def dask_command(name):
    for folder in (Path(sys.executable).parent, Path("/usr/bin")):
        if (folder / name).is_file():
            return [str(folder / name)]
    pytest.fail(f"{name} is missing (Debian: apt-get install python3-distributed)")


@pytest.fixture
def dask_cluster(tmp_path, build_dir):
    """A dask-scheduler and two dask-workers (one thread, no nanny: a killed worker stays dead),
    each in its own process group, all killed at the end. Yields (address, {worker pid: Popen})."""
    processes = []

    def start(command, log):
        env = dict(os.environ, PYTHONPATH=str(build_dir / "python"))
        process = subprocess.Popen(command, stdout=open(log, "w"), stderr=subprocess.STDOUT, env=env,
                                   cwd=tmp_path, start_new_session=True)
        processes.append(process)
        return process

    try:
        scheduler_file = tmp_path / "scheduler.json"
        scheduler = start(dask_command("dask-scheduler") + ["--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                                            "--dashboard-address", "127.0.0.1:0",
                                                            "--scheduler-file", str(scheduler_file)],
                          tmp_path / "scheduler.log")
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() or not scheduler_file.read_text().strip().endswith("}"):
            assert scheduler.poll() is None, (tmp_path / "scheduler.log").read_text()
            assert time.monotonic() < deadline, "the scheduler did not start"
            time.sleep(0.05)
        address = json.loads(scheduler_file.read_text())["address"]
        workers = {}
        for k in range(2):
            worker = start(dask_command("dask-worker") + [address, "--nthreads", "1", "--no-nanny",
                                                          "--local-directory", str(tmp_path / f"worker{k}")],
                           tmp_path / f"worker{k}.log")
            workers[worker.pid] = worker
        import distributed
        with distributed.Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
        yield address, workers
    finally:
        for process in processes:
            try:
                os.killpg(process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            process.wait()


def test_d_a_run_whose_worker_is_killed_is_resumed_on_another_worker(dask_cluster, tmp_path, cube_drop_scene,
                                                                    build_dir, cli_run, stats_without_wall_time):
    address, workers = dask_cluster
    out = tmp_path / "out"
    steps = 150
    env = dict(os.environ, PYTHONPATH=str(build_dir / "python"))
    sweep = subprocess.Popen([sys.executable, "-m", "nexdyn", "sweep", str(cube_drop_scene),
                              "--set", "contact.friction=0,0.2,0.4", "--out", str(out), "--steps", str(steps),
                              "--scheduler", address],
                             stdout=open(tmp_path / "sweep.log", "w"), stderr=subprocess.STDOUT, env=env,
                             start_new_session=True)
    try:
        # Mid-run: a run 45 steps in, not finished, whose lock names one of our workers (the
        # process stepping it). Then that worker is killed at once. The run checkpoints every 20
        # steps (its scene says 100): it has lost fewer than 20 steps.
        killed = None
        deadline = time.monotonic() + 240
        while killed is None:
            assert sweep.poll() is None, "the sweep ended before a run could be caught mid-way: " + \
                (tmp_path / "sweep.log").read_text()
            assert time.monotonic() < deadline, "no run was seen mid-way"
            for run_dir in sorted((out / "runs").glob("*")) if (out / "runs").exists() else []:
                try:
                    rows = (run_dir / "stats.partial.csv").read_text().count("\n") - 1
                    pid = int((run_dir / ".sweep.lock").read_text().split()[1])
                except (OSError, ValueError, IndexError):
                    continue
                if rows >= 45 and pid in workers and not (run_dir / "stats.csv").exists():
                    os.kill(pid, signal.SIGKILL)
                    killed = (run_dir, pid, rows)
                    break
            time.sleep(0.002)
        assert sweep.wait(timeout=300) == 0, (tmp_path / "sweep.log").read_text()
    finally:
        if sweep.poll() is None:
            os.killpg(sweep.pid, signal.SIGKILL)
            sweep.wait()
    run_dir, pid, rows = killed
    assert workers[pid].wait(timeout=30) == -signal.SIGKILL
    log = (tmp_path / "sweep.log").read_text()
    # The killed run went on from its newest checkpoint, in the other worker.
    resumed = re.search(rf"run {run_dir.name} done .*resumed from step (\d+)", log)
    assert resumed and rows - 20 < int(resumed.group(1)) < steps, log
    other = int((run_dir / ".sweep.lock").read_text().split()[1])
    assert other in workers and other != pid
    header, *lines = read_csv(out / "sweep.csv")
    assert [line[header.index("status")] for line in lines] == ["done"] * 3
    for number in range(3):
        assert_same_run_as_cli(out / "runs" / f"{number:04d}", tmp_path / f"cli{number}", cli_run,
                               stats_without_wall_time, steps)


# ---------------------------------------------------------------------------------------------
# A script without `if __name__ == "__main__":`, or read from stdin, sweeps on a local cluster


@pytest.mark.parametrize("how", ["file", "stdin"])
def test_a_script_without_a_main_guard_sweeps_on_a_local_cluster(tmp_path, cube_drop_scene, build_dir, how):
    # The workers are spawned processes, which import the main module again unless the sweep
    # hides it: this one would start its sweep in every worker (or, from stdin, name a file
    # "<stdin>" that is not there), and the workers would die at birth and be restarted forever.
    script = (f"import nexdyn\n"
              f"rows = nexdyn.sweep({str(cube_drop_scene)!r}, {{'time.dt': [0.01, 0.02]}}, {str(tmp_path / 'out')!r},\n"
              f"                    steps=3, workers=2)\n"
              f"print('statuses', [row['status'] for row in rows], __name__)\n")
    (tmp_path / "script.py").write_text(script)
    command = [sys.executable, str(tmp_path / "script.py")] if how == "file" else [sys.executable, "-"]
    process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True, env=dict(os.environ, PYTHONPATH=str(build_dir / "python")),
                               start_new_session=True)
    try:
        output, _ = process.communicate(script if how == "stdin" else None, timeout=120)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == 0 and output.count("statuses ['done', 'done'] __main__") == 1, output


# ---------------------------------------------------------------------------------------------
# (e) a bad key, value or scene is refused in one line before anything is submitted


class NoSubmit:
    """A client that fails the test if anything is submitted to it."""

    def submit(self, *args, **kwargs):
        raise AssertionError("a task was submitted")


@pytest.mark.parametrize("params, message", [
    ({"contcat.friction": [0.1]}, r"'contcat\.friction': .* has no contcat \(the keys of the top level: name,"),
    ({"bodies.1.velocity": [[0, 1, 0]]}, r"'bodies\.1\.velocity': bodies of .* is a list of 1; there is no item 1"),
    ({"bodies.first.velocity": [[0, 1, 0]]}, r"'bodies\.first\.velocity': .* 'first' is not an index"),
    ({"time.dt.x": [1]}, r"'time\.dt\.x': time\.dt of .* is the value 0\.01, not an object or a list"),
    ({"contact..friction": [1]}, r"'contact\.\.friction': an empty component"),
    # The engine reads the first run: an unknown key or a value out of range.
    ({"contact.fricton": [0.1]}, r"as run 0000 \(contact\.fricton=0\.1\): contact\.fricton: unknown key"),
    ({"contact.friction": [-1, 0.3]}, r"as run 0000 \(contact\.friction=-1\): contact\.friction: expected a number >= 0"),
])
def test_e_a_bad_key_or_value_is_refused_before_anything_is_submitted(tmp_path, cube_drop_scene, params, message):
    with pytest.raises(nexdyn.SceneError, match=message) as error:
        nexdyn.sweep(cube_drop_scene, params, tmp_path / "out", client=NoSubmit(), steps=5)
    assert "\n" not in str(error.value)
    assert not (tmp_path / "out").exists()


def test_e_the_cli_refuses_a_bad_key_with_one_line_and_exit_code_1_and_bad_usage_with_2(tmp_path, cube_drop_scene, build_dir):
    # The scheduler is not there: a sweep that tried to submit would say so instead.
    result = sweep_cli(build_dir, cube_drop_scene, "--set", "contact.friction=0.1,0.3", "--set", "contcat.dt=0.01",
                       "--out", tmp_path / "out", "--scheduler", "tcp://127.0.0.1:9", timeout=60)
    assert result.returncode == 1 and result.stdout == ""
    assert result.stderr.count("\n") == 1 and "'contcat.dt'" in result.stderr and "has no contcat" in result.stderr
    assert not (tmp_path / "out").exists()
    for arguments, message in [(["--set", "time.dt=[0.1"], "--set time.dt: unclosed bracket"),
                               (["--set", "time.dt=1", "--set", "time.dt=2"], "--set time.dt is given twice"),
                               (["--set", "time.dt=1", "--workers", "2", "--scheduler", "tcp://127.0.0.1:9"],
                                "--workers sizes a local cluster"),
                               (["--set", "time.dt=1", "--steps", "0"], "argument --steps: expected a positive integer")]:
        result = sweep_cli(build_dir, cube_drop_scene, *arguments, "--out", tmp_path / "out", timeout=60)
        assert result.returncode == 2 and message in result.stderr, result.stderr
    result = sweep_cli(build_dir, tmp_path / "missing.json", "--set", "time.dt=1", "--out", tmp_path / "out", timeout=60)
    assert result.returncode == 1 and "missing.json: cannot open the scene file" in result.stderr
    assert not (tmp_path / "out").exists()


def test_e_a_folder_of_another_sweep_is_refused(swept, cube_drop_scene):
    out, _ = swept
    with pytest.raises(ValueError, match=r"runs/0000/scene\.json is not this sweep's run 0000 .*"
                                         r"time\.steps is 30 there, 31 here"):
        nexdyn.sweep(cube_drop_scene, {"contact.friction": FRICTIONS, "bodies.0.translate": TRANSLATES}, out,
                     client=NoSubmit(), steps=31)


# ---------------------------------------------------------------------------------------------
# A later run the engine refuses fails alone; the CLI says so with exit code 1


def test_a_run_that_fails_is_a_failed_row_and_the_cli_exits_with_1(tmp_path, cube_drop_scene, build_dir):
    out = tmp_path / "out"
    result = sweep_cli(build_dir, cube_drop_scene, "--set", "contact.friction=0.3,-1", "--out", out,
                       "--steps", 5, "--workers", "1", timeout=180)
    assert result.returncode == 1, result.stdout + result.stderr
    assert "1 of 2 runs done, 1 failed" in result.stdout
    header, *lines = read_csv(out / "sweep.csv")
    status, reason, steps = (header.index(name) for name in ("status", "reason", "steps"))
    assert [line[status] for line in lines] == ["done", "failed"]
    assert lines[0][reason] == "" and lines[0][steps] == "5"
    assert "contact.friction: expected a number >= 0, got -1" in lines[1][reason] and lines[1][steps] == "0"
    assert (out / "runs" / "0000" / "stats.csv").exists() and not (out / "runs" / "0001" / "stats.csv").exists()
