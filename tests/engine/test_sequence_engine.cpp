#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "app/engine/sequence_engine.hpp"
#include "app/tools/replay/replay.hpp"
#include "sim/drive.hpp"
#include "sim/world.hpp"

using namespace markloop;

namespace {

struct Collector final : MatchSink {
  std::vector<MatchEvent> events;
  void on_match(const MatchEvent& e) override { events.push_back(e); }
};

struct DriveResult {
  std::vector<MatchEvent> events;
  std::vector<Pose2> truth;
  EngineCounters counters;
};

DriveResult drive(const std::string& scenario_name, std::uint64_t seed, EngineConfig config = {}) {
  const auto scenario = sim::make_scenario(scenario_name, seed);
  REQUIRE(scenario);
  sim::Drive drive(*scenario, sim::DriveConfig{}, seed + 100);
  auto engine = std::make_unique<SequenceEngine>(config);
  DriveResult result;
  Collector sink;
  sim::DriveFrame frame;
  while (drive.next(frame)) {
    result.truth.push_back(frame.truth);
    engine->process_frame(frame.estimate, frame.observations, sink);
  }
  engine->flush(sink);
  result.events = std::move(sink.events);
  result.counters = engine->counters();
  return result;
}

}  // namespace

TEST_CASE("the engine closes the loops of simulated drives without a false one", "[engine]") {
  for (const char* name : {"loop", "ring", "figure8"}) {
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
      INFO("scenario " << name << " seed " << seed);
      const DriveResult r = drive(name, seed);
      const replay::TruthJudge judge(r.truth, 10.0, 100.0);
      const auto evaluation = judge.evaluate(replay::frame_pairs(r.events), replay::relative_poses(r.events));
      CHECK(evaluation.wrong == 0);
      CHECK(evaluation.correct > 10);
      CHECK(evaluation.revisit_segments_detected * 10 >= evaluation.revisit_segments * 8);
      CHECK(evaluation.translation_error_max_m < 0.3);
      CHECK(evaluation.rotation_error_max_deg < 1.0);
    }
  }
}

TEST_CASE("a drive that never returns finds no loop", "[engine]") {
  // One lap of the ring only: the car never comes back.
  const auto scenario = sim::make_scenario("ring", 4);
  REQUIRE(scenario);
  sim::Scenario one_lap = *scenario;
  one_lap.laps = 1;
  sim::Drive drive(one_lap, sim::DriveConfig{}, 5);
  SequenceEngine engine{EngineConfig{}};
  Collector sink;
  sim::DriveFrame frame;
  while (drive.next(frame)) engine.process_frame(frame.estimate, frame.observations, sink);
  engine.flush(sink);
  CHECK(sink.events.empty());
  CHECK(engine.counters().sequences_created > 50);
}

// A straight road with two lanes of markings, driven twice; on the second
// pass one marking on the left lane is missed every time.
TEST_CASE("a missed marking on one lane leaves the chains through the other", "[engine]") {
  EngineConfig config;
  config.chain.k = 3;
  config.match.min_separation_s = 0;
  struct Mark {
    double x, y;
    Label label;
  };
  std::vector<Mark> world;
  for (int row = 0; row < 12; ++row) {
    const double x = 30.0 + row * 20.0 + (row % 3) * 3.0;  // irregular spacing
    world.push_back({x, 0.0, static_cast<Label>(row % 4)});
    world.push_back({x, 3.5, static_cast<Label>(10 + row % 5)});
  }
  const Mark missed = world[2 * 6 + 1];  // row 6, left lane

  SequenceEngine engine(config);
  Collector sink;
  FrameIndex frame = 0;
  double odometer = 0;
  for (int pass = 0; pass < 2; ++pass) {
    for (double car = 0; car < 330.0; car += 1.0, odometer += 1.0) {
      FrameInput in{frame, frame / 10.0, true, {car, 0.0, 0.0}};
      std::vector<Observation> seen;
      for (const Mark& m : world) {
        const double ahead = m.x - car;
        if (ahead < 4 || ahead > 20) continue;
        if (pass == 1 && m.x == missed.x && m.y == missed.y) continue;
        seen.push_back({m.label, static_cast<float>(m.x), static_cast<float>(m.y)});
      }
      engine.process_frame(in, seen, sink);
      ++frame;
    }
    if (pass == 0) engine.break_chains(sink);  // the car is driven back to the start
  }
  engine.flush(sink);
  // Rows k-1 .. 11 of the second pass each complete chains; every such row
  // still has a chain that avoids the missed marking.
  std::vector<bool> row_matched(12, false);
  for (const MatchEvent& e : sink.events) {
    CHECK(e.query[e.k - 1].x == e.match[e.k - 1].x);
    CHECK(e.residual_m < 1e-3);
    const int row = static_cast<int>(std::lround((e.query[e.k - 1].x - 30.0) / 20.0));
    if (row >= 0 && row < 12) row_matched[row] = true;
  }
  for (int row = static_cast<int>(config.chain.k) - 1; row < 12; ++row) {
    INFO("row " << row);
    CHECK(row_matched[row]);
  }
}

