// Per-stage costs of the engine (Google Benchmark): the pieces the table in
// markloop-bench puts together.
#include <benchmark/benchmark.h>

#include <array>
#include <memory>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "app/engine/landmark_tracker.hpp"
#include "app/engine/rigid_alignment.hpp"
#include "app/engine/sequence_database.hpp"
#include "app/engine/sequence_engine.hpp"
#include "sim/drive.hpp"
#include "sim/world.hpp"

namespace {

using namespace markloop;

void BM_DistanceBinRange(benchmark::State& state) {
  const DistanceQuantiser quantiser{MatchConfig{}};
  double d = 3.0;
  for (auto _ : state) {
    std::uint32_t first = 0, last = 0;
    quantiser.bin_range(d, first, last);
    benchmark::DoNotOptimize(first + last);
    d = d < 80.0 ? d + 0.37 : 3.0;
  }
}
BENCHMARK(BM_DistanceBinRange);

void BM_RigidFit(benchmark::State& state) {
  const auto k = static_cast<std::size_t>(state.range(0));
  std::vector<Eigen::Vector2d> from(k), to(k);
  for (std::size_t i = 0; i < k; ++i) {
    from[i] = {20.0 * static_cast<double>(i), 1.0 * static_cast<double>(i % 2)};
    to[i] = {from[i].x() + 0.3, from[i].y() - 0.2};
  }
  for (auto _ : state) benchmark::DoNotOptimize(fit_rigid_2d(from, to).rms_residual);
}
BENCHMARK(BM_RigidFit)->Arg(4)->Arg(10);

void BM_TrackerFrame(benchmark::State& state) {
  // Four markings in view, as on a busy junction.
  LandmarkTracker tracker{TrackerConfig{}};
  FixedVector<Landmark, 64> committed;
  FrameIndex frame = 0;
  for (auto _ : state) {
    const double x = frame * 1.0;
    const std::array<Observation, 4> seen{{{1, static_cast<float>(x + 10), 0.0f},
                                           {2, static_cast<float>(x + 10), 3.5f},
                                           {3, static_cast<float>(x + 18), 0.0f},
                                           {4, static_cast<float>(x + 18), 3.5f}}};
    tracker.observe(FrameInput{frame, frame / 10.0, true, {x, 0.0, 0.0}}, x, seen);
    committed.clear();
    tracker.commit(frame / 10.0, false, committed);
    ++frame;
  }
}
BENCHMARK(BM_TrackerFrame);

// A whole frame through the engine on a simulated drive (frames generated
// beforehand, so only the engine is timed); the argument is the number of
// rows a sequence may skip (ChainConfig::max_skipped_rows).
void BM_EngineFrame(benchmark::State& state) {
  const auto scenario = sim::make_scenario("ring", 1);
  sim::Drive drive(*scenario, sim::DriveConfig{}, 2);
  std::vector<sim::DriveFrame> frames;
  sim::DriveFrame frame;
  while (drive.next(frame)) frames.push_back(frame);

  struct NullSink final : MatchSink {
    std::size_t matches = 0;
    void on_match(const MatchEvent&) override { ++matches; }
  } sink;
  EngineConfig config;
  config.chain.max_skipped_rows = static_cast<unsigned>(state.range(0));
  config.database.sequence_capacity = 1 << 16;
  config.database.landmark_capacity = 1 << 14;
  auto engine = std::make_unique<SequenceEngine>(config);
  std::size_t i = 0;
  FrameIndex number = 0;
  double lap_offset = 0.0;
  for (auto _ : state) {
    sim::DriveFrame& f = frames[i];
    FrameInput input = f.estimate;
    input.frame = number++;
    input.t += lap_offset;
    engine->process_frame(input, f.observations, sink);
    if (++i == frames.size()) {  // drive the ring again, later
      i = 0;
      lap_offset = input.t + 1.0;
    }
  }
  state.counters["matches"] = static_cast<double>(sink.matches);
}
BENCHMARK(BM_EngineFrame)->Arg(0)->Arg(1);

}  // namespace

BENCHMARK_MAIN();
