// The shipped contact scenes end to end (issue 3): every step keeps min_distance > 0, and an
// independent exact check finds no two non-adjacent surface triangles intersecting in any OBJ
// frame (obstacle meshes included) and no vertex behind an obstacle plane. Plus the physics of
// the head-on collision and thread-count independence with contact.
#include "engine/contact/barrier_potential.hpp"
#include "engine/mesh/intersection.hpp"
#include "engine/run.hpp"
#include "engine/simulation.hpp"
#include "kernels/isa.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <utility>
#include <sstream>

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

struct StatsRow {
  std::vector<double> v;  // the 14 columns of DESIGN.md section 6, in order
  double operator[](int i) const { return v[i]; }
};
enum Column { kStep = 0, kKinetic = 2, kElastic = 3, kTotal = 6, kPx = 7, kIterations = 10,
              kContacts = 11, kMinDistance = 12 };

std::vector<StatsRow> read_stats(const fs::path& file) {
  std::vector<StatsRow> rows;
  const std::vector<std::string> lines = test::read_lines(file);
  for (size_t i = 1; i < lines.size(); ++i) {
    StatsRow row;
    std::stringstream ss(lines[i]);
    for (std::string cell; std::getline(ss, cell, ',');) row.v.push_back(std::stod(cell));
    rows.push_back(row);
  }
  return rows;
}

// Vertex positions of an OBJ frame (every vertex of the model, numbered globally).
std::vector<double> obj_positions(const fs::path& file) {
  std::ifstream in(file);
  std::vector<double> x;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("v ", 0) != 0) continue;
    std::stringstream ss(line.substr(2));
    double a, b, c;
    ss >> a >> b >> c;
    x.insert(x.end(), {a, b, c});
  }
  return x;
}

// Runs a scene file for `steps` steps and checks the contact invariants on every row and every
// OBJ frame, writing into `out`. Returns the rows.
std::vector<StatsRow> run_file_and_check(const std::string& file, int steps, fs::path out) {
  const test::CommandResult r = test::run_cli("run " + file + " --quiet --steps " + std::to_string(steps) +
                                              " --out " + out.string());
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  const std::vector<StatsRow> rows = read_stats(out / "stats.csv");
  REQUIRE(rows.size() == static_cast<size_t>(steps));
  int64_t contact_steps = 0;
  for (const StatsRow& row : rows) {
    CAPTURE(row[kStep]);
    CHECK(row[kMinDistance] > 0.0);
    CHECK(std::isfinite(row[kTotal]));
    contact_steps += row[kContacts] > 0;
  }
  CHECK(contact_steps > 0);  // the scene does reach contact within the steps run

  const Scene scene = load_scene(file);
  const Model& model = scene.model;
  int frames = 0;
  for (const auto& entry : fs::directory_iterator(out / "frames")) {
    if (entry.path().extension() != ".obj") continue;
    ++frames;
    CAPTURE(entry.path().filename().string());
    const std::vector<double> x = obj_positions(entry.path());
    REQUIRE(static_cast<int64_t>(x.size()) == model.num_dofs());
    const auto crossing = intersecting_triangle_pairs(x.data(), model.surface_triangles.data(),
                                                      static_cast<int64_t>(model.surface_triangles.size() / 3));
    CHECK(crossing.empty());
    for (int32_t v : model.surface_vertices)
      for (const ObstaclePlane& plane : model.obstacle_planes)
        CHECK((Eigen::Vector3d::Map(&x[3 * v]) - plane.point).dot(plane.normal) > 0.0);
  }
  CHECK(frames >= 2);
  return rows;
}

// The same for a shipped scene, by name.
std::vector<StatsRow> run_and_check(const std::string& name, int steps, fs::path out = {}) {
  if (out.empty()) out = test::temp_dir("scene_" + name);
  return run_file_and_check(test::scene_path(name + ".json").string(), steps, out);
}

}  // namespace

TEST_CASE("scene cube_drop: lands on the plane, intersection-free") { run_and_check("cube_drop", 60); }