// One lane, driven twice: the first pass misses the marking of row 5, the
// second that of row 9. Without a skipped row every sequence through either
// marking is lost; with one, only the rows whose own marking is missing.
TEST_CASE("a marking missed on one visit breaks no sequence when a row may be skipped", "[engine]") {
  struct Mark {
    double x;
    Label label;
  };
  std::vector<Mark> world;
  // Spacings and labels that no stretch of the road repeats, skipped rows included.
  const double spacing[14] = {0, 17, 23, 19, 29, 16, 25, 21, 31, 18, 27, 22, 33, 20};
  double x = 30.0;
  for (int row = 0; row < 14; ++row) {
    x += spacing[row];
    world.push_back({x, static_cast<Label>((row * 5) % 11)});
  }
  const auto matched_rows = [&](unsigned max_skipped_rows) {
    EngineConfig config;
    config.chain.k = 3;
    config.chain.max_skipped_rows = max_skipped_rows;
    config.match.min_separation_s = 0;
    SequenceEngine engine(config);
    Collector sink;
    FrameIndex frame = 0;
    for (int pass = 0; pass < 2; ++pass) {
      const int missed_row = pass == 0 ? 5 : 9;
      for (double car = 0; car < 400.0; car += 1.0) {
        FrameInput in{frame, frame / 10.0, true, {car, 0.0, 0.0}};
        std::vector<Observation> seen;
        for (int row = 0; row < 14; ++row) {
          const double ahead = world[row].x - car;
          if (ahead >= 4 && ahead <= 20 && row != missed_row)
            seen.push_back({world[row].label, static_cast<float>(world[row].x), 0.0f});
        }
        engine.process_frame(in, seen, sink);
        ++frame;
      }
      if (pass == 0) engine.break_chains(sink);  // the car is driven back to the start
    }
    engine.flush(sink);
    std::vector<int> rows;
    for (const MatchEvent& e : sink.events) {
      CHECK(e.query[e.k - 1].x == e.match[e.k - 1].x);
      CHECK(e.residual_m < 1e-3);
      for (int row = 0; row < 14; ++row)
        if (world[row].x == e.query[e.k - 1].x) rows.push_back(row);
    }
    // Each pass: 13 landmarks, of which the 10 with k rows before them make
    // k - 1 = 2 sequences over a skipped row each.
    CHECK(engine.counters().sequences_over_skipped_row == (max_skipped_rows == 0 ? 0u : 2u * 10u * 2u));
    return rows;
  };
  // Rows 0 and 1 start the chains; 5 is not in the map, 9 not in the query.
  CHECK(matched_rows(1) == std::vector<int>{2, 3, 4, 6, 7, 8, 10, 11, 12, 13});
  // Without: also every row whose sequence spans row 5 or row 9.
  CHECK(matched_rows(0) == std::vector<int>{2, 3, 4, 8, 12, 13});
}

