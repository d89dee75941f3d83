// `nexdyn render`: pictures checked against what the geometry predicts, the same bytes on 1 and
// 2 threads, the VTU and PNG files read back, and the command's one-line errors.
#include "engine/mesh/box_mesher.hpp"
#include "engine/mesh/surface.hpp"
#include "engine/output/frame_writer.hpp"
#include "engine/render/png_file.hpp"
#include "engine/render/render_command.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/threads_support.hpp"

#include <tbb/global_control.h>

#include <cmath>
#include <fstream>

namespace nexdyn {
namespace {

// A unit cube centred at `center` as render input, one body.
RenderInput unit_cube(const Eigen::Vector3d& center = Eigen::Vector3d::Zero()) {
  const TetMesh box = make_box_mesh(Eigen::Vector3d::Ones(), {2, 2, 2});
  const SurfaceMesh surface = extract_surface(box);
  RenderInput in;
  for (int32_t v = 0; v < box.num_vertices(); ++v)
    for (int d = 0; d < 3; ++d) in.positions.push_back(static_cast<float>(box.positions[3 * v + d] + center[d]));
  in.triangles.assign(surface.triangles.begin(), surface.triangles.end());
  in.triangle_body.assign(in.triangles.size() / 3, 0);
  return in;
}

// The box mesher's cube is centred on the origin.
const Eigen::Vector3d kCubeCenter = Eigen::Vector3d::Zero();

int64_t pixels_differing(const Image& a, const Image& b) {
  int64_t count = 0;
  for (size_t p = 0; p < a.rgb.size(); p += 3)
    count += a.rgb[p] != b.rgb[p] || a.rgb[p + 1] != b.rgb[p + 1] || a.rgb[p + 2] != b.rgb[p + 2];
  return count;
}

bool same_pixel(const Image& a, const Image& b, int i, int j) {
  const size_t p = 3 * (size_t(j) * size_t(a.width) + size_t(i));
  return a.rgb[p] == b.rgb[p] && a.rgb[p + 1] == b.rgb[p + 1] && a.rgb[p + 2] == b.rgb[p + 2];
}

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST_CASE("render: a unit cube seen along an axis covers the pixels its projection predicts") {
  // Eye on the cube's axis at distance D from its centre: the silhouette is the front face, a
  // square of side 1 at distance D - 1/2, so its side in pixels is height / (2 tan(fov/2) (D - 1/2)).
  const int size = 600;
  const double fov = 40.0;
  for (const double distance : {3.0, 5.0}) {
    RenderCamera camera;
    camera.position = kCubeCenter + Eigen::Vector3d(0.0, 0.0, distance);
    camera.target = kCubeCenter;
    camera.fov_deg = fov;
    RenderInput cube = unit_cube();
    RenderInput empty = cube;
    empty.triangles.clear();
    empty.triangle_body.clear();
    const Image with = render_image(cube, camera, size, size, ColorBy::body);
    const Image without = render_image(empty, camera, size, size, ColorBy::body);
    const double side = size / (2.0 * std::tan(0.5 * fov * M_PI / 180.0) * (distance - 0.5));
    const double predicted = side * side;
    CAPTURE(distance);
    CHECK(static_cast<double>(pixels_differing(with, without)) == doctest::Approx(predicted).epsilon(0.01));
    // The centre shows the cube, a corner (behind nothing) the background.
    CHECK_FALSE(same_pixel(with, without, size / 2, size / 2));
    CHECK(same_pixel(with, without, 2, 2));
    CHECK(same_pixel(with, without, size - 3, size - 3));
    // Just outside the predicted square on the right: background; just inside: cube.
    const int half = static_cast<int>(std::floor(0.5 * side));
    CHECK(same_pixel(with, without, size / 2 + half + 2, size / 2));
    CHECK_FALSE(same_pixel(with, without, size / 2 + half - 2, size / 2));
  }
}

TEST_CASE("render: a plane below the cube shows its grid, and is hidden from behind") {
  RenderInput in = unit_cube();
  in.planes.push_back({Eigen::Vector3d(0.0, -0.51, 0.0), Eigen::Vector3d::UnitY()});
  in.grid_spacing = 0.25;
  const RenderCamera camera = fit_camera(Eigen::Vector3d::Constant(-0.5), Eigen::Vector3d::Constant(0.5),
                                         Eigen::Vector3d::UnitY(), 40.0, 1.0);
  const Image picture = render_image(in, camera, 200, 200, ColorBy::body);
  RenderInput no_plane = in;
  no_plane.planes.clear();
  const Image bare = render_image(no_plane, camera, 200, 200, ColorBy::body);
  // The plane covers the lower part of the picture (the camera looks down on it).
  CHECK(pixels_differing(picture, bare) > 200 * 200 / 5);
  // Seen from below, the plane is invisible (only its normal's side is drawn).
  RenderCamera below = camera;
  below.position.y() = -3.0;
  const Image from_below = render_image(in, below, 200, 200, ColorBy::body);
  const Image from_below_bare = render_image(no_plane, below, 200, 200, ColorBy::body);
  CHECK(pixels_differing(from_below, from_below_bare) == 0);
}

TEST_CASE("render: the fitted camera sees the whole box") {
  const Eigen::Vector3d lower(-1.0, 0.0, -0.2), upper(3.0, 0.5, 0.2);
  for (const double aspect : {0.5, 1.0, 16.0 / 9.0}) {
    const RenderCamera c = fit_camera(lower, upper, Eigen::Vector3d::UnitY(), 40.0, aspect);
    const Eigen::Vector3d forward = (c.target - c.position).normalized();
    const Eigen::Vector3d right = forward.cross(c.up).normalized(), up = right.cross(forward);
    const double tan_half = std::tan(0.5 * c.fov_deg * M_PI / 180.0);
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3d p((corner & 1) ? upper.x() : lower.x(), (corner & 2) ? upper.y() : lower.y(),
                              (corner & 4) ? upper.z() : lower.z());
      const Eigen::Vector3d q = p - c.position;
      const double depth = q.dot(forward);
      REQUIRE(depth > 0.0);
      CHECK(std::abs(q.dot(right) / depth) < tan_half * aspect);
      CHECK(std::abs(q.dot(up) / depth) < tan_half);
    }
  }
}

TEST_CASE("render: pictures are the same bytes on 1 and 2 threads") {
  // Twenty-seven cubes on a plane, coloured by a value: shadows, the grid and interpolation.
  RenderInput in;
  for (int k = 0; k < 27; ++k) {
    const RenderInput cube = unit_cube(Eigen::Vector3d(1.3 * (k % 3), 1.3 * (k / 9), 1.3 * ((k / 3) % 3)));
    const uint32_t base = static_cast<uint32_t>(in.positions.size() / 3);
    in.positions.insert(in.positions.end(), cube.positions.begin(), cube.positions.end());
    for (uint32_t id : cube.triangles) in.triangles.push_back(base + id);
    in.triangle_body.insert(in.triangle_body.end(), cube.triangles.size() / 3, k);
  }
  for (size_t v = 0; v < in.positions.size() / 3; ++v) in.vertex_value.push_back(in.positions[3 * v + 1]);
  in.value_max = 4.0f;
  in.planes.push_back({Eigen::Vector3d(0.0, -0.55, 0.0), Eigen::Vector3d::UnitY()});
  const RenderCamera camera = fit_camera(Eigen::Vector3d::Constant(-0.5), Eigen::Vector3d::Constant(3.1),
                                         Eigen::Vector3d::UnitY(), 40.0, 4.0 / 3.0);
  for (const ColorBy color : {ColorBy::body, ColorBy::value}) {
    Image one, two;
    {
      test::ThreadsScope threads(1);
      one = render_image(in, camera, 320, 240, color);
    }
    {
      test::ThreadsScope threads(2);
      two = render_image(in, camera, 320, 240, color);
    }
    CHECK(one.rgb == two.rgb);
  }
}

TEST_CASE("render: PNG files read back to the picture written") {
  Image image;
  image.width = 37;
  image.height = 11;
  for (int k = 0; k < 37 * 11 * 3; ++k) image.rgb.push_back(static_cast<uint8_t>((k * 7919) % 256));
  const auto dir = test::temp_dir("png");
  write_png(dir / "a.png", image);
  const Image back = read_png(dir / "a.png");
  CHECK(back.width == 37);
  CHECK(back.height == 11);
  CHECK(back.rgb == image.rgb);
  CHECK_FALSE(std::filesystem::exists(dir / "a.png.tmp"));
  CHECK_THROWS_WITH_AS(write_png(dir / "no_such_folder" / "b.png", image),
                       doctest::Contains("no_such_folder/b.png.tmp: cannot open for writing"), std::runtime_error);
}

TEST_CASE("render: VTU frames read back to what the run wrote, and bad ones are one line") {
  const Scene scene = test::scene_from_json(R"({
    "materials": {"m": {"model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000}},
    "bodies": [{"box": {"size": [1, 0.5, 0.25], "cells": [2, 1, 1]}, "material": "m", "velocity": [1, 2, 3]}]
  })", "vtu");
  const std::string vtu = vtu_document(scene.model, scene.initial.x, scene.initial.v);
  const FrameData frame = parse_vtu_frame(vtu, "f.vtu");
  CHECK(frame.points == scene.initial.x);
  CHECK(frame.velocity == scene.initial.v);
  CHECK(frame.tets == scene.model.tets);
  CHECK(frame.body == scene.model.vertex_body);
  CHECK_THROWS_WITH_AS(parse_vtu_frame(vtu.substr(0, vtu.size() - 200), "f.vtu"),
                       doctest::Contains("f.vtu: DataArray"), std::runtime_error);
  CHECK_THROWS_WITH_AS(parse_vtu_frame("<xml/>", "g.vtu"), doctest::Contains("g.vtu: not a VTU frame"),
                       std::runtime_error);
}

TEST_CASE("render: output.camera reaches view.json, and a bad one is refused naming the key") {
  const std::string head = R"({"gravity": [0, 0, -9.81],
    "materials": {"m": {"model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000}},
    "bodies": [{"box": {"size": [1, 1, 1], "cells": [1, 1, 1]}, "material": "m"}],)";
  const Scene scene = test::scene_from_json(head + R"("output": {"camera": {"position": [3, -4, 2],
    "target": [0, 0, 0.5], "fov_deg": 30}}})", "camera");
  const SceneView view = scene_view(scene);
  CHECK(view.up == Eigen::Vector3d::UnitZ());  // against gravity
  REQUIRE(view.camera.has_value());
  CHECK(view.camera->position == Eigen::Vector3d(3, -4, 2));
  CHECK(view.camera->target == Eigen::Vector3d(0, 0, 0.5));
  CHECK(view.camera->up == Eigen::Vector3d::UnitZ());
  CHECK(view.camera->fov_deg == 30.0);
  // view.json carries it unchanged.
  const auto dir = test::temp_dir("view");
  test::write_text(dir / "view.json", view_document(view));
  const SceneView back = read_view(dir);
  REQUIRE(back.camera.has_value());
  CHECK(back.camera->position == view.camera->position);
  CHECK(back.camera->fov_deg == 30.0);
  CHECK_THROWS_WITH_AS(test::scene_from_json(head + R"("output": {"camera": {"position": [3, -4, 2]}}})", "c2"),
                       doctest::Contains("output.camera: needs \"position\" and \"target\""), SceneError);
  CHECK_THROWS_WITH_AS(test::scene_from_json(head + R"("output": {"camera": {"position": [0, 0, 2],
    "target": [0, 0, 0]}}})", "c3"), doctest::Contains("output.camera: looks straight along the up"), SceneError);
  test::write_text(dir / "view.json", "{\"format\": 1}");
  CHECK_THROWS_WITH_AS(read_view(dir), doctest::Contains("view.json: malformed"), std::runtime_error);
}

