#include <catch2/catch_test_macros.hpp>

#include <array>
#include <cmath>
#include <numbers>
#include <set>
#include <string>

#include "sim/drive.hpp"
#include "sim/world.hpp"
#include "tests/support/result_checks.hpp"

using namespace markloop;
using namespace markloop::sim;
using markloop::test::error_of;
using markloop::test::loaded;

namespace {

constexpr double kPi = std::numbers::pi;

// A 200 m circle driven `laps` times, weaving 0.3 m so no pass retraces
// another exactly (as real recorded routes do).
Path circle_route(double laps) {
  Path p;
  const double r = 100.0;
  const int steps = static_cast<int>(laps * 2 * kPi * r / 0.5);
  for (int i = 0; i <= steps; ++i) {
    const double a = -kPi / 2 + i * 0.5 / r;
    const double rr = r + 0.3 * std::sin(i * 0.5 / 23.0);
    p.add_point(rr * std::cos(a), 100.0 + rr * std::sin(a));
  }
  return p;
}

// Appends the straight from (x0, y0) towards (x1, y1) in 0.5 m steps.
void add_straight(Path& route, double x0, double y0, double x1, double y1) {
  const int steps = static_cast<int>(std::hypot(x1 - x0, y1 - y0) / 0.5);
  for (int i = 0; i < steps; ++i) route.add_point(x0 + (x1 - x0) * i / steps, y0 + (y1 - y0) * i / steps);
}

// Rows 4 to 5 m apart with a marking in every lane (every class as likely
// when `every_class`): dense enough that a rule left out shows.
WorldConfig dense_rows(bool every_class) {
  WorldConfig config;
  config.row_spacing_min_m = 4.0;
  config.row_spacing_max_m = 5.0;
  config.marking_probability = 1.0;
  if (every_class) {
    std::array<double, kClassCount> equal;
    equal.fill(1.0);
    config.class_weights = equal;
  }
  return config;
}

}  // namespace

TEST_CASE("a road driven again gets no second set of markings") {
  const Path route = circle_route(1.6);
  const double lap = 2 * kPi * 100.0;
  const Scenario world = make_route_scenario("circle", route, 7);
  REQUIRE(world.markings.size() > 10);
  // Markings are laid only along the first lap.
  for (const Marking& m : world.markings) {
    for (const Marking& other : world.markings)
      if (other.id != m.id) CHECK(std::hypot(other.x - m.x, other.y - m.y) > 1.0);
  }
  // The same world laid along one lap only has the same markings.
  const Scenario one_lap = make_route_scenario("circle", circle_route(1.0), 7);
  CHECK(one_lap.markings.size() <= world.markings.size());
  CHECK(world.markings.size() <= one_lap.markings.size() + 1);

  // Driving it: what the car passes on the second lap is what it passed on
  // the first.
  DriveConfig config;
  config.detection_probability = 1.0;
  config.false_positives_per_frame = 0.0;
  Drive drive(world, config, 3);
  std::set<std::uint32_t> first, second;
  DriveFrame frame;
  while (drive.next(frame)) {
    const double s = frame.estimate.t * config.speed_mps;
    for (const std::uint32_t id : frame.observed_marking_ids) {
      if (s < lap - 30) first.insert(id);
      if (s > lap + 30) second.insert(id);
    }
  }
  REQUIRE(second.size() >= 5);
  for (const std::uint32_t id : second) CHECK(first.count(id) == 1);
}

TEST_CASE("the world's roads are laid once per road too") {
  const Scenario world = make_route_scenario("circle", circle_route(1.6), 7);
  const Scenario one_lap = make_route_scenario("circle", circle_route(1.0), 7);
  // Strips of 1 to 2 m: the extra 0.6 lap adds none beyond the closing seam.
  CHECK(world.strips.size() <= one_lap.strips.size() + 20);
}