namespace {

struct Sighting {
  double x;                // on a straight road along x
  FrameIndex first, last;  // seen on these frames
  Label label;
};

// The car drives along x at `speed` metres a frame, 10 frames a second,
// seeing each marking on its frames; returns the stations released, in
// release order, and the car's x at each release.
std::vector<std::pair<double, double>> released(EngineConfig config, const std::vector<Sighting>& marks,
                                                FrameIndex frames, double speed = 1.0) {
  SequenceEngine engine(config);
  Collector sink;
  std::vector<std::pair<double, double>> out;
  for (FrameIndex f = 0; f < frames; ++f) {
    std::vector<Observation> seen;
    for (const Sighting& m : marks)
      if (f >= m.first && f <= m.last) seen.push_back({m.label, static_cast<float>(m.x), 0.0f});
    engine.process_frame({f, f / 10.0, true, {speed * f, 0.0, 0.0}}, seen, sink);
    while (out.size() < engine.counters().landmarks_released) {
      const Landmark* l = engine.database().landmark(static_cast<LandmarkId>(out.size()));
      REQUIRE(l != nullptr);
      out.emplace_back(l->station, speed * f);
    }
  }
  return out;
}

}  // namespace

TEST_CASE("a landmark enters the chains soon after the car passes it once nothing tracked lies behind it",
          "[engine]") {
  EngineConfig config;
  config.tracker.release_lag_m = 15.0;
  // Seen 20..4 m ahead; committed half a second after the last sighting.
  const std::vector<Sighting> one{{30.0, 10, 26, 3}};
  config.tracker.settled_lag_m = 1.0;
  const auto early = released(config, one, 60);
  REQUIRE(early.size() == 1);
  CHECK(early[0].first == Catch::Approx(30.0).margin(0.01));
  CHECK(early[0].second == 32.0);  // committed on frame 32, already 1 m past
  config.tracker.settled_lag_m = 15.0;
  const auto late = released(config, one, 60);
  REQUIRE(late.size() == 1);
  CHECK(late[0].second == 45.0);
}

TEST_CASE("a landmark settled early waits for a marking still tracked behind it", "[engine]") {
  EngineConfig config;
  config.tracker.settled_lag_m = 0.0;
  // At 20 m/s the farther marking, lost from view early (an occluder), is
  // committed and passed while the nearer one is still tracked.
  const auto order = released(config, {{33.0, 4, 8, 3}, {30.0, 5, 12, 5}}, 30, 2.0);
  REQUIRE(order.size() == 2);
  CHECK(order[0].first == Catch::Approx(30.0).margin(0.01));
  CHECK(order[1].first == Catch::Approx(33.0).margin(0.01));
  CHECK(order[0].second == 36.0);  // the nearer one's commit releases both
  CHECK(order[1].second == 36.0);
}

TEST_CASE(
    "with a negative settled lag a loop is sent before the car reaches its last marking, and names the "
    "frames of a marking passed",
    "[engine]") {
  // Markings about 20 m apart, each of its own label and seen from 20 to
  // 12 m ahead only (two lanes over): committed half a second later, still
  // metres ahead of the car. The road is driven twice; the drive ends with
  // one marking in view.
  const auto first_match = [](double settled_lag_m, std::uint64_t& flushed_ahead) {
    EngineConfig config;
    config.chain.k = 3;
    config.match.min_separation_s = 0;
    config.match.max_frame_distance_m = 4.0;
    config.tracker.settled_lag_m = settled_lag_m;
    SequenceEngine engine(config);
    Collector sink;
    FrameIndex frame = 0;
    constexpr double kNone = 1e9;
    double car_at_first_match = kNone;
    for (int pass = 0; pass < 2; ++pass) {
      for (double car = 0; car < (pass == 0 ? 260.0 : 183.0); car += 1.0) {
        std::vector<Observation> seen;
        for (int row = 0; row < 11; ++row) {
          const double x = 30.0 + row * 20.0 + (row % 3) * 4.0;
          if (x - car >= 12.0 && x - car <= 20.0)
            seen.push_back({static_cast<Label>(row), static_cast<float>(x), 4.0f});
        }
        engine.process_frame({frame, frame / 10.0, true, {car, 0.0, 0.0}}, seen, sink);
        ++frame;
        REQUIRE((pass == 1 || sink.events.empty()));
        if (pass == 1 && car_at_first_match == kNone && !sink.events.empty()) {
          const MatchEvent& e = sink.events.front();
          CHECK(e.query[e.k - 1].x == e.match[e.k - 1].x);
          // Represented by the frame closest to it so far...
          CHECK(e.query[e.k - 1].car_x == Catch::Approx(std::min(car, double{e.query[e.k - 1].x})));
          // ...the stored one by the frame level with it, once passed. The
          // newest pair's frames, 6 m apart, are beyond the frames-apart
          // limit: the loop names the pair whose cars were closest.
          CHECK(e.match[e.k - 1].car_x == Catch::Approx(e.match[e.k - 1].x));
          const unsigned framed = car < e.query[e.k - 1].x ? e.k - 2 : e.k - 1;
          CHECK(e.framed == framed);
          CHECK(e.query_frame() == e.query[framed].last_frame);
          CHECK(e.query[framed].car_x == Catch::Approx(e.query[framed].x));
          REQUIRE(e.has_relative_pose);
          CHECK(std::hypot(e.relative_pose.x, e.relative_pose.y) < 1e-6);
          car_at_first_match = car - e.query[e.k - 1].x;
        }
      }
      if (pass == 0) engine.break_chains(sink);
    }
    const std::size_t before_flush = sink.events.size();
    engine.flush(sink);
    CHECK(sink.events.size() == before_flush);  // the marking still in view is not queried
    flushed_ahead = engine.counters().landmarks_flushed_ahead;
    return car_at_first_match;
  };
  std::uint64_t flushed_ahead = 0;
  CHECK(first_match(-20.0, flushed_ahead) == Catch::Approx(-6.0));
  CHECK(flushed_ahead == 1u);
  CHECK(first_match(1.0, flushed_ahead) == Catch::Approx(1.0));
  CHECK(flushed_ahead == 1u);
}

