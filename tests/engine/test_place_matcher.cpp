// Place matching through the whole engine: a car drives polylines past
// markings it sees 4..20 m ahead, as the sequence tests do.
#include <catch2/catch_test_macros.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "app/engine/sequence_engine.hpp"

using namespace markloop;

namespace {

struct Collector final : MatchSink {
  std::vector<MatchEvent> events;
  void on_match(const MatchEvent& e) override { events.push_back(e); }
};

struct Mark {
  double x, y;
  Label label;
  // The direction it is painted for; NaN: alike from either way (a
  // crosswalk). A car reads it turned when driving the other way.
  double painted_yaw = std::nan("");
};

Facing facing_seen(const Mark& m, double car_yaw) {
  if (std::isnan(m.painted_yaw)) return Facing::kAny;
  return std::cos(m.painted_yaw - car_yaw) > 0.0 ? Facing::kAlong : Facing::kAgainst;
}

struct Point {
  double x, y;
};

// Drives from one point to the next in 1 m steps (1 frame each, 10 frames
// a second), observing the markings 4..20 m ahead and within 8 m to a side.
class Car {
 public:
  Car(SequenceEngine& engine, const std::vector<Mark>& world) : engine_(engine), world_(world) {}

  void drive(std::vector<Point> path) {
    for (std::size_t i = 0; i + 1 < path.size(); ++i) {
      const double dx = path[i + 1].x - path[i].x, dy = path[i + 1].y - path[i].y;
      const double length = std::hypot(dx, dy), yaw = std::atan2(dy, dx);
      for (double s = 0; s < length; s += 1.0)
        step(path[i].x + dx * s / length, path[i].y + dy * s / length, yaw);
    }
  }
  // Where the car is on the n-th frame it drove.
  const std::vector<Point>& trail() const { return trail_; }
  Collector sink;
  double drift = 0.0;  // the pose estimate and what it places lie this far north

 private:
  void step(double x, double y, double yaw) {
    const FrameIndex frame = static_cast<FrameIndex>(trail_.size());
    trail_.push_back({x, y});
    std::vector<Observation> seen;
    for (const Mark& m : world_) {
      const double ahead = (m.x - x) * std::cos(yaw) + (m.y - y) * std::sin(yaw);
      const double side = -(m.x - x) * std::sin(yaw) + (m.y - y) * std::cos(yaw);
      if (ahead >= 4 && ahead <= 20 && std::abs(side) <= 8)
        seen.push_back(
            {m.label, static_cast<float>(m.x), static_cast<float>(m.y + drift), 1.0f, facing_seen(m, yaw)});
    }
    engine_.process_frame({frame, frame / 10.0, true, {x, y + drift, yaw}}, seen, sink);
  }

  SequenceEngine& engine_;
  const std::vector<Mark>& world_;
  std::vector<Point> trail_;
};

EngineConfig place_config(unsigned place_landmarks) {
  EngineConfig config;
  config.chain.k = 4;
  config.tracker.release_lag_m = 5.0;
  config.match.place_landmarks = place_landmarks;
  config.match.max_drift_rel = 0.02;
  config.match.max_frame_distance_m = 5.0;
  return config;
}

// An east-west street (y = 0) with irregular markings, and a north-south one
// (x = 230).
std::vector<Mark> town() {
  std::vector<Mark> world;
  const double spacing[] = {0, 17, 23, 19, 29, 16, 25, 21, 31, 18, 27, 22};
  double x = 40.0;
  for (int i = 0; i < 12; ++i) {
    x += spacing[i];
    world.push_back({x, -1.0, static_cast<Label>((i * 5) % 11)});
  }
  for (int i = 0; i < 8; ++i) world.push_back({230.0 + 1.0, -300.0 + 35.0 * i + (i % 3) * 4.0, 12});
  return world;
}

// Whether the first correct match comes within `metres` of the car's return
// to the street; no match is wrong.
struct Outcome {
  std::size_t matches = 0, wrong = 0;
  double first_x = -1;  // the car's x when the first match was made
};

Outcome judge(const Car& car, const std::vector<MatchEvent>& events) {
  Outcome o;
  for (const MatchEvent& e : events) {
    ++o.matches;
    const Point q = car.trail()[e.query_frame()], m = car.trail()[e.match_frame()];
    if (std::hypot(q.x - m.x, q.y - m.y) > 5.0) ++o.wrong;
  }
  return o;
}

// Places of two with any labels, and no stored marking left unseen.
EngineConfig places_of_two_config() {
  EngineConfig config = place_config(3);
  config.match.place_pair_min_bits = 1.0;
  config.match.place_pair_max_unseen = 0;
  return config;
}

// Drives north on x = 0 three times around a block; from the second visit on
// the odometry places everything 6 m further north. Returns the number of
// matches before the third visit.
std::size_t drive_north_three_times(SequenceEngine& engine, Car& car) {
  const std::vector<Point> block = {{0, 0}, {0, 200}, {-150, 200}, {-150, -50}, {0, -50}, {0, 0}};
  car.drive(block);
  car.drift = 6.0;
  car.drive(block);
  const std::size_t before_third = car.sink.events.size();
  car.drive({{0, 0}, {0, 200}});
  engine.flush(car.sink);
  return before_third;
}

}  // namespace

