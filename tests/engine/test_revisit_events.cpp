// Revisit events found in synthetic truth (issue 64's measure): their
// extent, length and kind, the 30 s age and 3 s gap rules, and the distance
// at which the first correct detection closes each.
#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <utility>
#include <vector>

#include "app/tools/replay/revisit_events.hpp"

using namespace markloop;
using namespace markloop::replay;
using Catch::Approx;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kFrame_s = 0.1;
constexpr double kSpeed_mps = 10.0;  // 1 m per frame

// A synthetic drive: the car's true pose and time per frame at 10 Hz.
struct Drive {
  std::vector<Pose2> poses;
  std::vector<double> times;

  double now() const { return times.empty() ? 0.0 : times.back() + kFrame_s; }
  // Straight on for `metres` from (x, y) heading `yaw`, one metre a frame.
  Drive& straight(double x, double y, double yaw, double metres) {
    const auto frames = static_cast<int>(std::lround(metres / (kSpeed_mps * kFrame_s)));
    for (int i = 0; i < frames; ++i) {
      const double t = now();
      poses.push_back({x + std::cos(yaw) * i, y + std::sin(yaw) * i, yaw});
      times.push_back(t);
    }
    return *this;
  }
  // Stands still far away (10 km off) for `seconds`: frames that revisit nothing.
  Drive& away(double seconds) {
    const auto frames = static_cast<int>(std::lround(seconds / kFrame_s));
    for (int i = 0; i < frames; ++i) {
      const double t = now();
      poses.push_back({10000.0 + 10.0 * static_cast<double>(poses.size()), 10000.0, 0.0});
      times.push_back(t);
    }
    return *this;
  }
  // A circle of `radius` about the origin, counter-clockwise, `laps` times.
  Drive& circle(double radius, double laps) {
    const double step = kSpeed_mps * kFrame_s / radius;
    const auto frames = static_cast<int>(std::lround(laps * 2.0 * kPi / step));
    for (int i = 0; i < frames; ++i) {
      const double a = step * i, t = now();
      poses.push_back({radius * std::cos(a), radius * std::sin(a), a + kPi / 2.0});
      times.push_back(t);
    }
    return *this;
  }
  std::vector<RevisitEvent> events() const { return find_revisit_events(poses, times); }
};

}  // namespace

TEST_CASE("a loop driven twice the same way is one same-direction event of its second lap") {
  // 628 m a lap, 62.8 s: every frame of lap 2 is 62.8 s after its place in lap 1.
  Drive d;
  d.circle(100.0, 2.0);
  const auto events = d.events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RevisitKind::SameDirection);
  // Lap 2 starts revisiting a few metres before the lap closes (6 m).
  CHECK(events[0].first_frame == Approx(628 - 6).margin(1));
  CHECK(events[0].last_frame == d.poses.size() - 1);
  CHECK(events[0].length_m == Approx(628.0 + 6.0).margin(2.0));
}

TEST_CASE("a road driven back the other way is an opposite-direction event") {
  Drive d;
  d.straight(0, 0, 0, 300).away(40).straight(300, 3.5, kPi, 300);
  const auto events = d.events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RevisitKind::OppositeDirection);
  CHECK(events[0].length_m == Approx(299.0).margin(2.0));
}

TEST_CASE("a perpendicular pass over an old road is a short crossing") {
  Drive d;
  d.straight(0, 0, 0, 300).away(40).straight(100, -100, kPi / 2, 200);
  const auto events = d.events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RevisitKind::Crossing);
  CHECK(events[0].length_m == Approx(12.0).margin(1.0));
  CHECK(events[0].length_m < kLongRevisit_m);
}

TEST_CASE("a turn onto an old road that then runs 70 m along it the same way is same-direction") {
  // Up from the south to the junction at x = 100, then east along the old road.
  Drive d;
  d.straight(0, 0, 0, 300).away(40).straight(100, -60, kPi / 2, 60).straight(100, 0, 0, 71).away(40);
  const auto events = d.events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RevisitKind::SameDirection);
  CHECK(events[0].length_m == Approx(76.0).margin(2.0));
}

TEST_CASE("a turn onto an old road that leaves it again after 5 m is a crossing") {
  Drive d;
  d.straight(0, 0, 0, 300)
      .away(40)
      .straight(100, -60, kPi / 2, 60)
      .straight(100, 0, 0, 5)
      .straight(105, 0, -kPi / 2, 60);
  const auto events = d.events();
  REQUIRE(events.size() == 1);
  CHECK(events[0].kind == RevisitKind::Crossing);
}