TEST_CASE("the engine rejects bad configurations", "[engine]") {
  EngineConfig config;
  CHECK(validate(config) == nullptr);
  config.chain.k = 1;
  CHECK(validate(config) != nullptr);
  config = {};
  config.match.distance_tolerance_abs_m = std::nan("");
  CHECK(validate(config) != nullptr);
  config = {};
  config.match.index_bin_tolerances = 1.0;
  CHECK(validate(config) != nullptr);
  config = {};
  config.chain.max_skipped_rows = 2;
  CHECK(validate(config) != nullptr);
  config.chain.max_skipped_rows = 0;
  CHECK(validate(config) == nullptr);
  config = {};
  config.match.max_frame_distance_m = -1.0;
  CHECK(validate(config) != nullptr);
  config = {};
  config.tracker.settled_lag_m = -20.0;
  CHECK(validate(config) == nullptr);
  config.tracker.settled_lag_m = -1001.0;
  CHECK(validate(config) != nullptr);
  config.tracker.settled_lag_m = std::nan("");
  CHECK(validate(config) != nullptr);
}

// A straight road with one marking per row, driven twice; on the second pass
// the odometry has turned the world by 0.5 degrees about the start, and the
// markings' positions carry a fixed, made-up error per marking and pass.
TEST_CASE(
    "a landmark is represented by the frame in which the car passed it, and a run of "
    "matches refines the pose",
    "[engine]") {
  EngineConfig config;
  config.chain.k = 3;
  config.match.min_separation_s = 0;
  std::vector<double> row_x;
  for (int row = 0; row < 10; ++row) row_x.push_back(30.0 + row * 20.0 + (row % 3) * 4.0);
  const double drift = 0.5 * 3.14159265358979323846 / 180.0;
  const auto error_of = [](int row, int pass) {  // deterministic, up to 8 cm
    return 0.08 * std::sin(1.7 * row + 2.9 * pass);
  };

  SequenceEngine engine(config);
  Collector sink;
  FrameIndex frame = 0;
  std::vector<double> frame_car_x;
  for (int pass = 0; pass < 2; ++pass) {
    const double yaw = pass == 0 ? 0.0 : drift;
    const double c = std::cos(yaw), s = std::sin(yaw);
    for (double car = 0; car < 260.0; car += 0.5) {
      // The estimated pose: the true one (along x) turned by the drift.
      FrameInput in{frame, frame / 20.0, true, {c * car, s * car, yaw}};
      std::vector<Observation> seen;
      for (int row = 0; row < static_cast<int>(row_x.size()); ++row) {
        const double ahead = row_x[row] - car;
        if (ahead < 4 || ahead > 20) continue;
        const double x = row_x[row] + error_of(row, pass), y = error_of(row + 5, pass);
        seen.push_back({static_cast<Label>(row % 4), static_cast<float>(c * x - s * y),
                        static_cast<float>(s * x + c * y)});
      }
      engine.process_frame(in, seen, sink);
      frame_car_x.push_back(car);
      ++frame;
    }
    if (pass == 0) engine.break_chains(sink);
  }
  engine.flush(sink);

  REQUIRE(sink.events.size() >= 6);
  for (std::size_t i = 0; i < sink.events.size(); ++i) {
    const MatchEvent& e = sink.events[i];
    INFO("event " << i);
    // The car drew level with the last marking in the query and match frames.
    const double marking_x = e.query[e.k - 1].x;
    CHECK(std::abs(frame_car_x[e.query_frame()] - marking_x) <= 0.6);
    CHECK(std::abs(frame_car_x[e.match_frame()] - marking_x) <= 0.6);
    CHECK(e.query_frame() > e.match_frame());
    // The first match of the run rests on k pairs, later ones on more.
    CHECK(e.aligned_pairs == (i == 0 ? e.k : std::min(e.k + static_cast<unsigned>(i), 6u)));
    CHECK(e.has_relative_pose);
    // The true relative pose is the identity shifted by where the two cars
    // stood (the same marking, so within one frame step). Three points in a
    // line leave the rotation loose (here 0.3 degrees, 15 cm at the car);
    // five or more of the run pin it down.
    const double true_dx = frame_car_x[e.query_frame()] - frame_car_x[e.match_frame()];
    const double tolerance_m = e.aligned_pairs >= 5 ? 0.1 : 0.3;
    const double tolerance_deg = e.aligned_pairs >= 5 ? 0.1 : 1.0;
    CHECK(std::abs(e.relative_pose.x - true_dx) < tolerance_m);
    CHECK(std::abs(e.relative_pose.y) < tolerance_m);
    CHECK(std::abs(e.relative_pose.yaw) < tolerance_deg * 3.14159265358979323846 / 180.0);
  }
  CHECK(engine.counters().closures_extended == sink.events.size() - 1);
}