TEST_CASE("a turn into an old street closes a loop after a few markings", "[engine][place]") {
  const std::vector<Mark> world = town();
  for (unsigned place : {0u, 3u}) {
    INFO("place landmarks " << place);
    SequenceEngine engine(place_config(place));
    Car car(engine, world);
    // East along the street, round a block, then up the side street and a
    // turn east into the old street: three of its markings follow.
    car.drive({{0, 0}, {330, 0}, {330, -300}, {231, -300}, {231, -1}, {400, -1}, {400, 200}});
    engine.flush(car.sink);
    const Outcome o = judge(car, car.sink.events);
    CHECK(o.wrong == 0);
    if (place == 0) {
      // The paper's sequences need k = 4 old markings in a row: only 3 follow.
      CHECK(o.matches == 0);
    } else {
      const PlaceCounters& pc = engine.place_counters();
      INFO("queries " << pc.queries << " hypotheses " << pc.hypotheses << " too few " << pc.too_few_pairs
                      << " residual " << pc.rejected_residual << " drift " << pc.rejected_drift
                      << " ambiguous " << pc.ambiguous << " frames apart "
                      << engine.counters().candidates_rejected_frames_apart);
      REQUIRE(o.matches >= 1);
      CHECK(engine.counters().place_matches >= 1);
      CHECK(car.sink.events[0].k >= 3);
    }
  }
}

TEST_CASE("a turn into an old street and off again after two markings closes a loop", "[engine][place]") {
  const std::vector<Mark> world = town();
  for (const double pair_bits : {0.0, 4.0}) {
    INFO("bits for a place of two " << pair_bits);
    EngineConfig config = place_config(3);
    config.match.place_pair_min_bits = pair_bits;
    SequenceEngine engine(config);
    Car car(engine, world);
    // As above, but off the old street again 2 markings after the turn in.
    car.drive({{0, 0}, {330, 0}, {330, -300}, {231, -300}, {231, -1}, {268, -1}, {268, 200}});
    engine.flush(car.sink);
    const Outcome o = judge(car, car.sink.events);
    CHECK(o.wrong == 0);
    if (pair_bits == 0.0) {
      CHECK(o.matches == 0);
    } else {
      REQUIRE(o.matches >= 1);
      CHECK(car.sink.events[0].k == 2);
      CHECK(engine.place_counters().unseen == 0);
    }
  }
}

TEST_CASE("a car turning into an old street closes a loop at its second marking", "[engine][place]") {
  // Back from the south, the car turns east into the street and passes its
  // first marking mid-turn, 41 degrees off the street: by its heading a
  // little later it drove the street.
  const std::vector<Mark> world = {{100, -4, 14}, {115, -1, 15}};
  EngineConfig config = place_config(3);
  config.match.place_pair_min_bits = 1.0;
  SequenceEngine engine(config);
  Car car(engine, world);
  car.drive({{0, 0}, {200, 0}, {200, -150}, {95, -150}, {95, -8}, {103, -1}, {200, -1}});
  engine.flush(car.sink);
  CHECK(judge(car, car.sink.events).wrong == 0);
  REQUIRE(car.sink.events.size() == 1);
  CHECK(car.sink.events[0].k == 2);
  CHECK(engine.place_counters().across == 0);
}