TEST_CASE("revisit frames 2.9 s apart make one event, 3.1 s apart two") {
  for (const auto& [gap_s, expected] : {std::pair{2.9, 1u}, std::pair{3.1, 2u}}) {
    Drive d;
    // The revisit is interrupted by frames away from the road: the gap is
    // the time from the last revisit frame to the next.
    d.straight(0, 0, 0, 300).away(40).straight(0, 1, 0, 100).away(gap_s - kFrame_s).straight(100, 1, 0, 100);
    const auto events = d.events();
    INFO("gap " << gap_s << " s");
    CHECK(events.size() == expected);
    for (const RevisitEvent& e : events) CHECK(e.kind == RevisitKind::SameDirection);
  }
}

TEST_CASE("a place driven again 29 s later is no revisit; 31 s later it is") {
  for (const auto& [later_s, expected] : {std::pair{29.0, 0u}, std::pair{31.0, 1u}}) {
    // The same 100 m twice, the second time `later_s` after the first,
    // frame for frame.
    Drive d;
    d.straight(0, 0, 0, 100).away(later_s - 10.0).straight(0, 0, 0, 100);
    INFO("driven again " << later_s << " s later");
    CHECK(d.events().size() == expected);
  }
}

TEST_CASE("the first correct detection with its query frame in an event closes it") {
  Drive d;
  d.straight(0, 0, 0, 300).away(40).straight(0, 1, 0, 200).away(40).straight(300, 1, kPi, 100);
  auto events = d.events();
  REQUIRE(events.size() == 2);
  const std::size_t first = events[0].first_frame;
  REQUIRE(first == 700);  // 300 m, then 400 frames away
  const std::vector<ClosingDetection> detections = {
      {first + 10, first + 20, false},                             // wrong: closes nothing
      {first - 5, first + 2, true},                                // query before the event
      {first + 30, first + 45, true},                              // closes it 45 m in
      {first + 25, first + 40, true},                              // reached the bus earlier: 40 m in
      {first + 60, first + 90, true},                              // later than that
      {events[1].last_frame + 5, events[1].last_frame + 5, true},  // beyond the truth
  };
  close_revisit_events(events, d.poses, detections);
  REQUIRE(events[0].closed_at_m);
  CHECK(*events[0].closed_at_m == Approx(40.0));
  CHECK(events[0].closing_query_frame == first + 25);
  CHECK_FALSE(events[1].closed_at_m);
}

TEST_CASE("the tally counts events by kind and length and spreads the closure distances") {
  std::vector<RevisitEvent> events(12);
  for (std::size_t i = 0; i < events.size(); ++i) {
    events[i].length_m = 100.0;
    events[i].kind = RevisitKind::SameDirection;
    events[i].closed_at_m = 10.0 * static_cast<double>(i + 1);  // 10 .. 120 m
  }
  events[11].closed_at_m.reset();                   // 11 closed: 10 .. 110 m
  events[0].length_m = 20.0;                        // a short one, closed at 10 m
  events[1].kind = RevisitKind::OppositeDirection;  // closed at 20 m
  const RevisitTally t = tally_revisit_events(events);
  CHECK(t.all.total == 12);
  CHECK(t.all.closed == 11);
  CHECK(t.shorter.total == 1);
  CHECK(t.longer.total == 11);
  CHECK(t.longer.closed == 10);
  const auto same = static_cast<std::size_t>(RevisitKind::SameDirection);
  const auto opposite = static_cast<std::size_t>(RevisitKind::OppositeDirection);
  CHECK(t.by_kind[same][1].total == 10);
  CHECK(t.by_kind[same][1].closed == 9);
  CHECK(t.by_kind[same][0].total == 1);
  CHECK(t.by_kind[opposite][1].closed == 1);
  // All closed: 10 .. 110 m, median 60, p90 the 10th of 11 (nearest rank) = 100.
  CHECK(t.closure_all.count == 11);
  CHECK(t.closure_all.median_m == Approx(60.0));
  CHECK(t.closure_all.p90_m == Approx(100.0));
  // Long and closed: 20 .. 110 m, median 65, p90 the 9th of 10 = 100.
  CHECK(t.closure_long.count == 10);
  CHECK(t.closure_long.median_m == Approx(65.0));
  CHECK(t.closure_long.p90_m == Approx(100.0));
}

