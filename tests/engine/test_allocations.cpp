// Proves the engine does not touch the heap after construction: every global
// operator new is counted while the engine processes a long drive.
#include <catch2/catch_test_macros.hpp>
#include <catch2/generators/catch_generators.hpp>

#include <memory>

#include "app/engine/sequence_engine.hpp"
#include "sim/drive.hpp"
#include "sim/world.hpp"
#include "tests/support/count_allocations.hpp"

using namespace markloop;
using markloop::test::AllocationCounter;

namespace {
struct CountingSink final : MatchSink {
  std::size_t matches = 0;
  void on_match(const MatchEvent&) override { ++matches; }
};
}  // namespace

TEST_CASE("no heap allocation after start-up over a 60 km drive", "[engine][memory]") {
  const bool places = GENERATE(false, true);
  INFO("place matching " << (places ? "on" : "off"));
  const auto scenario = sim::make_scenario("long", 3);
  REQUIRE(scenario);
  sim::Drive drive(*scenario, sim::DriveConfig{}, 9);

  EngineConfig config;
  if (places) {
    config.match.place_landmarks = 3;
    config.match.place_min_bits = 4;
    config.match.place_pair_min_bits = 4;  // places of two: the car's path kept
    config.match.far_run_m = 300;
  }
  // Small enough that both rings wrap many times during the drive.
  config.database.landmark_capacity = 512;
  config.database.sequence_capacity = 4096;  // about k sequences per landmark
  config.match.min_separation_s = 30;
  auto engine = std::make_unique<SequenceEngine>(config);
  CountingSink sink;

  sim::DriveFrame frame;
  std::size_t frames = 0;
  AllocationCounter heap;
  heap.pause();
  while (drive.next(frame)) {  // the simulator may allocate; it is not counted
    heap.resume();
    engine->process_frame(frame.estimate, frame.observations, sink);
    heap.pause();
    ++frames;
  }
  heap.resume();
  engine->flush(sink);
  const std::size_t allocations = heap.stop();

  INFO("frames " << frames << ", matches " << sink.matches);
  CHECK(frames >= 50000);
  CHECK(allocations == 0);
  CHECK(sink.matches > 100);
  if (places) CHECK(engine->place_counters().queries > 50);
  if (places) CHECK(engine->place_counters().hypotheses > 0);
  const DatabaseStats stats = engine->database().stats();
  CHECK(stats.sequences_evicted > 1000);
  CHECK(stats.landmarks_evicted > 1000);
  CHECK(stats.sequences <= stats.sequence_capacity);
}

TEST_CASE("the allocation counter sees allocations", "[memory]") {
  AllocationCounter heap;
  auto p = std::make_unique<int>(3);
  const std::size_t allocations = heap.stop();
  CHECK(allocations == 1);
  CHECK(*p == 3);
}
