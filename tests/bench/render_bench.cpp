// Time to render one 1280x512 camera frame in the simulator (Google
// Benchmark), per illumination, on the city grid (most markings per frame).
// The drive advances 1 m per iteration, so the view keeps changing.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>

#include "app/perception/camera_model.hpp"
#include "sim/render.hpp"
#include "sim/world.hpp"

namespace {

using namespace markloop;

void BM_RenderFrame(benchmark::State& state) {
  static const auto scenario = sim::make_scenario("grid", 1);
  static const auto camera = perception::default_camera_model();
  sim::Renderer renderer(camera, *scenario);
  sim::Conditions conditions;
  conditions.light = static_cast<sim::Illumination>(state.range(0));
  conditions.occluder_probability = 1.0;
  cv::Mat image;
  std::vector<sim::Occluder> occluders;
  occluders.reserve(4);
  double s = 0.0;
  std::uint64_t frame = 0;
  for (auto _ : state) {
    const Pose2 pose = scenario->road.at(s);
    sim::occluders_at(conditions, 0.1 * static_cast<double>(frame), scenario->road, s, pose, 3.5, occluders);
    renderer.render(pose, 10.0, conditions, frame, occluders, image);
    benchmark::DoNotOptimize(image.data);
    s = s + 1.0 < scenario->road.length() ? s + 1.0 : 0.0;
    ++frame;
  }
  state.SetLabel(std::string(sim::illumination_name(conditions.light)));
}
BENCHMARK(BM_RenderFrame)->DenseRange(0, 3)->Unit(benchmark::kMillisecond);

void BM_VisibleMarkings(benchmark::State& state) {
  static const auto scenario = sim::make_scenario("grid", 1);
  static const auto camera = perception::default_camera_model();
  sim::Renderer renderer(camera, *scenario);
  std::vector<sim::VisibleMarking> seen;
  seen.reserve(64);
  double s = 0.0;
  for (auto _ : state) {
    renderer.visible_markings(scenario->road.at(s), 3.0, 25.0, {}, seen);
    benchmark::DoNotOptimize(seen.data());
    s = s + 1.0 < scenario->road.length() ? s + 1.0 : 0.0;
  }
}
BENCHMARK(BM_VisibleMarkings)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
