// A scene: the Model and initial State built from a JSON scene file, plus the run settings.
//
// Every key of the file is documented in docs/scenes.md. Loading is strict: unknown keys, wrong
// types, out-of-range values and missing files throw SceneError naming the file, the key path
// (e.g. "bodies[2].material") and the offending value, on one line. Nothing is written while
// loading.
//
// load_scene (scene.cpp) is built from three layers: the strict JSON reader (json_reader.hpp),
// the settings readers (settings_readers.hpp) and the model builder (build_model.hpp).
#pragma once

#include "engine/integrator.hpp"
#include "engine/model.hpp"
#include "engine/mpm/mpm_model.hpp"
#include "engine/scene/scene_error.hpp"
#include "engine/solver/linear_solver_kind.hpp"
#include "engine/state.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace nexdyn {

struct TimeSettings {
  double dt = 0.01;                  // [s]
  int64_t steps = 100;
  IntegratorParams integrator = default_integrator();  // generalized_alpha, rho_inf 0.5
  bool consistent_initial_acceleration = true;  // a0 = M^-1 f(x0); false: a0 = 0
  // Retake with implicit Euler any step whose integration would create energy (docs/scenes.md).
  bool energy_guard = true;
};

inline constexpr int kMaxSubstepHalvings = 16;

// Sleeping bodies (engine/sleeping.hpp), "solver": {"sleep": ...}.
struct SleepSettings {
  bool enabled = true;    // on by default; only scenes with contact have bodies that can rest
  double velocity = 0.0;  // [m/s] rest speed; 0 = 10x the Newton tolerance (solver.tolerance)
  int steps = 10;         // steps at rest before a contact group sleeps
};

// How an implicit step is solved ("solver.method"; docs/scenes.md says what each supports).
enum class SolverMethod : uint8_t {
  newton,               // Newton on the incremental potential with every term (the default)
  linearized,           // one linear solve of the potential's quadratic model at x_n (Baraff-Witkin)
  projective_dynamics,  // local-global iterations on the arap energy (engine/solver/projective_dynamics.hpp)
};
struct SolverSettings {
  SolverMethod method = SolverMethod::newton;
  LinearSolverKind linear = LinearSolverKind::cholmod;
  bool chebyshev = true;     // Projective Dynamics: Chebyshev semi-iterative acceleration
  double chebyshev_rho = 0;  // its spectral radius; 0 = estimated
  double tolerance = 1e-5;  // [m/s] Newton increment divided by dt
  int max_iterations = 100;
  double joint_tolerance = 0.0;  // [m] largest joint violation accepted; 0 = default, 1e-9 of
                                 // the bodies' bounding-box diagonal
  int substep_halvings = 4;  // a failed step is retried as two of half the dt, this deep at most
  SleepSettings sleep;
};

struct ContactSettings {
  bool enabled = false;   // true when the scene has a "contact" object, unless "enabled": false
  double dhat = 0.0;      // [m]; 0 = default, resolved by the contact code: 1e-3 of the
                          // bounding-box diagonal of the tet bodies (obstacles excluded)
  double friction = 0.0;  // Coulomb coefficient, kinetic (0: frictionless)
  double static_friction = -1.0;  // static Coulomb coefficient, >= friction; < 0: = friction
  // A per-material-pair override of the two coefficients (material indices, a <= b).
  struct FrictionPair {
    int32_t a = 0, b = 0;
    double friction = 0.0, static_friction = 0.0;
  };
  std::vector<FrictionPair> friction_pairs;
  double epsv = 0.0;      // [m/s] sticking slip speed; 0 = default, 1e-3 of the bounding-box
                          // diagonal per second
  int friction_iterations = -1;  // lagging iterations per step; -1 (the default): until the normal
                                 // forces settle (at most kMaxFrictionLags)
  bool has_friction() const {
    bool any = friction > 0.0 || static_friction > 0.0;
    for (const FrictionPair& pair : friction_pairs) any = any || pair.static_friction > 0.0;
    return enabled && any;
  }
};

// Where `nexdyn render` looks from ("output.camera"); without it the camera is fitted to the
// bodies' bounds.
struct CameraSettings {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // [m]
  Eigen::Vector3d target = Eigen::Vector3d::Zero();    // [m], the point at the picture's centre
  Eigen::Vector3d up = Eigen::Vector3d::Zero();        // not given: against gravity (+y without)
  double fov_deg = 40.0;                               // vertical field of view
};

struct OutputSettings {
  int64_t every = 1;  // write a frame every this many steps
  int64_t checkpoint_every = 100;  // write a checkpoint every this many steps (0: only on a signal)
  bool vtu = true;
  bool obj = false;
  bool bodies = false;  // frames/bodies_NNNNNN.csv: one row per body (engine/output/frame_writer.hpp)
  std::optional<CameraSettings> camera;
};

struct Scene {
  std::string name;
  std::filesystem::path file;
  TimeSettings time;
  SolverSettings solver;
  ContactSettings contact;
  OutputSettings output;
  Model model;
  State initial;  // x = start positions, v = body velocities (0 for obstacle vertices),
                  // a = 0 (set by the simulation)
  // A scene of particle bodies (issue 23): its grid, particles and boundary conditions. Such a
  // scene has no tets: `model` holds only its materials and gravity, `initial` is empty, and
  // MpmSimulation (engine/mpm/mpm_simulation.hpp) steps it.
  std::optional<MpmModel> mpm;
};

// How large a scene may be. A few bytes of JSON can ask for a box of 10^9 cells or a million
// copies of a mesh: the loader checks what a body would add before building it and refuses a
// scene past these limits with a SceneError naming the key. The defaults are far above any
// scene the engine can step in reasonable time (scripts/make_mat.py 1000 is 2M vertices and
// 6M tets); tests and fuzzers pass smaller ones.
struct SceneLimits {
  int64_t max_vertices = 20'000'000;   // bodies and obstacle meshes together
  int64_t max_tets = 100'000'000;
  int64_t max_materials = 1'000;       // friction keeps a table of every pair
};

// Reads, checks and builds the scene in `file`. Bodies given as surfaces (.obj, .stl, .ply) are
// tetrahedralised, and the tets kept in `mesh_cache_dir` (the run's DIR/meshes) to be reused
// while the surface and its settings stay the same; an empty folder keeps nothing.
Scene load_scene(const std::filesystem::path& file, const SceneLimits& limits = {},
                 const std::filesystem::path& mesh_cache_dir = {});

// The scene's "name" (by default the file's stem), as load_scene reads it: the default output
// folder is out/<name>.
std::string scene_name(const std::filesystem::path& file);

}  // namespace nexdyn
