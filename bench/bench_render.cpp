// `nexdyn render`'s cost: one 1920x1080 picture of the 1,000-body pile (scenes/stress/pile_1000,
// its start state), on 1 and 2 threads. BM_RenderFrame is what the command spends per frame
// after reading it: surface extraction, the Embree BVH build and one primary ray plus one shadow
// ray per pixel; BM_EncodePng the PNG writing of that picture.
#include "engine/output/frame_writer.hpp"
#include "engine/render/png_file.hpp"
#include "engine/render/render_command.hpp"
#include "engine/scene/scene.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <filesystem>

namespace {

using namespace nexdyn;

struct PileFrame {
  FrameData frame;
  SceneView view;
  RenderOptions options;
  RenderSetting setting;
};

const PileFrame& pile_frame() {
  static const PileFrame pile = [] {
    const Scene scene = load_scene(std::filesystem::path(NEXDYN_SOURCE_DIR) / "scenes/stress/pile_1000.json");
    PileFrame p;
    p.frame = parse_vtu_frame(vtu_document(scene.model, scene.initial.x, scene.initial.v), "pile_1000");
    p.view = scene_view(scene);
    p.options.width = 1920;
    p.options.height = 1080;
    p.setting = choose_render_setting(p.options, p.view, p.frame, p.frame);
    return p;
  }();
  return pile;
}

void BM_RenderFrame(benchmark::State& state) {
  const PileFrame& p = pile_frame();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(render_frame(p.frame, p.view, p.setting, p.options, "pile_1000"));
  state.counters["pixels_per_second"] =
      benchmark::Counter(1920.0 * 1080.0, benchmark::Counter::kIsIterationInvariantRate);
}

void BM_EncodePng(benchmark::State& state) {
  const PileFrame& p = pile_frame();
  const Image image = render_frame(p.frame, p.view, p.setting, p.options, "pile_1000");
  const auto file = std::filesystem::temp_directory_path() / "nexdyn_bench_render.png";
  for (auto _ : state) write_png(file, image);
  std::filesystem::remove(file);
}

}  // namespace

BENCHMARK(BM_RenderFrame)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_EncodePng)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_MAIN();