// A short run of cube_drop (contact with a plane) to render.
std::filesystem::path cube_drop_run(const std::string& tag) {
  const auto dir = test::temp_dir(tag);
  const auto result = test::run_cli("run " + test::scene_path("cube_drop.json").string() + " --steps 6 --out " +
                                    dir.string() + " --quiet");
  REQUIRE(result.exit_code == 0);
  return dir;
}

TEST_CASE("render CLI: the last frame by default, the same bytes on 1 and 2 threads") {
  const auto dir = cube_drop_run("render_cli");
  const auto one = test::run_cli_on_threads("render " + dir.string() + " --size 320x200 --out " + (dir / "one").string(), 1);
  REQUIRE(one.exit_code == 0);
  const auto two = test::run_cli_on_threads("render " + dir.string() + " --size 320x200 --out " + (dir / "two").string(), 2);
  REQUIRE(two.exit_code == 0);
  const std::vector<FrameEntry> frames = read_frame_list(dir);
  char name[32];
  std::snprintf(name, sizeof name, "frame_%06lld.png", static_cast<long long>(frames.back().number));
  CHECK(one.output.find(name) != std::string::npos);
  const Image picture = read_png(dir / "one" / name);
  CHECK(picture.width == 320);
  CHECK(picture.height == 200);
  CHECK(file_bytes(dir / "one" / name) == file_bytes(dir / "two" / name));
  // --all: one picture per frame, and --color speed differs from --color body.
  const auto all = test::run_cli("render " + dir.string() + " --all --size 64x48 --color speed --out " +
                                 (dir / "all").string());
  REQUIRE(all.exit_code == 0);
  size_t pictures = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir / "all")) pictures += entry.path().extension() == ".png";
  CHECK(pictures == frames.size());
}