TEST_CASE("scene bullet_plate: a 40 m/s cube does not tunnel through a 2 cm plate") {
  const fs::path out = test::temp_dir("bullet_final");
  run_and_check("bullet_plate", 40, out);
  // At 0.2 m per step the cube would be 1.4 m below the plate after 40 steps without CCD. Every
  // vertex of the cube (body 1) must still be above the lowest point of the plate (body 0).
  const Model model = load_scene(test::scene_path("bullet_plate.json")).model;
  const std::vector<double> x = obj_positions(out / "frames" / "frame_000040.obj");
  REQUIRE(static_cast<int64_t>(x.size()) == model.num_dofs());
  double lowest[2] = {1e9, 1e9};  // plate, cube
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    double& low = lowest[model.vertex_body[v]];
    low = std::min(low, x[3 * v + 1]);
  }
  const double plate_lowest = lowest[0], cube_lowest = lowest[1];
  CHECK(cube_lowest > plate_lowest);
}

TEST_CASE("scene impact_plate: a ball at 30 m/s on a thin plate keeps every step and gains no energy") {
  // Issue 16: under Newmark this scene gained 80% of its energy in 12 steps and failed at step
  // 20. The default integrator must run it through, with the total energy (kinetic, elastic,
  // gravity, barrier) never above its start plus 1%: the plate's clamps do no work.
  const Scene scene = load_scene(test::scene_path("impact_plate.json"));
  StepStats start;
  Simulation(scene).measure(start);
  const std::vector<StatsRow> rows = run_and_check("impact_plate", 40);
  std::stringstream header(stats_header(scene));
  size_t guarded_column = 0;
  for (std::string name; std::getline(header, name, ',') && name != "guarded_steps";) ++guarded_column;
  for (const StatsRow& row : rows) {
    CAPTURE(row[kStep]);
    CHECK(row[kTotal] <= start.total_energy + 0.01 * std::abs(start.total_energy));
    // The energy guard never stepped in, so this is also generalized-alpha with rho_inf 0.5 on
    // its own. (The column is found by name: counted from the end, it had become
    // sleeping_bodies when damping_dissipated was appended, and this check then held trivially.)
    CHECK(row.v.at(guarded_column) == 0.0);
  }
}

TEST_CASE("scene cube_stack: the IPC paper's stack of five cubes, intersection-free for 5 s") {
  // The column compresses (about 8% strain at the bottom) and, frictionless, leans and topples
  // after about 1 s in this port; the invariants must hold through all of it.
  const std::vector<StatsRow> rows = run_and_check("cube_stack", 200);
  CHECK(rows[20][kContacts] >= 4 * 4);  // all four cube-cube interfaces are in contact early on
}

TEST_CASE("scene bowl_drop: a ball falls into a static mesh bowl") { run_and_check("bowl_drop", 40); }

TEST_CASE("scene pile: 100 boxes fall into a box of planes") { run_and_check("pile", 25); }

TEST_CASE("scene head_on: momentum is conserved, the boxes bounce apart, newmark keeps most energy") {
  const std::vector<StatsRow> rows = run_and_check("head_on", 80);
  const double p0 = 1000.0 * 0.008 * 1.0;  // |momentum| of one box: rho V v
  for (const StatsRow& row : rows) {
    CAPTURE(row[kStep]);
    for (int d = 0; d < 3; ++d) CHECK(std::abs(row[kPx + d]) <= 1e-6 * p0);
  }
  // Energy: none is created, and the bounce keeps most of it (the contact impulse treats the
  // surface layer like implicit Euler; see engine/potential/incremental_potential.hpp).
  const double before = rows.front()[kTotal];
  const double after = rows.back()[kTotal];
  CHECK(after <= before * (1.0 + 1e-6));
  CHECK(after >= 0.85 * before);
}