// The same markings passed twice, the second time on a parallel line
// `lateral_m` to the side (where routes part at a junction, the car turns
// off before the last marking): the markings agree, and the loop's two
// frames lie apart by that much.
TEST_CASE("a loop whose two frames lie further apart than max_frame_distance_m is not reported", "[engine]") {
  const auto loops = [](double lateral_m, double max_frame_distance_m) {
    EngineConfig config;
    config.chain.k = 3;
    config.match.min_separation_s = 0;
    config.match.max_frame_distance_m = max_frame_distance_m;
    SequenceEngine engine(config);
    Collector sink;
    FrameIndex frame = 0;
    for (int pass = 0; pass < 2; ++pass) {
      const double car_y = pass == 0 ? 0.0 : lateral_m;
      for (double car = 0; car < 260.0; car += 0.5, ++frame) {
        std::vector<Observation> seen;
        for (int row = 0; row < 10; ++row) {
          const double x = 30.0 + row * 20.0 + (row % 3) * 4.0;
          if (x - car >= 4 && x - car <= 20)
            seen.push_back({static_cast<Label>(row % 4), static_cast<float>(x), 0.0f});
        }
        engine.process_frame({frame, frame / 20.0, true, {car, car_y, 0.0}}, seen, sink);
      }
      if (pass == 0) engine.break_chains(sink);
    }
    engine.flush(sink);
    return std::pair{sink.events.size(), engine.counters().candidates_rejected_frames_apart};
  };
  // 2 m to the side: the same place, within 5 m.
  const auto [near_loops, near_rejected] = loops(2.0, 5.0);
  CHECK(near_loops >= 6);
  CHECK(near_rejected == 0);
  // 8 m to the side: every match is held back, and counted.
  const auto [far_loops, far_rejected] = loops(8.0, 5.0);
  CHECK(far_loops == 0);
  CHECK(far_rejected >= 6);
  // Without the limit the same drive closes its loops.
  const auto [unlimited_loops, unlimited_rejected] = loops(8.0, 0.0);
  CHECK(unlimited_loops == near_loops);
  CHECK(unlimited_rejected == 0);
}