TEST_CASE("a place of three with common labels is judged as a place of two", "[engine][place]") {
  // No labels are rare enough for a place of three here: with places of two
  // on, three pairs that pass their checks close the loop.
  const std::vector<Mark> world = {{100, -1, 14}, {106, -1, 15}, {114, -1, 1}};
  for (const double pair_bits : {0.0, 1.0}) {
    INFO("bits for a place of two " << pair_bits);
    EngineConfig config = place_config(3);
    config.match.place_min_bits = 100.0;
    config.match.place_pair_min_bits = pair_bits;
    SequenceEngine engine(config);
    Car car(engine, world);
    car.drive({{0, 0}, {200, 0}, {200, 100}, {-40, 100}, {-40, 0}, {200, 0}});
    engine.flush(car.sink);
    CHECK(judge(car, car.sink.events).wrong == 0);
    if (pair_bits == 0.0) {
      CHECK(car.sink.events.empty());
      CHECK(engine.place_counters().too_common >= 1);
    } else {
      // The first two pairs already make a place of two; the third makes one
      // of three, which its labels alone would not.
      CHECK(std::any_of(car.sink.events.begin(), car.sink.events.end(),
                        [](const MatchEvent& e) { return e.k == 3; }));
    }
  }
}

TEST_CASE("a place of three with common labels closes a loop where the cars crossed a pair",
          "[engine][place]") {
  // Two markings on an east-west street and one at the corner of a side
  // street. The first visit drives east and turns south past the corner
  // marking; the second drives the street west, passing it across.
  const std::vector<Mark> world = {{100, -1, 14}, {106, -1, 15}, {113, -5, 1}};
  EngineConfig config = place_config(3);
  config.match.place_min_bits = 100.0;
  config.match.place_pair_min_bits = 1.0;
  SequenceEngine engine(config);
  Car car(engine, world);
  car.drive({{0, 0}, {116, 0}, {116, -150}, {300, -150}, {300, -1}, {-40, -1}});
  engine.flush(car.sink);
  CHECK(judge(car, car.sink.events).wrong == 0);
  REQUIRE(car.sink.events.size() >= 1);
  CHECK(car.sink.events[0].k == 3);
  CHECK(engine.place_counters().across >= 1);  // the corner and one marking: two pairs are not enough
}

TEST_CASE("a place of two is no loop where a stored marking went unseen on the way in", "[engine][place]") {
  // Three markings; the third from the west (first passed) is gone when the
  // car comes back: what is left is a place of two, and the car looked
  // where the third was and saw nothing there.
  for (const unsigned max_unseen : {0u, 1u}) {
    INFO("unseen allowed " << max_unseen);
    EngineConfig config = place_config(3);
    config.match.place_pair_min_bits = 1.0;
    config.match.place_pair_max_unseen = max_unseen;
    SequenceEngine engine(config);
    std::vector<Mark> world = {{90, -1, 3}, {100, -1, 14}, {106, -1, 15}};
    Car car(engine, world);
    car.drive({{0, 0}, {200, 0}, {200, 100}, {-40, 100}, {-40, 0}});
    world.erase(world.begin());
    car.drive({{-40, 0}, {200, 0}});
    engine.flush(car.sink);
    CHECK(judge(car, car.sink.events).wrong == 0);
    if (max_unseen == 0) {
      CHECK(car.sink.events.empty());
      CHECK(engine.place_counters().unseen >= 1);
    } else {
      REQUIRE(car.sink.events.size() == 1);
      CHECK(car.sink.events[0].k == 2);
    }
  }
}

TEST_CASE("another visit's copy of a paired marking, drifted along the road, is not unseen",
          "[engine][place]") {
  // Two markings on a street driven north three times. From the second visit
  // on, the odometry places everything 6 m further north: aligned onto the
  // second visit, the first visit's copies of the two markings lie 6 m behind
  // the landmarks, where the car looked and saw none.
  const std::vector<Mark> world = {{1, 100, 14}, {1, 106, 15}};
  SequenceEngine engine(places_of_two_config());
  Car car(engine, world);
  const std::size_t third_visit = drive_north_three_times(engine, car);
  CHECK(judge(car, car.sink.events).wrong == 0);
  // One loop for each revisit.
  REQUIRE(car.sink.events.size() == 2);
  CHECK(car.sink.events[third_visit].k == 2);
  CHECK(engine.place_counters().unseen == 0);
}

