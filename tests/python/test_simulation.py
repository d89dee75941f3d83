"""nexdyn.Simulation: stepping from Python against the CLI, views of the engine's buffers, kicks,
errors, checkpoints and resumes, Ctrl-C, threads, docstrings and the stub (issue 41, point 1)."""

import ast
import json
import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import nexdyn

ROOT = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("NEXDYN_BUILD_DIR", ROOT / "build"))
CLI = BUILD / "nexdyn"
CUBE_DROP = ROOT / "scenes" / "cube_drop.json"


def cube_drop(**changes):
    scene = json.loads(CUBE_DROP.read_text())
    for key, value in changes.items():
        scene[key] = value
    return scene


def test_stepping_from_python_writes_the_cli_s_output_folder(tmp_path, cli_run, stats_without_wall_time):
    cli_run(CUBE_DROP, tmp_path / "cli", 30)
    sim = nexdyn.Simulation(CUBE_DROP, out=tmp_path / "py", steps=30)
    assert sim.total_steps == 30 and sim.stats is None
    for _ in range(30):
        row = sim.step()
    assert not (tmp_path / "py" / "stats.partial.csv").exists()
    assert stats_without_wall_time(tmp_path / "py" / "stats.csv") == stats_without_wall_time(tmp_path / "cli" / "stats.csv")
    # The returned row is stats.csv's last row, by column name, with the CLI's values.
    header, *rows = stats_without_wall_time(tmp_path / "cli" / "stats.csv")
    assert list(row) == header
    for name, text in zip(header, rows[-1]):
        if name != "wall_seconds":
            assert row[name] == (int(text) if isinstance(row[name], int) else float(text)), name
    assert sim.stats == row and sim.step_index == 30 and sim.time == pytest.approx(0.3)
    assert sorted(p.name for p in (tmp_path / "py" / "frames").iterdir()) == \
        sorted(p.name for p in (tmp_path / "cli" / "frames").iterdir())
    with pytest.raises(ValueError, match="finished its 30 steps"):
        sim.step()