namespace {

// The views of a marking at (x, y) from every frame of `d` in which it lies
// in view (anywhere ahead within 40 m): the area counted as seen is
// mark_shared_markings's to apply.
void add_views(const Drive& d, std::uint32_t marking, double x, double y, std::size_t first_frame,
               std::size_t end_frame, std::vector<MarkingView>& views) {
  for (std::size_t f = first_frame; f < end_frame && f < d.poses.size(); ++f) {
    const Pose2 at = compose(inverse(d.poses[f]), Pose2{x, y, 0.0});
    if (at.x > 0.0 && at.x < 40.0) views.push_back({f, marking, at.x, at.y});
  }
}

// Distance driven to the first frame at `p`.
double travelled_to(const Drive& d, const Pose2& p) {
  double metres = 0.0;
  for (std::size_t i = 1; i < d.poses.size(); ++i) {
    if (std::hypot(d.poses[i - 1].x - p.x, d.poses[i - 1].y - p.y) < 1e-6) return metres;
    metres += std::hypot(d.poses[i].x - d.poses[i - 1].x, d.poses[i].y - d.poses[i - 1].y);
  }
  return metres;
}

}  // namespace

TEST_CASE("an event's shared markings: seen ahead on both visits, passed where last seen") {
  Drive d;
  d.straight(0, 0, 0, 300).away(40).straight(0, 1, 0, 200);
  auto events = d.events();
  REQUIRE(events.size() == 1);
  const std::size_t second_visit = events[0].first_frame;
  REQUIRE(second_visit == 700);
  std::vector<MarkingView> views;
  // On the road, seen on both visits: last seen 5.5 m ahead or more, so at
  // 44, 94 and 144 m of the second visit (one metre a frame).
  for (const auto& [id, x] : {std::pair{1u, 50.0}, {2u, 100.0}, {3u, 150.0}})
    add_views(d, id, x, 1.0, 0, d.poses.size(), views);
  // Only on the second visit: new paint is nothing shared.
  add_views(d, 4, 70.0, 1.0, second_visit, d.poses.size(), views);
  // Beside the road (7 m): in view, but out of the area the ECU observes.
  add_views(d, 5, 80.0, 8.0, 0, d.poses.size(), views);
  // Beyond the truth: ignored.
  views.push_back({d.poses.size() + 5, 6, 10.0, 0.0});
  mark_shared_markings(events, d.poses, d.times, views);
  REQUIRE(events[0].seen);
  const SharedMarkings& e = *events[0].seen;
  CHECK(e.count == 3);
  REQUIRE(e.second_m);
  REQUIRE(e.third_m);
  CHECK(*e.second_m == Approx(94.0));
  CHECK(*e.third_m == Approx(144.0));

  // With the third marking gone there is no third.
  std::erase_if(views, [](const MarkingView& v) { return v.marking == 3; });
  mark_shared_markings(events, d.poses, d.times, views);
  CHECK(events[0].seen->count == 2);
  CHECK_FALSE(events[0].seen->third_m);
}

TEST_CASE("a marking passed just before a turn onto the old road counts at 0 m") {
  // The old road runs east along y = 0; the car comes back from the south
  // along x = 20 and turns onto it. The crossing's marking at (20, 0) was
  // seen from the old road, and is last seen 5.5 m or more ahead, before
  // the car comes within 6 m of the old road.
  Drive d;
  d.straight(0, 0, 0, 300).away(40).straight(20, -60, kPi / 2.0, 60).straight(20, 1, 0, 100);
  auto events = d.events();
  REQUIRE(events.size() == 1);
  std::vector<MarkingView> views;
  add_views(d, 1, 20.0, 0.0, 0, d.poses.size(), views);
  add_views(d, 2, 60.0, 0.5, 0, d.poses.size(), views);
  mark_shared_markings(events, d.poses, d.times, views);
  REQUIRE(events[0].seen);
  REQUIRE(events[0].seen->second_m);
  CHECK(events[0].seen->count == 2);
  // The second: last seen from x = 54, 33 m of driving after the event's
  // first frame (y = -5: 5 m north, then 1 m of the jog, then 34 m east).
  CHECK(*events[0].seen->second_m ==
        Approx(travelled_to(d, {54.0, 1.0}) - travelled_to(d, d.poses[events[0].first_frame])));
}