TEST_CASE("another visit's copy of a marking not paired is judged by the fitted visit's own copy",
          "[engine][place]") {
  // Two markings, and a third 2 m past the second, on a street driven north
  // three times; from the second visit on, the odometry places everything
  // 6 m further north. When the third visit's second marking is released, the
  // first visit's copy of the third marking, aligned onto the second visit,
  // lies 6 m behind it: passed, with nothing there. The second visit's own
  // copy lies ahead, not yet released, and is the one to judge.
  const std::vector<Mark> world = {{1, 100, 14}, {1, 106, 15}, {1, 108, 3}};
  SequenceEngine engine(places_of_two_config());
  Car car(engine, world);
  const std::size_t third_visit = drive_north_three_times(engine, car);
  CHECK(judge(car, car.sink.events).wrong == 0);
  REQUIRE(car.sink.events.size() > third_visit);
  CHECK(car.sink.events[third_visit].k == 2);
  CHECK(engine.place_counters().unseen == 0);
}

TEST_CASE("a street driven back the other way is the same place", "[engine][place]") {
  // Markings alike from either way, or painted for driving east and read
  // turned on the way back.
  for (const double painted_yaw : {std::nan(""), 0.0}) {
    std::vector<Mark> world = town();
    for (Mark& m : world) m.painted_yaw = painted_yaw;
    SequenceEngine engine(place_config(3));
    Car car(engine, world);
    car.drive({{0, 0}, {330, 0}, {330, 300}, {320, 300}, {320, -1}});
    car.drive({{320, -1}, {0, -1}});  // back west along the street
    engine.flush(car.sink);
    const Outcome o = judge(car, car.sink.events);
    CHECK(o.wrong == 0);
    CHECK(o.matches >= 3);
  }
}

TEST_CASE("a place of common labels met from the other direction is matched only so far back",
          "[engine][place]") {
  // The street driven east, then back west some 600 to 900 m later.
  const std::vector<Mark> world = town();
  const auto places = [&](double opposite_within_m) {
    EngineConfig config = places_of_two_config();
    config.match.place_min_bits = 100.0;  // every place's labels too common
    config.match.place_opposite_within_m = opposite_within_m;
    SequenceEngine engine(config);
    Car car(engine, world);
    car.drive({{0, 0}, {330, 0}, {330, 300}, {320, 300}, {320, -1}, {0, -1}});
    engine.flush(car.sink);
    CHECK(judge(car, car.sink.events).wrong == 0);
    return engine.place_counters().matches;
  };
  CHECK(places(2500.0) >= 1);
  CHECK(places(500.0) == 0);
}

TEST_CASE("markings painted for opposite directions are two places, though the drift lays them together",
          "[engine][place]") {
  // Three markings on an eastbound street (y = 0) and the same three on a
  // westbound one 60 m north. The odometry lays the second street on the
  // first, the cars 1 m apart, as a street driven back the other way.
  const auto drive = [](double west_painted_yaw) {
    std::vector<Mark> world;
    for (const Mark m : {Mark{100, -1, 3}, Mark{107, 1, 5}, Mark{115, -1, 7}}) {
      world.push_back({m.x, m.y, m.label, 0.0});
      world.push_back({m.x, m.y + 61, m.label, west_painted_yaw});
    }
    SequenceEngine engine(place_config(3));
    Car car(engine, world);
    car.drive({{0, 0}, {260, 0}, {260, 60}});
    car.drift = -60.0;
    car.drive({{260, 60}, {0, 60}});
    engine.flush(car.sink);
    return judge(car, car.sink.events);
  };
  // Painted for the westbound car, read upright by it: two markings each.
  const Outcome painted_west = drive(std::numbers::pi);
  CHECK(painted_west.matches == 0);
  // Painted the same way as the eastbound street's, the westbound car reads
  // them turned, as on the same street: a place the engine cannot tell from
  // the first.
  CHECK(drive(0.0).wrong >= 1);
}

TEST_CASE("a place met from a cross street names the frames where the cars were closest", "[engine][place]") {
  // Three markings round a crossing, passed eastwards, then northwards.
  // Northwards the car passes the last one 8.6 m from where it passed it
  // eastwards; the middle one, on both paths, 1 m.
  const std::vector<Mark> world = {{98, -4, 14}, {104, 1, 15}, {111, 5, 1}};
  SequenceEngine engine(place_config(3));
  Car car(engine, world);
  car.drive({{0, 0}, {200, 0}, {200, -150}, {104, -150}, {104, 100}});
  engine.flush(car.sink);
  REQUIRE(car.sink.events.size() >= 1);
  CHECK(judge(car, car.sink.events).wrong == 0);
  const MatchEvent& e = car.sink.events[0];
  const Point q = car.trail()[e.query_frame()], m = car.trail()[e.match_frame()];
  CHECK(std::hypot(q.x - m.x, q.y - m.y) < 2.0);
  CHECK(e.query[e.framed].label == 15);
}