TEST_CASE("render CLI: --color speed paints the moving body red and the one at rest dark blue") {
  // No gravity: body 0 (orange in --color body) rests at x = +0.3, body 1 (blue) moves at 3 m/s
  // along z at x = -0.3. Seen along -z, the moving one is on the left. By speed, the fastest
  // vertex is the colour map's top (red, 0.85 0.22 0.15) and a vertex at rest its bottom (dark
  // blue, 0.16 0.18 0.50); shading scales a pixel's three channels alike, so the ratio of red to
  // blue over a body's pixels tells the two apart. Both are the opposite of the bodies' own
  // colours, so a speed picture drawn in body colours fails too.
  const auto dir = test::temp_dir("render_speed");
  const auto scene = test::write_text(dir / "two.json", R"({
    "time": { "dt": 0.01, "steps": 1 },
    "materials": { "m": { "model": "neohookean", "youngs": 1e6, "poisson": 0.3, "density": 1000 } },
    "bodies": [
      { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "m", "translate": [0.3, 0, 0] },
      { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "m", "translate": [-0.3, 0, 0],
        "velocity": [0, 0, 3] } ],
    "output": { "every": 1 } })");
  REQUIRE(test::run_cli("run " + scene.string() + " --quiet --out " + (dir / "run").string()).exit_code == 0);
  const std::string camera = " --frame 1 --size 320x240 --camera 0,0,2,0,0,0,40 --out ";
  for (const std::string color : {"speed", "body"}) {
    CAPTURE(color);
    const std::filesystem::path out = dir / color;
    REQUIRE(test::run_cli("render " + (dir / "run").string() + camera + out.string() + " --color " + color).exit_code == 0);
    const Image picture = read_png(out / "frame_000001.png");
    // Rows just above the horizon hold the two bodies and the sky only (the ground grid lies below
    // the bodies); the sky's colour depends on the row alone, so a pixel that differs from its
    // row's first pixel is a body's.
    double red[2] = {0, 0}, blue[2] = {0, 0};
    int64_t pixels[2] = {0, 0};
    for (int j = picture.height / 2 - picture.height / 20; j < picture.height / 2; ++j) {
      const uint8_t* row = &picture.rgb[3 * size_t(j) * size_t(picture.width)];
      for (int i = 0; i < picture.width; ++i) {
        const uint8_t* p = row + 3 * i;
        if (p[0] == row[0] && p[1] == row[1] && p[2] == row[2]) continue;
        const int side = i < picture.width / 2 ? 0 : 1;  // 0: the moving body, 1: the one at rest
        red[side] += p[0];
        blue[side] += p[2];
        ++pixels[side];
      }
    }
    MESSAGE(color << ": moving body " << pixels[0] << " pixels, red / blue " << red[0] / blue[0] << "; body at rest "
                  << pixels[1] << " pixels, red / blue " << red[1] / blue[1]);
    REQUIRE(pixels[0] > 200);
    REQUIRE(pixels[1] > 200);
    if (color == "speed") {
      CHECK(red[0] > 3.0 * blue[0]);  // 0.85 / 0.15 at the top of the map
      CHECK(blue[1] > 2.0 * red[1]);  // 0.50 / 0.16 at the bottom
    } else {
      CHECK(blue[0] > red[0]);  // body 1 is blue, body 0 orange: the other way round
      CHECK(red[1] > blue[1]);
    }
  }
}