TEST_CASE("only a marking's first pass in an event counts") {
  // Laps two and three of a circle are one event; markings 40 m and 80 m
  // ahead of its first frame, seen on every lap, are passed on lap two.
  Drive d;
  d.circle(60.0, 3.0);
  auto events = d.events();
  REQUIRE(events.size() == 1);
  const Pose2 start = d.poses[events[0].first_frame];
  const double step = 1.0 / 60.0;  // radians per metre of the circle
  std::vector<MarkingView> views;
  for (const auto& [id, metres] : {std::pair{1u, 40.0}, {2u, 80.0}}) {
    const double a = std::atan2(start.y, start.x) + metres * step;
    add_views(d, id, 60.0 * std::cos(a), 60.0 * std::sin(a), 0, d.poses.size(), views);
  }
  mark_shared_markings(events, d.poses, d.times, views);
  REQUIRE(events[0].seen);
  REQUIRE(events[0].seen->second_m);
  // Last seen at least 5.5 m ahead: about 74 m in, not a lap later.
  CHECK(*events[0].seen->second_m == Approx(74.0).margin(1.5));
}

TEST_CASE("the tally spreads the second and third shared markings of long events") {
  std::vector<RevisitEvent> events(4);
  for (std::size_t i = 0; i < events.size(); ++i) {
    events[i].length_m = 100.0;
    events[i].seen = SharedMarkings{3, 5.0 * static_cast<double>(i + 1),  // 5 .. 20 m
                                    10.0 * static_cast<double>(i + 1)};   // 10 .. 40 m
  }
  events[3].seen->third_m.reset();   // two shared only
  events[2].length_m = 20.0;         // short: not in the long events' figures
  events.push_back(RevisitEvent{});  // shared markings unknown
  events.back().length_m = 100.0;
  events[0].landmarked = SharedMarkings{3, 30.0, 60.0};  // landmarked: a tally of their own
  events[0].closed_at_m = 70.0;                          // 10 m past the third
  events[1].landmarked = SharedMarkings{3, 30.0, 60.0};  // not closed: no wait
  const RevisitTally t = tally_revisit_events(events);
  CHECK(t.seen_long.known == 3);
  CHECK(t.seen_long.second.count == 3);  // 5, 10, 20
  CHECK(t.seen_long.second.median_m == Approx(10.0));
  CHECK(t.seen_long.third.count == 2);  // 10, 20
  CHECK(t.seen_long.third.median_m == Approx(15.0));
  CHECK(t.seen_long.third.p90_m == Approx(20.0));
  CHECK(t.landmarked_long.known == 2);
  CHECK(t.landmarked_long.third.median_m == Approx(60.0));
  CHECK(t.beyond_third_landmarked_long.count == 1);
  CHECK(t.beyond_third_landmarked_long.median_m == Approx(10.0));
}

TEST_CASE("an event's landmarked markings: one label on both visits, the older pass before the event") {
  Drive d;
  d.straight(0, 0, 0, 300).away(40).straight(0, 1, 0, 200);
  auto events = d.events();
  REQUIRE(events.size() == 1);
  const std::size_t second_visit = events[0].first_frame;  // x = 0 again
  REQUIRE(second_visit == 700);
  // A pass by the marking at x on the first visit and on the second, each
  // ending 5 m before the car reaches it (one metre a frame).
  std::vector<LandmarkedPass> passes;
  const auto pass = [&](std::uint32_t marking, double x, Label first, Label second) {
    passes.push_back({static_cast<std::size_t>(x - 5.0), marking, first});
    passes.push_back({second_visit + static_cast<std::size_t>(x - 5.0), marking, second});
  };
  pass(1, 30.0, 4, 4);
  pass(2, 60.0, 7, 7);
  pass(3, 90.0, 2, 9);  // named otherwise on the return: no pair for a place
  pass(4, 120.0, 5, 5);
  // Only on the second visit; and a pass beyond the truth: neither counts.
  passes.push_back({second_visit + 45, 5, 4});
  passes.push_back({d.poses.size() + 3, 1, 4});
  mark_landmarked_markings(events, d.poses, d.times, passes);
  REQUIRE(events[0].landmarked);
  const SharedMarkings& e = *events[0].landmarked;
  CHECK(e.count == 3);
  REQUIRE(e.second_m);
  REQUIRE(e.third_m);
  CHECK(*e.second_m == Approx(55.0));
  CHECK(*e.third_m == Approx(115.0));
  CHECK_FALSE(events[0].seen);
}