TEST_CASE("a place repeated nearby is never a loop", "[engine][place]") {
  // The same three markings at x = 100 and x = 140, nothing else: the
  // second lies beyond the drift limits of the revisit, but not so far
  // beyond that the odometry could not be that wrong.
  std::vector<Mark> world;
  for (double base : {100.0, 140.0})
    for (const Mark m : {Mark{0, -1, 14}, Mark{6, -1, 15}, Mark{14, -1, 1}})
      world.push_back({base + m.x, m.y, m.label});
  SequenceEngine engine(place_config(3));
  Car car(engine, world);
  // Past both, round a block, then past the first one only, turning off
  // before the second comes into view.
  car.drive({{0, 0}, {260, 0}, {260, 200}, {-40, 200}, {-40, 0}, {118, 0}, {118, 200}});
  engine.flush(car.sink);
  CHECK(car.sink.events.empty());
  CHECK(engine.place_counters().ambiguous >= 1);
}

TEST_CASE("a look-alike far beyond the drift limits leaves the place alone", "[engine][place]") {
  // The same three markings at x = 100 and x = 200: the odometry cannot be
  // 100 m wrong after 700 m, so the revisit of the first is a loop.
  std::vector<Mark> world;
  for (double base : {100.0, 200.0})
    for (const Mark m : {Mark{0, -1, 14}, Mark{6, -1, 15}, Mark{14, -1, 1}})
      world.push_back({base + m.x, m.y, m.label});
  SequenceEngine engine(place_config(3));
  Car car(engine, world);
  car.drive({{0, 0}, {260, 0}, {260, 200}, {-40, 200}, {-40, 0}, {150, 0}, {150, 200}});
  engine.flush(car.sink);
  REQUIRE(car.sink.events.size() >= 1);
  CHECK(judge(car, car.sink.events).wrong == 0);
  CHECK(engine.place_counters().ambiguous == 0);
}

TEST_CASE("a place beyond the odometry's drift is not matched", "[engine][place]") {
  const std::vector<Mark> world = {{100, -1, 14}, {106, -1, 15}, {114, -1, 1}};
  EngineConfig config = place_config(3);
  config.match.place_distinct_m = config.match.place_search_m = 20.0;
  for (const double drift : {0.0, 25.0}) {
    INFO("drift " << drift);
    SequenceEngine engine(config);
    Car car(engine, world);
    car.drive({{0, 0}, {200, 0}, {200, 100}, {-40, 100}});
    car.drift = drift;  // the odometry has drifted this far to the north since
    car.drive({{-40, 100}, {-40, 0}, {200, 0}});
    engine.flush(car.sink);
    CHECK(judge(car, car.sink.events).wrong == 0);
    CHECK(car.sink.events.size() == (drift == 0.0 ? 1u : 0u));
  }
}

TEST_CASE("one marking seen in pieces is one pair, not a place", "[engine][place]") {
  // A crosswalk the detector sees as three pieces 1.5 m apart across the
  // road: in a row, they fit the same row shifted along it, so they count as
  // one marking. Three separate markings 6 m apart are a place.
  for (const double spacing : {1.5, 6.0}) {
    INFO("spacing " << spacing);
    std::vector<Mark> world;
    for (int i = 0; i < 3; ++i)
      world.push_back({100.0 + (spacing > 2 ? spacing * i : 0.0), -1.5 + 1.5 * i, 14});
    SequenceEngine engine(place_config(3));
    Car car(engine, world);
    car.drive({{0, 0}, {200, 0}, {200, 100}, {-40, 100}, {-40, 0}, {200, 0}});
    engine.flush(car.sink);
    CHECK(judge(car, car.sink.events).wrong == 0);
    if (spacing < 2)
      CHECK(engine.place_counters().matches == 0);
    else
      CHECK(engine.place_counters().matches >= 1);
  }
}

