// The odometry prior and the confirmation of loaded places against
// look-alike places: the same marking layout laid twice, 1 km apart.
#include <catch2/catch_test_macros.hpp>

#include <array>
#include <filesystem>
#include <memory>
#include <vector>

#include "app/ecu/map_store.hpp"
#include "app/engine/sequence_engine.hpp"

using namespace markloop;

namespace {

struct Marking {
  double x, y;
  Label label;
};

// A 600 m layout of markings along y = 0 starting at x0.
std::vector<Marking> layout(double x0) {
  std::vector<Marking> out;
  std::uint32_t state = 99;
  const auto next = [&] { return (state = state * 1664525u + 1013904223u) >> 8; };
  for (double x = 10; x < 600; x += 13.0 + double(next() % 1300) / 100.0)
    out.push_back({x0 + x, double(next() % 600) / 100.0 - 3.0, static_cast<Label>(next() % 16)});
  return out;
}

struct CountingSink final : MatchSink {
  unsigned matches = 0;
  void on_match(const MatchEvent&) override { ++matches; }
};

// Drives along y = 0 from x_from to x_to (world), seeing `markings` 4..20 m
// ahead; the car's pose is `offset` + its position (a drift-free odometry).
void drive(SequenceEngine& engine, CountingSink& sink, const std::vector<Marking>& markings, double x_from,
           double x_to, FrameIndex& frame, double& t) {
  std::array<Observation, SequenceEngine::kMaxObservationsPerFrame> seen{};
  for (double x = x_from; x < x_to; x += 1.0, t += 0.1) {
    std::size_t n = 0;
    for (const Marking& m : markings)
      if (m.x - x >= 4 && m.x - x <= 20 && n < seen.size())
        seen[n++] = {m.label, static_cast<float>(m.x), static_cast<float>(m.y)};
    FrameInput input{frame++, t, true, {x, 0.0, 0.0}};
    engine.process_frame(input, std::span<const Observation>(seen.data(), n), sink);
  }
}

EngineConfig config(bool prior) {
  EngineConfig c;
  c.database.landmark_capacity = c.database.sequence_capacity = 4096;
  if (prior) {
    c.match.max_drift_rel = 0.02;
    c.match.confirm_loaded_places = true;
  }
  return c;
}

// A second session's engine with the map at `path` loaded.
std::unique_ptr<SequenceEngine> engine_with_map(const std::filesystem::path& path, bool prior) {
  auto engine = std::make_unique<SequenceEngine>(config(prior));
  ecu::MapStore store(path.string());
  REQUIRE(store.load(engine->mutable_database(), engine->config().match).outcome ==
          ecu::MapLoadOutcome::kLoaded);
  return engine;
}

}  // namespace

TEST_CASE("within a session, a look-alike place 1 km away is rejected, a true revisit is not") {
  const std::vector<Marking> here = layout(0.0);
  const std::vector<Marking> there = layout(1000.0);  // the same layout, 1 km on
  for (const bool prior : {false, true}) {
    INFO("odometry prior " << prior);
    SequenceEngine engine(config(prior));
    CountingSink sink;
    FrameIndex frame = 0;
    double t = 0.0;
    drive(engine, sink, here, 0, 650, frame, t);
    drive(engine, sink, there, 650, 1650, frame, t);
    const unsigned look_alike = sink.matches;
    if (prior) {
      CHECK(look_alike == 0);
      CHECK(engine.counters().candidates_rejected_drift > 0);
    } else {
      CHECK(look_alike > 5);
    }
    // Back to the start (the car drove round; the odometer counts the way).
    drive(engine, sink, here, -200, 650, frame, t);
    CHECK(sink.matches - look_alike > 5);
  }
}

TEST_CASE("a loaded map's places are matched once two matches agree, even in another world frame") {
  const auto path = std::filesystem::temp_directory_path() / "markloop-look-alike-map.bin";
  std::filesystem::remove(path);
  const std::vector<Marking> here = layout(0.0);
  const std::vector<Marking> there = layout(1000.0);
  {
    SequenceEngine first(config(true));
    CountingSink sink;
    FrameIndex frame = 0;
    double t = 0.0;
    drive(first, sink, here, 0, 650, frame, t);
    first.flush(sink);
    ecu::MapStore store(path.string());
    REQUIRE_FALSE(store.save(first.database()));
  }
  for (const bool prior : {false, true}) {
    INFO("confirmation " << prior);
    const auto loaded = engine_with_map(path, prior);
    SequenceEngine& second = *loaded;
    CountingSink sink;
    FrameIndex frame = 0;
    double t = 0.0;
    // This session's world frame is shifted by 1 km from the map's: the
    // look-alike layout here is the mapped place itself, seen from another
    // frame; every match agrees on the same 1 km shift.
    drive(second, sink, there, 1000, 1650, frame, t);
    CHECK(sink.matches > 5);
    if (prior) {
      // The first sequence into the map waits for the next row to agree.
      CHECK(second.counters().loaded_single_sequences >= 1);
      CHECK(second.counters().loaded_hypotheses >= 1);
      CHECK(second.counters().loaded_rejected == 0);
      // The first matches, held back as hypotheses, went out once confirmed.
      CHECK(second.counters().loaded_hypotheses_sent >= 1);
    }
  }
}

TEST_CASE("a loaded map with the same place twice is never matched: the two alignments are rivals") {
  const auto path = std::filesystem::temp_directory_path() / "markloop-look-alike-twice.bin";
  std::filesystem::remove(path);
  // The map holds the layout twice, 1 km apart: every match into it has a
  // twin that fits as well, 1 km off.
  {
    SequenceEngine first(config(true));
    CountingSink sink;
    FrameIndex frame = 0;
    double t = 0.0;
    drive(first, sink, layout(0.0), 0, 650, frame, t);
    first.break_chains(sink);
    drive(first, sink, layout(1000.0), 1000, 1650, frame, t);
    first.flush(sink);
    ecu::MapStore store(path.string());
    REQUIRE_FALSE(store.save(first.database()));
  }
  const auto loaded = engine_with_map(path, true);
  SequenceEngine& second = *loaded;
  CountingSink sink;
  FrameIndex frame = 0;
  double t = 0.0;
  // The same layout again, in a frame shifted by 5 km: which of the two
  // mapped copies it is cannot be told, so no place may be reported.
  drive(second, sink, layout(5000.0), 5000, 5650, frame, t);
  CHECK(second.counters().loaded_hypotheses >= 2);
  CHECK(second.counters().loaded_rivalled >= 1);
  CHECK(sink.matches == 0);
}