def test_positions_and_velocities_view_the_engine_s_buffers_read_only():
    sim = nexdyn.Simulation(CUBE_DROP)
    x, v = sim.positions, sim.velocities
    assert x.shape == v.shape == (125, 3) and x.dtype == np.float64
    assert not x.flags.writeable and not v.flags.writeable and not x.flags.owndata
    with pytest.raises(ValueError):
        x[0, 0] = 1.0
    start = x.copy()
    sim.step(3)
    # The arrays taken before the steps show the new values: they are views, not copies.
    assert not np.array_equal(x, start)
    np.testing.assert_array_equal(x, sim.positions)
    np.testing.assert_array_equal(v, sim.velocities)
    assert np.shares_memory(x, sim.positions)
    # Free fall under Newmark (average acceleration) before the cube lands: exact for gravity.
    t = sim.time
    np.testing.assert_allclose(x[:, 1], start[:, 1] - 0.5 * 9.81 * t * t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(v[:, 1], -9.81 * t, rtol=0, atol=1e-12)
    del sim  # the views keep the simulation alive
    assert np.isfinite(x).all()


def test_a_kick_sets_the_momentum_and_is_checked():
    scene = cube_drop(gravity=[0, 0, 0])
    sim = nexdyn.Simulation(scene, base_dir=CUBE_DROP.parent)
    mass = 1000 * 0.2 ** 3
    kick = np.zeros(sim.velocities.shape)
    kick[:, 0] = 2.0
    kick[:, 2] = -0.5
    sim.set_velocities(kick)
    np.testing.assert_array_equal(sim.velocities, kick)
    row = sim.step(4)
    # No force acts: the momentum is the kick's, and the body moved with it.
    assert row["momentum_x"] == pytest.approx(2.0 * mass, rel=1e-12)
    assert row["momentum_z"] == pytest.approx(-0.5 * mass, rel=1e-12)
    assert row["kinetic_energy"] == pytest.approx(0.5 * mass * (4.0 + 0.25), rel=1e-9)
    with pytest.raises(ValueError, match=r"shape \(125, 3\)"):
        sim.set_velocities(np.zeros((124, 3)))
    bad = kick.copy()
    bad[7, 1] = np.nan
    with pytest.raises(ValueError, match="row 7 is not finite"):
        sim.set_velocities(bad)


def test_a_dict_scene_finds_its_meshes_against_base_dir(tmp_path, cli_run, stats_without_wall_time):
    scene = json.loads((ROOT / "scenes" / "mixed_drop.json").read_text())
    assert any("mesh" in body for body in scene["bodies"])
    with pytest.raises(nexdyn.SceneError):
        nexdyn.Simulation(scene, base_dir=tmp_path)  # the meshes are not there
    sim = nexdyn.Simulation(scene, out=tmp_path / "run", base_dir=ROOT / "scenes", steps=2)
    sim.step(2)
    written = json.loads((tmp_path / "run" / "scene.json").read_text())
    meshes = [body["mesh"] for body in written["bodies"] if "mesh" in body]
    assert meshes and all(os.path.isabs(m) and os.path.exists(m) for m in meshes)
    cli_run(tmp_path / "run" / "scene.json", tmp_path / "cli", 2)
    assert stats_without_wall_time(tmp_path / "run" / "stats.csv") == stats_without_wall_time(tmp_path / "cli" / "stats.csv")


def test_errors_are_python_exceptions_with_the_cli_s_message(tmp_path):
    scene = cube_drop()
    scene["materials"]["rubber"]["poisson"] = 0.7
    with pytest.raises(nexdyn.SceneError) as error:
        nexdyn.Simulation(scene, base_dir=CUBE_DROP.parent)
    assert isinstance(error.value, ValueError)
    bad_file = tmp_path / "bad.json"
    bad_file.write_text(json.dumps(scene))
    cli = subprocess.run([str(CLI), "check", str(bad_file)], capture_output=True, text=True)
    assert cli.returncode == 1
    with pytest.raises(nexdyn.SceneError) as from_file:
        nexdyn.Simulation(bad_file)
    assert cli.stderr.strip() == "nexdyn: error: " + str(from_file.value)
    assert "poisson" in str(from_file.value)

    failing = cube_drop(solver={"tolerance": 1e-4, "max_iterations": 1, "substep_halvings": 0})
    sim = nexdyn.Simulation(failing, base_dir=CUBE_DROP.parent)
    start = sim.positions.copy()
    with pytest.raises(nexdyn.StepFailed, match=r"step 1 .*failed \[max_iterations\]") as failed:
        sim.step(5)
    assert isinstance(failed.value, RuntimeError)
    assert sim.step_index == 0
    np.testing.assert_array_equal(sim.positions, start)
    with pytest.raises(nexdyn.CheckpointError, match="no run to resume"):
        nexdyn.Simulation.resume(tmp_path)
    with pytest.raises(ValueError, match="threads must be at least 1"):
        nexdyn.Simulation(CUBE_DROP, threads=0)


def test_a_checkpoint_file_resumes_bit_for_bit(tmp_path):
    sim = nexdyn.Simulation(CUBE_DROP)
    sim.step(15)  # the cube lands during the next steps
    path = sim.checkpoint(tmp_path / "at15.ckpt")
    rows = [sim.step() for _ in range(20)]
    resumed = nexdyn.Simulation.resume(path)
    assert resumed.step_index == 15 and resumed.stats is None
    again = [resumed.step() for _ in range(20)]
    for a, b in zip(rows, again):
        a.pop("wall_seconds"), b.pop("wall_seconds")
        assert a == b
    np.testing.assert_array_equal(sim.positions, resumed.positions)
    with pytest.raises(RuntimeError, match="needs a file"):
        sim.checkpoint()


def test_an_output_folder_resumes_as_the_cli_s_run(tmp_path, cli_run, stats_without_wall_time):
    cli_run(CUBE_DROP, tmp_path / "cli", 40)
    sim = nexdyn.Simulation(CUBE_DROP, out=tmp_path / "py", steps=40, checkpoint_every=0)
    sim.step(17)
    assert sim.checkpoint().endswith("checkpoint_000000017.ckpt")
    sim.step(3)  # rows past the checkpoint: a resume cuts them off and takes the steps again
    del sim
    resumed = nexdyn.Simulation.resume(tmp_path / "py")
    assert resumed.step_index == 17 and resumed.total_steps == 40
    resumed.step(23)
    assert stats_without_wall_time(tmp_path / "py" / "stats.csv") == stats_without_wall_time(tmp_path / "cli" / "stats.csv")
    assert not (tmp_path / "py" / "checkpoints").exists() or not list((tmp_path / "py" / "checkpoints").iterdir())


def test_results_do_not_depend_on_the_thread_count():
    one = nexdyn.Simulation(CUBE_DROP, threads=1)
    rows_one = one.step(30)
    positions_one = one.positions.copy()
    del one
    two = nexdyn.Simulation(CUBE_DROP, threads=2)
    rows_two = two.step(30)
    np.testing.assert_array_equal(positions_one, two.positions)
    rows_one.pop("wall_seconds"), rows_two.pop("wall_seconds")
    assert rows_one == rows_two


def test_ctrl_c_stops_at_a_step_boundary_and_the_simulation_goes_on(tmp_path):
    sim = nexdyn.Simulation(CUBE_DROP, out=tmp_path / "run", steps=100000, checkpoint_every=0)
    partial = tmp_path / "run" / "stats.partial.csv"

    def interrupt_after_a_few_steps():
        # Runs while the main thread is inside sim.step: the GIL is released during a step.
        while partial.read_text().count("\n") < 4:
            time.sleep(0.005)
        os.kill(os.getpid(), signal.SIGINT)

    watcher = threading.Thread(target=interrupt_after_a_few_steps)
    watcher.start()
    with pytest.raises(KeyboardInterrupt):
        sim.step(100000)
    watcher.join()
    done = sim.step_index
    assert 3 <= done < 100000
    assert partial.read_text().count("\n") == done + 1  # every step taken has its row, no half row
    assert sim.step(2)["step"] == done + 2


def test_ctrl_c_inside_a_step_abandons_it_and_the_run_goes_on_as_if_never_stopped(monkeypatch):
    # SIGINT as step 5's first Newton iteration begins (the engine's test hook, so by step count,
    # not by wall time): the step is abandoned at that safe point, not finished.
    reference = nexdyn.Simulation(CUBE_DROP)
    reference.step(4)
    at_4 = reference.positions.copy()
    reference.step(6)
    monkeypatch.setenv("NEXDYN_TEST_SIGNAL", "INT@5:newton")
    sim = nexdyn.Simulation(CUBE_DROP)
    with pytest.raises(KeyboardInterrupt):
        sim.step(10)
    assert sim.step_index == 4 and sim.stats["step"] == 4
    assert np.array_equal(sim.positions, at_4)
    sim.step(6)
    assert np.array_equal(sim.positions, reference.positions)
    assert np.array_equal(sim.velocities, reference.velocities)


def test_an_output_folder_has_one_writer(tmp_path):
    first = nexdyn.Simulation(CUBE_DROP, out=tmp_path / "run", steps=4)
    with pytest.raises(RuntimeError, match=f"another run is writing this output folder \\(process {os.getpid()}"):
        nexdyn.Simulation(CUBE_DROP, out=tmp_path / "run", steps=4)
    with pytest.raises(RuntimeError, match="another run is writing"):
        nexdyn.Simulation.resume(tmp_path / "run")
    first.step(4)  # the run finishes and lets the folder go
    assert nexdyn.Simulation(CUBE_DROP, out=tmp_path / "run", steps=4).step_index == 0
    # A dict scene is written into the folder as scene.json: not over a running one's.
    running = nexdyn.Simulation(cube_drop(), out=tmp_path / "dict", steps=4)
    written = (tmp_path / "dict" / "scene.json").read_bytes()
    with pytest.raises(RuntimeError, match="another run is writing"):
        nexdyn.Simulation(cube_drop(gravity=[0, -1, 0]), out=tmp_path / "dict", steps=4)
    assert (tmp_path / "dict" / "scene.json").read_bytes() == written
    running.step(4)


def test_every_public_name_has_a_docstring_and_is_in_the_stub():
    stub = ast.parse((Path(nexdyn.__file__).parent / "__init__.pyi").read_text())
    stub_names = {node.name for node in stub.body if isinstance(node, (ast.ClassDef, ast.FunctionDef))}
    stub_members = {node.name for cls in stub.body if isinstance(cls, ast.ClassDef) and cls.name == "Simulation"
                    for node in cls.body if isinstance(node, ast.FunctionDef)}
    for name in nexdyn.__all__:
        assert name in stub_names, name
        assert getattr(nexdyn, name).__doc__, name
    public = {name for name in vars(nexdyn.Simulation) if not name.startswith("_")}
    assert public <= stub_members, public - stub_members
    for name in public:
        assert getattr(nexdyn.Simulation, name).__doc__, name
    assert nexdyn.Simulation.__init__.__doc__ is not None or nexdyn.Simulation.__doc__


def test_a_kick_moves_an_affine_body_rigidly():
    scene = json.loads((ROOT / "scenes" / "affine_spin.json").read_text())
    scene["bodies"][0]["angular_velocity"] = [0, 0, 0]
    sim = nexdyn.Simulation(scene, base_dir=ROOT / "scenes")
    x = sim.positions
    vertices = 4 * 3 * 2  # the box's 4 x 3 x 2 grid of vertices; the four coordinate nodes follow
    assert x.shape == (vertices + 4, 3)
    centre = x[vertices]
    u, w = np.array([0.3, -0.2, 0.1]), np.array([1.0, -2.0, 0.5])
    kick = np.full(x.shape, 1e3)  # the nodes' rows are not read
    kick[:vertices] = u + np.cross(w, x[:vertices] - centre)
    sim.set_velocities(kick)
    v = sim.velocities
    np.testing.assert_allclose(v[:vertices], kick[:vertices], rtol=0, atol=1e-12)
    np.testing.assert_allclose(v[vertices], u, rtol=0, atol=1e-12)
    np.testing.assert_allclose(v[vertices + 1:], np.cross(w, x[vertices + 1:]), rtol=0, atol=1e-12)
    mass = 7800 * 0.3 * 0.2 * 0.1
    row = sim.step()
    np.testing.assert_allclose([row["momentum_x"], row["momentum_y"], row["momentum_z"]], mass * u, rtol=1e-12)


def test_resuming_a_run_whose_scene_changed_is_a_checkpoint_error(tmp_path):
    scene_file = tmp_path / "drop.json"
    scene_file.write_text(json.dumps(nexdyn.resolve_mesh_paths(cube_drop(), CUBE_DROP.parent)))
    sim = nexdyn.Simulation(scene_file, out=tmp_path / "run", steps=20, checkpoint_every=5)
    sim.step(12)
    del sim
    scene_file.write_text(scene_file.read_text() + " ")  # one byte more: another file
    with pytest.raises(nexdyn.CheckpointError, match="changed since the run started"):
        nexdyn.Simulation.resume(tmp_path / "run")


def test_a_kick_wakes_a_sleeping_body():
    scene = cube_drop()
    scene["time"]["integrator"] = "implicit_euler"  # lands and comes to rest within a second
    sim = nexdyn.Simulation(scene, base_dir=CUBE_DROP.parent)
    for _ in range(300):
        if sim.step()["sleeping_bodies"] == 1:
            break
    assert sim.stats["sleeping_bodies"] == 1
    height = sim.positions[:, 1].mean()
    kick = np.zeros(sim.velocities.shape)
    kick[:, 1] = 1.0
    sim.set_velocities(kick)
    row = sim.step()
    # Awake and solved again: it rose (a sleeping body's vertices are held where they are).
    assert row["sleeping_bodies"] == 0
    assert sim.positions[:, 1].mean() - height > 0.005