TEST_CASE("a place whose fit is off by more than the place residual is not matched", "[engine][place]") {
  // The third marking lies 0.5 m further on when the car comes back (a
  // look-alike's spacing): the fit is off by about 0.2 m.
  for (const double limit : {0.5, 0.1}) {
    INFO("place residual " << limit);
    EngineConfig config = place_config(3);
    config.match.place_max_residual_m = limit;
    SequenceEngine engine(config);
    std::vector<Mark> world = {{100, -1, 14}, {106, -1, 15}, {114, -1, 1}};
    Car car(engine, world);
    car.drive({{0, 0}, {200, 0}, {200, 100}, {-40, 100}, {-40, 0}});
    world[2].x += 0.5;
    car.drive({{-40, 0}, {200, 0}});
    engine.flush(car.sink);
    if (limit > 0.3) {
      CHECK(car.sink.events.size() == 1);
    } else {
      CHECK(car.sink.events.empty());
      CHECK(engine.place_counters().rejected_residual >= 1);
    }
  }
}

TEST_CASE("place matching settings are checked", "[engine][place]") {
  EngineConfig config;
  config.match.place_landmarks = 1;
  CHECK(validate(config) != nullptr);
  config.match.place_landmarks = 3;
  CHECK(validate(config) == nullptr);
  config.match.place_window_m = 0;
  CHECK(validate(config) != nullptr);
  config.match.place_window_m = 60;
  config.match.place_max_residual_m = 0;
  CHECK(validate(config) != nullptr);
  config.match.place_max_residual_m = 0.5;
  config.match.place_pair_min_bits = -1;
  CHECK(validate(config) != nullptr);
  config.match.place_pair_min_bits = 4;
  CHECK(validate(config) == nullptr);
  config.match.place_view_depth_m = 0;
  CHECK(validate(config) != nullptr);
}

TEST_CASE("a sequence match between visits far apart waits for a longer run", "[engine][far]") {
  const std::vector<Mark> world = town();
  const auto first_loop_x = [&](double far_run_m, std::uint64_t& held) {
    EngineConfig config = place_config(0);
    config.match.far_after_m = 200.0;
    config.match.far_run_m = far_run_m;
    SequenceEngine engine(config);
    Car car(engine, world);
    car.drive({{0, 0}, {330, 0}, {330, -300}, {0, -300}, {0, 0}, {330, 0}});
    engine.flush(car.sink);
    held = engine.counters().matches_held_far;
    CHECK(judge(car, car.sink.events).wrong == 0);
    REQUIRE(!car.sink.events.empty());
    const MatchEvent& first = car.sink.events[0];
    return static_cast<double>(first.query[first.k - 1].x);
  };
  std::uint64_t held_at_once = 0, held_for_run = 0;
  const double at_once = first_loop_x(0.0, held_at_once);
  const double after_run = first_loop_x(60.0, held_for_run);
  CHECK(held_at_once == 0);
  CHECK(held_for_run >= 1);
  // The first markings are 57, 80, 99 and 128 m along: the run from 57 m
  // spans 60 m only at the fifth.
  CHECK(at_once < 110.0);
  CHECK(after_run > at_once);
  CHECK(after_run - 57.0 >= 60.0);
}

TEST_CASE("a far visit's run goes on through rows of markings side by side", "[engine][far]") {
  // Every row of the street holds two markings across the road: the
  // sequences through it end on either, and the run must not start again
  // each time they change.
  std::vector<Mark> world = town();
  for (std::size_t i = 0; i < 12; ++i)  // town()'s first twelve: the street's
    world.push_back({world[i].x + 0.3, 2.5, static_cast<Label>((i * 7 + 3) % 11)});
  EngineConfig config = place_config(0);
  config.match.far_after_m = 200.0;
  config.match.far_run_m = 100.0;
  SequenceEngine engine(config);
  Car car(engine, world);
  car.drive({{0, 0}, {330, 0}, {330, -300}, {0, -300}, {0, 0}, {330, 0}});
  engine.flush(car.sink);
  CHECK(judge(car, car.sink.events).wrong == 0);
  REQUIRE(!car.sink.events.empty());
  const MatchEvent& first = car.sink.events[0];
  // The run from the first row (40 m) spans 100 m at the sixth (144 m).
  CHECK(first.query[first.k - 1].x > 140.0);
  CHECK(first.query[first.k - 1].x < 150.0);
}