TEST_CASE("render CLI: bad input is one line and writes nothing") {
  const auto dir = cube_drop_run("render_bad");
  const auto one_line = [](const test::CommandResult& r) {
    return r.exit_code == 1 && r.output.find('\n') == r.output.size() - 1;
  };
  const auto missing = test::run_cli("render " + (dir / "nope").string());
  CHECK(one_line(missing));
  CHECK(missing.output.find("scene.pvd: no such file") != std::string::npos);
  const auto frame = test::run_cli("render " + dir.string() + " --frame 999");
  CHECK(one_line(frame));
  CHECK(frame.output.find("no frame 999 (frames 0 to") != std::string::npos);
  const auto size = test::run_cli("render " + dir.string() + " --size 12by7");
  CHECK(one_line(size));
  CHECK(size.output.find("--size expects WxH") != std::string::npos);
  const auto camera = test::run_cli("render " + dir.string() + " --camera 1,2,3");
  CHECK(one_line(camera));
  CHECK(camera.output.find("--camera expects") != std::string::npos);
  const auto video = test::run_cli("render " + dir.string() + " --video x.mp4");
  CHECK(one_line(video));
  CHECK(video.output.find("--video needs --all") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir / "render"));
  // A damaged frame names its file.
  const std::vector<FrameEntry> frames = read_frame_list(dir);
  std::filesystem::resize_file(frames.back().file, 300);
  const auto damaged = test::run_cli("render " + dir.string());
  CHECK(one_line(damaged));
  CHECK(damaged.output.find(frames.back().file.filename().string()) != std::string::npos);
}

}  // namespace
}  // namespace nexdyn
