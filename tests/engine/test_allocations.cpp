// Proves the engine does not touch the heap after construction: every global
// operator new is counted while the engine processes a long drive.
#include <catch2/catch_test_macros.hpp>

#include <atomic>
#include <cstdlib>
#include <memory>
#include <new>

#include "engine/sequence_engine.hpp"
#include "sim/drive.hpp"
#include "sim/world.hpp"

namespace {
std::atomic<bool> counting{false};
std::atomic<std::size_t> allocations{0};

void* counted_allocation(std::size_t size) {
  if (counting.load(std::memory_order_relaxed)) allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
}  // namespace

void* operator new(std::size_t size) { return counted_allocation(size); }
void* operator new[](std::size_t size) { return counted_allocation(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

using namespace markloop;

namespace {
struct CountingSink final : MatchSink {
  std::size_t matches = 0;
  void on_match(const MatchEvent&) override { ++matches; }
};
}  // namespace

TEST_CASE("no heap allocation after start-up over a 60 km drive", "[engine][memory]") {
  const auto scenario = sim::make_scenario("long", 3);
  REQUIRE(scenario);
  sim::Drive drive(*scenario, sim::DriveConfig{}, 9);

  EngineConfig config;
  // Small enough that both rings wrap many times during the drive.
  config.database.landmark_capacity = 512;
  config.database.sequence_capacity = 1024;
  config.match.min_separation_s = 30;
  auto engine = std::make_unique<SequenceEngine>(config);
  CountingSink sink;

  sim::DriveFrame frame;
  std::size_t frames = 0;
  while (drive.next(frame)) {  // the simulator may allocate; it is not counted
    counting = true;
    engine->process_frame(frame.estimate, frame.observations, sink);
    counting = false;
    ++frames;
  }
  counting = true;
  engine->flush(sink);
  counting = false;

  INFO("frames " << frames << ", matches " << sink.matches);
  CHECK(frames >= 50000);
  CHECK(allocations.load() == 0);
  CHECK(sink.matches > 100);
  const DatabaseStats stats = engine->database().stats();
  CHECK(stats.sequences_evicted > 1000);
  CHECK(stats.landmarks_evicted > 1000);
  CHECK(stats.sequences <= stats.sequence_capacity);
}

TEST_CASE("the allocation counter sees allocations", "[memory]") {
  counting = true;
  const std::size_t before = allocations.load();
  auto p = std::make_unique<int>(3);
  counting = false;
  CHECK(allocations.load() == before + 1);
  CHECK(*p == 3);
}
