// nexdyn._core: the engine's Runner (engine/run.hpp) for Python. The public names, their
// docstrings and the scene-as-dict handling are in nexdyn/__init__.py; this file is the door:
// a simulation object that steps with the GIL released, views of the state's own buffers, and
// the engine's errors as Python exceptions.
#include "engine/run.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>
#include <tbb/global_control.h>

#include <cmath>
#include <memory>
#include <optional>
#include <string>

namespace py = pybind11;

namespace nexdyn {
namespace {

// Raised for a step that failed after its halvings (the Python class is nexdyn.StepFailed).
struct StepFailedError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// stats.csv's columns that hold counts; the others are floats.
bool integer_column(const std::string& name) {
  return name == "step" || name == "newton_iterations" || name == "contacts" || name == "retries" ||
         name == "guarded_steps" || name == "sleeping_bodies";
}

class PySimulation {
 public:
  // A fresh run of the scene file `scene` (into `out` when not empty) for `steps` steps (-1: the
  // scene's time.steps with an output folder, no end without). `lock` is the folder's, when the
  // caller took it to write the scene file into it; else a folder that exists is locked before
  // anything (the scene's surface meshes) goes into it.
  PySimulation(const std::string& scene, const std::string& out, std::optional<int> threads, int64_t steps,
               int64_t checkpoint_every, std::shared_ptr<OutputLock> lock)
      : threads_(thread_limit(threads)) {
    const std::filesystem::path out_dir = out;
    if (std::error_code ec; !lock && !out_dir.empty() && std::filesystem::is_directory(out_dir, ec))
      lock = OutputLock::acquire(out_dir);
    scene_ = std::make_unique<Scene>(load_scene(scene, {}, out_dir.empty() ? out_dir : out_dir / "meshes"));
    RunOptions options;
    options.lock = std::move(lock);
    options.out_dir = out_dir;
    options.steps = steps >= 0 ? steps : out_dir.empty() ? std::numeric_limits<int64_t>::max() : -1;
    options.checkpoint_every = checkpoint_every;
    runner_ = Runner::start(*scene_, options);
  }

  // A run resumed from an output folder or a checkpoint file.
  PySimulation(const std::string& source, std::optional<int> threads) : threads_(thread_limit(threads)) {
    try {
      runner_ = Runner::resume(source, false);
    } catch (const SceneError&) {
      throw;
    } catch (const CheckpointError&) {
      throw;
    } catch (const OutputFolderBusy&) {
      throw;  // RuntimeError: another run writes the folder
    } catch (const std::runtime_error& e) {
      throw CheckpointError(e.what());  // a changed scene or mesh: the run cannot be continued
    }
  }

  // Steps n times; the GIL is released during each step. Ctrl-C abandons the step under way at its
  // next safe point (engine/stop_request.hpp; on the main thread, where Python takes its signals)
  // and raises KeyboardInterrupt with the state of the last finished step; a signal that came
  // between two steps raises its exception there. Returns the last step's stats row.
  py::dict step(int64_t n) {
    if (n < 1) throw py::value_error("step(n): n must be at least 1, got " + std::to_string(n));
    check_open();
    if (runner_->total_steps() - runner_->steps_done() < n)
      throw py::value_error("step(" + std::to_string(n) + "): the run in " + runner_->out_dir().string() + " has " +
                            std::to_string(runner_->total_steps() - runner_->steps_done()) + " of its " +
                            std::to_string(runner_->total_steps()) + " steps left");
    const py::module_ threading = py::module_::import("threading");
    const bool main_thread = threading.attr("current_thread")().is(threading.attr("main_thread")());
    for (int64_t k = 0; k < n; ++k) {
      StepOutcome outcome;
      bool interrupted = false;  // Ctrl-C during the step, which it abandoned or (no safe point left) finished
      {
        std::optional<StopSignals> interrupt;
        if (main_thread) interrupt.emplace(/*interrupt_only=*/true);
        {
          py::gil_scoped_release release;
          outcome = runner_->step();
          if (outcome.ok() && runner_->has_output() && runner_->finished()) runner_->close();
        }
        interrupted = interrupt && interrupt->received() != 0;
      }
      if (outcome.status == StepStatus::stopped || (interrupted && outcome.ok())) {
        PyErr_SetNone(PyExc_KeyboardInterrupt);
        throw py::error_already_set();
      }
      if (!outcome.ok()) {
        const std::string message = runner_->summary().message;
        throw StepFailedError(runner_->has_output() ? message + " (the last good state is in " +
                                                          runner_->summary().checkpoint + ")"
                                                    : message);
      }
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    }
    return stats();
  }

  py::dict stats() const {
    py::dict row;
    if (runner_->last_stats().step == 0) return row;  // no step taken by this process yet
    const std::string header = stats_header(runner_->scene());
    const std::string values = stats_row(runner_->last_stats());
    size_t h = 0, v = 0;
    while (h <= header.size() && v <= values.size()) {
      const size_t he = std::min(header.find(',', h), header.size());
      const size_t ve = std::min(values.find(',', v), values.size());
      const std::string name = header.substr(h, he - h), value = values.substr(v, ve - v);
      if (integer_column(name))
        row[py::str(name)] = py::int_(std::stoll(value));
      else
        row[py::str(name)] = py::float_(std::stod(value));
      h = he + 1;
      v = ve + 1;
    }
    return row;
  }