TEST_CASE("contact results do not depend on the number of threads") {
  const std::string scene = test::scene_path("head_on.json").string();
  const fs::path out1 = test::temp_dir("contact_threads1"), out2 = test::temp_dir("contact_threads2");
  REQUIRE(test::run_cli_on_threads("run " + scene + " --steps 30 --quiet --out " + out1.string(), 1).exit_code == 0);
  REQUIRE(test::run_cli_on_threads("run " + scene + " --steps 30 --quiet --out " + out2.string(), 2).exit_code == 0);
  std::vector<std::string> a = test::read_lines(out1 / "stats.csv"), b = test::read_lines(out2 / "stats.csv");
  REQUIRE(a.size() == b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    a[i] = test::without_wall_seconds(a[i]);
    b[i] = test::without_wall_seconds(b[i]);
    CHECK(a[i] == b[i]);
  }
  // and the positions and velocities are the same bit for bit: the VTU frame holds them as raw
  // doubles (the OBJ frame's text at %.9g could hide a difference in the last bits)
  auto bytes = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string frame1 = bytes(out1 / "frames" / "frame_000030.vtu");
  CHECK(frame1.size() > 10000);
  CHECK(frame1 == bytes(out2 / "frames" / "frame_000030.vtu"));
}

// Friction scenes (issue 4). Velocities come from stats.csv (momentum / mass), displacements
// from the first and last OBJ frame.
namespace {

double total_mass(const Model& model) {
  double m = 0.0;
  for (double mi : model.mass) m += mi;
  return m;
}

// Mean position of all vertices in an OBJ frame.
Eigen::Vector3d mean_position(const fs::path& frame) {
  const std::vector<double> x = obj_positions(frame);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (size_t v = 0; 3 * v < x.size(); ++v) mean += Eigen::Vector3d::Map(&x[3 * v]);
  return mean / static_cast<double>(x.size() / 3);
}

// The IPC paper's slope: a stiff unit cube on a plane of slope tan(theta) = 0.5.
struct Slope {
  fs::path out;
  std::vector<StatsRow> rows;
  Model model;
  Eigen::Vector3d down;  // unit vector down the slope
  double velocity(int row) const {
    return Eigen::Vector3d(rows[row][kPx], rows[row][kPx + 1], rows[row][kPx + 2]).dot(down) / total_mass(model);
  }
};

Slope run_slope_file(const std::string& file, const std::string& tag) {
  Slope s;
  s.out = test::temp_dir(tag);
  s.rows = run_file_and_check(file, 100, s.out);
  s.model = load_scene(file).model;
  REQUIRE(s.model.obstacle_planes.size() == 1);
  const Eigen::Vector3d n = s.model.obstacle_planes[0].normal;
  s.down = (Eigen::Vector3d(0, -1, 0) - n * n.dot(Eigen::Vector3d(0, -1, 0))).normalized();
  CHECK(n.y() / std::hypot(n.x(), n.y()) == test::relative(2 / std::sqrt(5.0), 1e-12));  // tan(theta) = 0.5
  return s;
}

Slope run_slope(const std::string& name) { return run_slope_file(test::scene_path(name + ".json").string(), name); }

using Edits = std::initializer_list<std::pair<std::string, std::string>>;

// The text of a shipped scene with each `from` replaced (its first occurrence) by its `to`.
std::string edited_scene(const std::string& name, Edits edits) {
  std::ifstream in(test::scene_path(name + ".json"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const auto& [from, to] : edits) {
    const size_t at = text.find(from);
    REQUIRE(at != std::string::npos);
    text.replace(at, from.size(), to);
  }
  return text;
}

// A shipped scene edited and written to a temporary folder, its mesh paths made absolute.
std::string edited_scene_file(const std::string& name, const std::string& tag, Edits edits) {
  std::string text = edited_scene(name, edits);
  const std::string from = "\"meshes/", to = "\"" + test::scene_path("meshes").string() + "/";
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
  return test::write_text(test::temp_dir(tag) / (tag + ".json"), text).string();
}

std::string slope_variant(const std::string& tag, Edits edits) { return edited_scene_file("slope_stick", tag, edits); }

constexpr double kG = 9.81;
const double kTheta = std::atan(0.5);

}  // namespace

TEST_CASE("scene slope_slide: mu = 0.49 < tan(theta), the cube slides at g (sin - mu cos)") {
  const Slope s = run_slope("slope_slide");
  // Rows 20 and 100: t = 0.5 s and 2.5 s (dt = 0.025), after the cube has settled on the plane.
  const double a = (s.velocity(99) - s.velocity(19)) / 2.0;
  // Sliding far above epsv the smoothed friction is mu N, and implicit Euler's velocity changes
  // are exact under a constant force: measured 1e-6 off.
  CHECK(a == test::relative(kG * (std::sin(kTheta) - 0.49 * std::cos(kTheta)), 1e-3));
}

TEST_CASE("scene slope_stick: mu = 0.51 > tan(theta), the cube sticks up to the epsv creep") {
  const Slope s = run_slope("slope_stick");
  // The smoothed friction holds the cube with a creep speed v where mu N f1(v / epsv) balances
  // the weight along the slope: f1(y) = 2 y - y^2 = tan(theta) / mu.
  const double epsv = 1e-3 * bodies_bbox_diagonal(s.model);  // the scene's default
  const double creep = epsv * (1.0 - std::sqrt(1.0 - 0.5 / 0.51));
  // Within 5%: the scene's Newton tolerance, 1e-4 m/s, is 5% of this creep speed (measured: 0.9%).
  CHECK(s.velocity(99) == test::relative(creep, 0.05));
  // The displacement along the slope over the run stays below the creep bound epsv T.
  const Eigen::Vector3d moved = mean_position(s.out / "frames" / "frame_000100.obj") -
                                mean_position(s.out / "frames" / "frame_000000.obj");
  CHECK(std::abs(moved.dot(s.down)) <= epsv * 2.5);
}

TEST_CASE("scene block_slide: a block at v0 = 1 m/s stops after v0^2 / (2 mu g)") {
  const fs::path out = test::temp_dir("block_slide");
  const std::vector<StatsRow> rows = run_and_check("block_slide", 60, out);
  CHECK(std::abs(rows.back()[kPx]) < 1e-2 * std::abs(rows.front()[kPx]));  // at rest after 0.3 s
  const Eigen::Vector3d moved = mean_position(out / "frames" / "frame_000060.obj") -
                                mean_position(out / "frames" / "frame_000000.obj");
  // Implicit Euler's x_{n+1} = x_n + h v_{n+1} falls short of the exact stopping distance by
  // h v0 / 2 (2.5 mm at h = 5 ms); corrected for that, measured 0.15% off.
  CHECK(moved.x() == test::relative(1.0 / (2 * 0.5 * kG) - 0.005 * 1.0 / 2, 0.005));
}

TEST_CASE("slope with static friction 0.6 and kinetic 0.4: held at rest, sliding once moving") {
  // tan(theta) = 0.5 lies between the two coefficients. At rest the cube sticks, creeping at the
  // speed where mu_s N f1(v / epsv) carries the weight along the slope.
  const std::string mu = R"("friction": 0.4, "static_friction": 0.6)";
  // (Newton tolerance 1e-6 m/s: the shipped 1e-4 is 8% of this creep speed.)
  const Slope rest = run_slope_file(
      slope_variant("slope_static", {{"\"friction\": 0.51", mu}, {"\"tolerance\": 0.0001", "\"tolerance\": 1e-6"}}),
      "slope_static");
  const double epsv = 1e-3 * bodies_bbox_diagonal(rest.model);
  // Within 1%: the Newton tolerance is 0.1% of the creep speed (measured: 1e-5 off).
  CHECK(rest.velocity(99) == test::relative(epsv * (1.0 - std::sqrt(1.0 - 0.5 / 0.6)), 0.01));
  // Thrown down the slope at 0.5 m/s it slides with the kinetic coefficient and speeds up.
  const Slope thrown = run_slope_file(
      slope_variant("slope_kinetic", {{"\"friction\": 0.51", mu},
                                      {"\"material\": \"stiff\"", R"("material": "stiff", "velocity": [0.4472135955, -0.2236067977, 0])"}}),
      "slope_kinetic");
  const double a = (thrown.velocity(99) - thrown.velocity(19)) / 2.0;
  CHECK(thrown.velocity(0) > 0.45);
  // As for slope_slide; the block thrown from rest on the slope vibrates a little (measured 3e-4 off).
  CHECK(a == test::relative(kG * (std::sin(kTheta) - 0.4 * std::cos(kTheta)), 2e-3));
}

TEST_CASE("friction_pairs: a block on a plane of material ice slides with the pair's coefficient") {
  // block_slide's default friction 0.5 applies to every pair but (m, ice): 0.1 there, so the
  // block thrown at 1 m/s stops after 1 / (2 0.1 g) = 0.51 m instead of 0.10 m.
  const std::string text = edited_scene("block_slide", {
      {R"("friction": 0.5)", R"("friction": 0.5, "friction_pairs": [ { "materials": ["ice", "m"], "friction": 0.1 } ])"},
      {R"("materials": {)", R"("materials": { "ice": { "model": "linear", "youngs": 1e9, "poisson": 0.3, "density": 900 },)"},
      {R"("plane": {)", R"("material": "ice", "plane": {)"}});
  const fs::path out = test::temp_dir("block_on_ice");
  const std::string file = test::write_text(out / "block_on_ice.json", text).string();
  const std::vector<StatsRow> rows = run_file_and_check(file, 240, out / "run");  // 1.2 s, stops at 1.02 s
  CHECK(std::abs(rows.back()[kPx]) < 1e-2 * std::abs(rows.front()[kPx]));
  const Eigen::Vector3d moved = mean_position(out / "run" / "frames" / "frame_000240.obj") -
                                mean_position(out / "run" / "frames" / "frame_000000.obj");
  // Less implicit Euler's h v0 / 2, as for block_slide (measured 0.03% off).
  CHECK(moved.x() == test::relative(1.0 / (2 * 0.1 * kG) - 0.005 * 1.0 / 2, 0.005));
}

TEST_CASE("scene block_push: a moving wall pushes a block along the floor, intersection-free") {
  const std::vector<StatsRow> rows = run_and_check("block_push", 100);
  // 1 kg at the wall's 0.5 m/s (measured 6e-5 off: the barrier's gap to the wall still closing)
  CHECK(rows.back()[kPx] == test::relative(0.5 * 1.0, 1e-3));
}

namespace {

// Mean x of the ball (the scene's first body, 1760 vertices) in an OBJ frame.
double ball_x(const fs::path& frame) {
  const std::vector<double> x = obj_positions(frame);
  double sum = 0.0;
  for (int v = 0; v < 1760; ++v) sum += x[3 * v];
  return sum / 1760;
}

}  // namespace

TEST_CASE("scene roller: the rotating roller grips the ball and draws it through the gap") {
  // The gap under the roller is 8.5% narrower than the ball. Turning with the ball (bottom moving
  // along +x) the roller pulls it through; turning against it, it throws the ball back.
  const fs::path out = test::temp_dir("roller");
  run_and_check("roller", 40, out);
  CHECK(ball_x(out / "frames" / "frame_000000.obj") < -0.09);
  CHECK(ball_x(out / "frames" / "frame_000040.obj") > 0.1);  // past the roller (radius 0.05 + 0.05)

  const fs::path back = test::temp_dir("roller_back");
  const std::vector<StatsRow> rows = run_file_and_check(
      edited_scene_file("roller", "roller_back", {{"\"angular_velocity\": 20", "\"angular_velocity\": -20"}}), 30, back);
  CHECK(rows.back()[kPx] < -0.05);  // moving back at more than 0.1 m/s (0.52 kg)
  CHECK(ball_x(back / "frames" / "frame_000030.obj") < ball_x(back / "frames" / "frame_000020.obj"));
}

TEST_CASE("scene stress/pile_10: mixed shapes fall into a box of planes, intersection-free") {
  const std::vector<StatsRow> rows = run_and_check("stress/pile_10", 40);
  CHECK(rows.back()[kContacts] > 0);
}

TEST_CASE("scene mat40x40_twist: the IPC mat twisted from both ends, intersection-free while it buckles") {
  // The first 1.8 s (45 steps): the ends turn by 0.72 pi each, and from step 34 the mat folds
  // onto itself; the whole 10 s is a benchmark (docs/performance.md).
  const std::vector<StatsRow> rows = run_and_check("mat40x40_twist", 45);
  CHECK(rows.back()[kContacts] > 50);
}

TEST_CASE("scene stress/pile_10: islands solved on 1 and 2 threads give bitwise equal steps") {
  // Ten bodies landing one after another: islands form, merge through contacts and friction, and
  // converge at different iterations, and the groups of the line search change from iteration to
  // iteration; none of that may depend on the thread count. 40 steps: contact from step 7 (under
  // ThreadSanitizer, its own build, 20: 137 contacts by then, and half of its 140 s).
#ifdef __SANITIZE_THREAD__
  constexpr int kSteps = 20;
#else
  constexpr int kSteps = 40;
#endif
  const std::string scene = test::scene_path("stress/pile_10.json").string();
  const fs::path out1 = test::temp_dir("pile10_threads1"), out2 = test::temp_dir("pile10_threads2");
  for (const auto& [threads, out] : {std::pair{1, out1}, std::pair{2, out2}}) {
    const test::CommandResult r = test::run_cli_on_threads(
        "run " + scene + " --steps " + std::to_string(kSteps) + " --quiet --out " + out.string(), threads);
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
  }
  std::vector<std::string> a = test::read_lines(out1 / "stats.csv"), b = test::read_lines(out2 / "stats.csv");
  REQUIRE(a.size() == kSteps + 1);
  REQUIRE(a.size() == b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    CAPTURE(i);
    a[i] = test::without_wall_seconds(a[i]);
    b[i] = test::without_wall_seconds(b[i]);
    CHECK(a[i] == b[i]);
  }
  const std::vector<StatsRow> rows = read_stats(out1 / "stats.csv");
  CHECK(rows.back()[kContacts] > 100);  // the pile has formed
  for (int step = 20; step <= kSteps; step += 20) {
    char frame[32];
    std::snprintf(frame, sizeof(frame), "frame_%06d.obj", step);
    CAPTURE(frame);
    const std::vector<std::string> f1 = test::read_lines(out1 / "frames" / frame);
    CHECK(!f1.empty());
    CHECK(f1 == test::read_lines(out2 / "frames" / frame));
  }
}

TEST_CASE("scene stress/pile_10: every instruction-set path gives bitwise equal steps") {
  // The hand-vectorised kernels (kernels/isa.hpp) are chosen at run time; forcing a narrower path
  // with NEXDYN_ISA may change the speed only. Each path this CPU runs, 40 steps on 2 threads.
  const std::string scene = test::scene_path("stress/pile_10.json").string();
  std::vector<std::string> reference_stats, reference_frame;
  for (Isa isa : kAllIsas) {
    if (static_cast<int>(isa) > static_cast<int>(detected_isa())) continue;
    CAPTURE(isa_name(isa));
    const fs::path out = test::temp_dir("pile10_isa_" + std::string(isa_name(isa)));
    setenv("NEXDYN_ISA", isa_name(isa), 1);
    const test::CommandResult r = test::run_cli("run " + scene + " --steps 40 --threads 2 --quiet --out " + out.string());
    unsetenv("NEXDYN_ISA");
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    std::vector<std::string> stats = test::read_lines(out / "stats.csv");
    REQUIRE(stats.size() == 41);
    for (std::string& row : stats) row = test::without_wall_seconds(row);
    const std::vector<std::string> frame = test::read_lines(out / "frames" / "frame_000040.obj");
    CHECK(!frame.empty());
    if (isa == Isa::scalar) {
      reference_stats = stats;
      reference_frame = frame;
      continue;
    }
    CHECK(stats == reference_stats);
    CHECK(frame == reference_frame);
  }
}

TEST_CASE("NEXDYN_ISA: a value that names no path is an error naming it, before any output") {
  const fs::path out = test::temp_dir("bad_isa");
  fs::remove_all(out);
  auto run_with = [&](const char* isa) {
    setenv("NEXDYN_ISA", isa, 1);
    const test::CommandResult r =
        test::run_cli("run " + test::scene_path("head_on.json").string() + " --steps 2 --quiet --out " + out.string());
    unsetenv("NEXDYN_ISA");
    return r;
  };
  const test::CommandResult r = run_with("avx3");
  CHECK(r.exit_code != 0);
  CHECK(r.output.find("NEXDYN_ISA=avx3") != std::string::npos);
  CHECK(r.output.find("scalar, avx2, avx512") != std::string::npos);
  CHECK(!fs::exists(out));
  if (detected_isa() != Isa::avx512) {  // asking for more than the CPU has
    const test::CommandResult wide = run_with("avx512");
    CHECK(wide.exit_code != 0);
    CHECK(wide.output.find("this CPU runs at most") != std::string::npos);
  }
}