TEST_CASE("no marking is painted inside an intersection") {
  // East along y = 0, round a block, then south along x = 0: the route
  // crosses itself at right angles at the origin.
  Path route;
  add_straight(route, -100, 0, 100, 0);
  add_straight(route, 100, 0, 100, 100);
  add_straight(route, 100, 100, 0, 100);
  add_straight(route, 0, 100, 0, -100);
  const WorldConfig config = dense_rows(false);  // without the rule, some would fall on the crossing
  const Scenario world = make_route_scenario("crossing", route, 11, config);
  // Each road covers from its right edge (lane 0's centre less half a lane
  // and the shoulder) to its left edge: [-2.35, 5.85] m across, both ways.
  const double right = -config.lane_width_m / 2 - 0.6;
  const double left = (config.lanes - 0.5) * config.lane_width_m + 0.6;
  int near = 0;
  for (const Marking& m : world.markings) {
    const bool eastward = std::abs(std::cos(m.heading)) > 0.9;
    const double along = eastward ? m.x : m.y;  // where it lies along its road
    const double across = eastward ? m.y : m.x;
    if (std::abs(across - (right + left) / 2) > (left - right) / 2) continue;  // not by the crossing
    INFO("marking " << m.id << " at " << m.x << ", " << m.y << ", " << m.length_m << " m long");
    // Its footprint along its road stays off the other road's width.
    CHECK((along + m.length_m / 2 < right || along - m.length_m / 2 > left));
    near += std::abs(along) < 15.0 ? 1 : 0;
  }
  CHECK(near >= 2);  // markings up to the intersection, not a road left bare
}

TEST_CASE("no marking is painted over or against another") {
  // A straight road east, rows 4 to 5 m apart with a marking in every lane
  // and every class as likely: without the rule, arrows 6 m long would lie
  // over the row before and crosswalks over the markings beside them.
  Path route;
  for (int i = 0; i <= 800; ++i) route.add_point(i * 0.5, 0.0);
  const Scenario world = make_route_scenario("dense", route, 3, dense_rows(true));
  REQUIRE(world.markings.size() >= 40);  // a road still marked, not left bare
  int crosswalks = 0;
  for (std::size_t i = 0; i < world.markings.size(); ++i) {
    const Marking& a = world.markings[i];
    crosswalks += marking_class_names()[a.label] == "crosswalk" ? 1 : 0;
    for (std::size_t j = i + 1; j < world.markings.size(); ++j) {
      const Marking& b = world.markings[j];
      const bool side_by_side = std::abs(a.y - b.y) < (a.width_m + b.width_m) / 2;
      if (!side_by_side) continue;  // in other lanes
      INFO("markings " << a.id << " and " << b.id << " at x " << a.x << " and " << b.x);
      // At least a metre of bare road between their ends.
      CHECK(std::abs(a.x - b.x) - (a.length_m + b.length_m) / 2 >= 1.0 - 1e-9);
    }
  }
  CHECK(crosswalks >= 2);
}

TEST_CASE("no line crosses a marking, on a corner or where another road runs") {
  // East, round a 12 m corner north, sharply west, then sharply back
  // south-east across the first street at 30 degrees (too shallow to be an
  // intersection), dense rows. Without the rule, markings laid where the
  // road turns lie across their own lane's lines, and the slanting road's
  // lines across the first street's markings (both seen failing).
  Path route;
  add_straight(route, -200, 0, 0, 0);
  for (int i = 0; i < 40; ++i) {
    const double a = -kPi / 2 + kPi / 2 * i / 40.0;
    route.add_point(12 * std::cos(a), 12 + 12 * std::sin(a));
  }
  add_straight(route, 12, 12, 12, 40);
  add_straight(route, 12, 40, -169.3, 40);
  add_straight(route, -169.3, 40, -30.7, -40);  // crosses y = 0 at x = -100
  const Scenario world = make_route_scenario("corner", route, 5, dense_rows(true));
  int near_corner = 0, near_slant = 0;
  for (const Marking& m : world.markings) {
    // A crosswalk spans the road, over the lines between its lanes.
    if (marking_class_names()[m.label] == "crosswalk") continue;
    near_corner += std::hypot(m.x, m.y - 12) < 25.0 ? 1 : 0;
    near_slant += std::abs(m.y) < 5.0 && std::abs(m.x + 100) < 30.0 ? 1 : 0;
    const double c = std::cos(m.heading), s = std::sin(m.heading);
    // Points along each line's middle, inside the footprint less 0.1 m (a
    // stop line meets the edge line by design).
    const auto crosses = [&](const Strip& strip) {
      for (double t = -1.0; t <= 1.0; t += 0.25) {
        const double x = strip.x + std::cos(strip.heading) * strip.half_length * t - m.x;
        const double y = strip.y + std::sin(strip.heading) * strip.half_length * t - m.y;
        const double along = x * c + y * s, across = -x * s + y * c;
        if (std::abs(along) < m.length_m / 2 - 0.1 && std::abs(across) < m.width_m / 2 - 0.1) return true;
      }
      return false;
    };
    for (const Strip& strip : world.strips) {
      if (strip.kind == StripKind::kRoad || !crosses(strip)) continue;
      FAIL_CHECK("marking " << m.id << " (" << marking_class_names()[m.label] << ") at " << m.x << ", " << m.y
                            << " crossed by a line at " << strip.x << ", " << strip.y);
    }
  }
  // The straights still marked, up to the corner and the slanting road.
  CHECK(world.markings.size() >= 60);
  CHECK(near_corner >= 2);
  CHECK(near_slant >= 2);
}