  // A read-only (n, 3) view of x or v; `self` is its base, so it keeps the simulation alive.
  py::array view(py::object self, bool velocities) {
    const std::vector<double>& buffer = velocities ? state_v() : state_x();
    const py::ssize_t n = static_cast<py::ssize_t>(buffer.size() / 3);
    py::array array(py::dtype::of<double>(), {n, py::ssize_t{3}},
                    {py::ssize_t{3 * sizeof(double)}, py::ssize_t{sizeof(double)}}, buffer.data(), self);
    array.attr("setflags")(py::arg("write") = false);
    return array;
  }

  void set_velocities(py::array_t<double, py::array::c_style | py::array::forcecast> v) {
    check_open();
    const size_t n = state_v().size() / 3;
    if (v.ndim() != 2 || static_cast<size_t>(v.shape(0)) != n || v.shape(1) != 3)
      throw py::value_error("set_velocities: expected an array of shape (" + std::to_string(n) + ", 3), got shape " +
                            std::string(py::str(py::object(v.attr("shape")))));
    const double* data = v.data();
    for (size_t i = 0; i < 3 * n; ++i)
      if (!std::isfinite(data[i]))
        throw py::value_error("set_velocities: row " + std::to_string(i / 3) + " is not finite");
    if (Simulation* simulation = runner_->simulation()) {
      simulation->set_velocities(data);
    } else {
      runner_->mpm_simulation()->set_velocities(data);
    }
  }

  std::string checkpoint(const std::string& file) {
    check_open();
    py::gil_scoped_release release;
    return runner_->checkpoint(file).string();
  }

  void close() {
    if (runner_) runner_->close();
  }

  double time() const { return runner_->time(); }
  int64_t step_index() const { return runner_->steps_done(); }
  int64_t total_steps() const { return runner_->total_steps(); }
  std::string out_dir() const { return runner_->out_dir().string(); }
  std::string scene_file() const { return runner_->scene().file.string(); }
  std::string stats_header_line() const { return stats_header(runner_->scene()); }

 private:
  static std::unique_ptr<tbb::global_control> thread_limit(std::optional<int> threads) {
    if (!threads) return nullptr;
    if (*threads < 1) throw py::value_error("threads must be at least 1, got " + std::to_string(*threads));
    return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                 static_cast<size_t>(*threads));
  }
  void check_open() const {
    if (runner_->has_output() && runner_->finished())
      throw py::value_error("the run in " + runner_->out_dir().string() + " has finished its " +
                            std::to_string(runner_->total_steps()) + " steps");
  }
  const std::vector<double>& state_x() {
    if (Simulation* s = runner_->simulation()) return s->state().x;
    return runner_->mpm_simulation()->state().particles.x;
  }
  const std::vector<double>& state_v() {
    if (Simulation* s = runner_->simulation()) return s->state().v;
    return runner_->mpm_simulation()->state().particles.v;
  }

  std::unique_ptr<tbb::global_control> threads_;
  std::unique_ptr<Scene> scene_;  // a fresh run's (a resumed runner owns its own)
  std::unique_ptr<Runner> runner_;
};

}  // namespace
}  // namespace nexdyn

PYBIND11_MODULE(_core, m) {
  using nexdyn::PySimulation;
  m.doc() = "The engine behind nexdyn.Simulation (see nexdyn/__init__.py).";
  // The exception classes are nexdyn's own (defined in __init__.py and handed in by set_errors).
  static py::object scene_error, step_failed, checkpoint_error;
  m.def("_set_errors", [](py::object scene, py::object step, py::object checkpoint) {
    scene_error = scene;
    step_failed = step;
    checkpoint_error = checkpoint;
  });
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const nexdyn::SceneError& e) {
      PyErr_SetString(scene_error ? scene_error.ptr() : PyExc_ValueError, e.what());
    } catch (const nexdyn::StepFailedError& e) {
      PyErr_SetString(step_failed ? step_failed.ptr() : PyExc_RuntimeError, e.what());
    } catch (const nexdyn::CheckpointError& e) {
      PyErr_SetString(checkpoint_error ? checkpoint_error.ptr() : PyExc_RuntimeError, e.what());
    }
  });
  // The lock of an output folder (engine/run_lock.hpp), held while the object lives: taken before
  // the scene file of a dict scene is written into the folder. OutputFolderBusy is a RuntimeError.
  py::class_<nexdyn::OutputLock, std::shared_ptr<nexdyn::OutputLock>>(m, "_OutputLock");
  m.def("_lock_folder", [](const std::string& folder) { return nexdyn::OutputLock::acquire(folder); },
        py::arg("folder"));
  py::class_<PySimulation>(m, "_Simulation")
      .def(py::init<const std::string&, const std::string&, std::optional<int>, int64_t, int64_t,
                    std::shared_ptr<nexdyn::OutputLock>>(),
           py::arg("scene"), py::arg("out"), py::arg("threads"), py::arg("steps"), py::arg("checkpoint_every"),
           py::arg("lock") = nullptr)
      .def(py::init<const std::string&, std::optional<int>>(), py::arg("source"), py::arg("threads"))
      .def("step", &PySimulation::step, py::arg("n"))
      .def("stats", &PySimulation::stats)
      .def("positions", [](py::object self) { return self.cast<PySimulation&>().view(self, false); })
      .def("velocities", [](py::object self) { return self.cast<PySimulation&>().view(self, true); })
      .def("set_velocities", &PySimulation::set_velocities, py::arg("v"))
      .def("checkpoint", &PySimulation::checkpoint, py::arg("file"))
      .def("close", &PySimulation::close)
      .def("time", &PySimulation::time)
      .def("step_index", &PySimulation::step_index)
      .def("total_steps", &PySimulation::total_steps)
      .def("out_dir", &PySimulation::out_dir)
      .def("scene_file", &PySimulation::scene_file)
      .def("stats_header", &PySimulation::stats_header_line);
}