TEST_CASE("built-in scenarios lay markings of the classifier's classes") {
  for (const std::string& name : scenario_names()) {
    const auto s = make_scenario(name, 2);
    REQUIRE(s);
    CHECK(s->markings.size() > 10);
    CHECK(!s->strips.empty());
    for (const Marking& m : s->markings) {
      REQUIRE(m.label < kClassCount);
      CHECK(m.length_m > 0.2);
      CHECK(m.width_m > 0.5);
    }
  }
  CHECK_FALSE(make_scenario("nowhere", 1));
}

TEST_CASE("the same seed gives the same world, another seed another") {
  const auto a = make_scenario("grid", 5), b = make_scenario("grid", 5), c = make_scenario("grid", 6);
  REQUIRE(a->markings.size() == b->markings.size());
  for (std::size_t i = 0; i < a->markings.size(); ++i) {
    CHECK(a->markings[i].label == b->markings[i].label);
    CHECK(a->markings[i].x == b->markings[i].x);
  }
  bool differs = a->markings.size() != c->markings.size();
  for (std::size_t i = 0; !differs && i < a->markings.size(); ++i)
    differs = a->markings[i].label != c->markings[i].label || a->markings[i].x != c->markings[i].x;
  CHECK(differs);
}

TEST_CASE("the city grid repeats its blocks' layouts") {
  // Identical-looking blocks are the hard case for false loops: several
  // stretches of street carry the same sequence of classes.
  const auto grid = make_scenario("grid", 1);
  std::set<std::string> triples;
  int repeats = 0;
  for (std::size_t i = 0; i + 2 < grid->markings.size(); ++i) {
    const std::string key = std::to_string(grid->markings[i].label) + "," +
                            std::to_string(grid->markings[i + 1].label) + "," +
                            std::to_string(grid->markings[i + 2].label);
    if (!triples.insert(key).second) ++repeats;
  }
  CHECK(repeats >= 5);
}

TEST_CASE("class weights choose the classes laid") {
  WorldConfig config;
  config.class_weights = loaded(parse_class_weights("stop=1,diamond=3"));
  const auto s = make_scenario("ring", 1, config);
  int stops = 0, diamonds = 0;
  for (const Marking& m : s->markings) {
    REQUIRE((marking_class_names()[m.label] == "stop" || marking_class_names()[m.label] == "diamond"));
    (marking_class_names()[m.label] == "stop" ? stops : diamonds)++;
  }
  CHECK(diamonds > stops);

  CHECK(error_of(parse_class_weights("stop")).find("NAME=WEIGHT") != std::string::npos);
  CHECK(error_of(parse_class_weights("zebra=1")).find("unknown marking class 'zebra'") != std::string::npos);
  CHECK_FALSE(parse_class_weights("stop=-1"));
  CHECK_FALSE(parse_class_weights("stop=0"));
}

TEST_CASE("legacy scenarios keep their marking mix (no stop lines or crosswalks)") {
  const auto s = make_scenario("ring", 3);
  for (const Marking& m : s->markings) CHECK(m.label < 14);
}
