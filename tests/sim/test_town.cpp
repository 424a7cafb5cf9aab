#include <catch2/catch_test_macros.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "app/perception/camera_model.hpp"
#include "sim/render.hpp"
#include "sim/town.hpp"
#include "sim/world.hpp"

using namespace markloop;
using namespace markloop::sim;

namespace {

constexpr double kPi = std::numbers::pi;
const std::vector<std::string> kTownScenarios = {"turn-ins", "opposite", "closing", "avenue", "far"};

// FNV-1a over a world's markings and strips, positions to the millimetre.
std::uint64_t world_hash(const Scenario& s) {
  std::uint64_t h = 1469598103934665603ULL;
  const auto add = [&](std::int64_t v) {
    for (int k = 0; k < 8; ++k) {
      h ^= static_cast<std::uint64_t>(v >> (8 * k)) & 0xFF;
      h *= 1099511628211ULL;
    }
  };
  for (const Marking& m : s.markings) {
    add(m.id);
    add(m.label);
    add(std::llround(m.x * 1000));
    add(std::llround(m.y * 1000));
    add(std::llround(m.heading * 1e6));
    add(std::llround(m.length_m * 1000));
    add(std::llround(m.width_m * 1000));
  }
  for (const Strip& st : s.strips) {
    add(std::llround(st.x * 1000));
    add(std::llround(st.y * 1000));
    add(static_cast<std::int64_t>(st.kind));
  }
  add(std::llround(s.road.length() * 1000));
  return h;
}

Label label(std::string_view name) {
  return *perception::marking_class_from_name(name);
}

// An oriented rectangle's corners, grown by `margin`.
std::array<std::array<double, 2>, 4> corners(double x, double y, double heading, double half_length,
                                             double half_width, double margin = 0.0) {
  const double c = std::cos(heading), s = std::sin(heading);
  const double l = half_length + margin, w = half_width + margin;
  return {{{x + c * l - s * w, y + s * l + c * w},
           {x + c * l + s * w, y + s * l - c * w},
           {x - c * l + s * w, y - s * l - c * w},
           {x - c * l - s * w, y - s * l + c * w}}};
}

// Separating-axis test of two convex quadrilaterals.
bool quads_overlap(const std::array<std::array<double, 2>, 4>& a,
                   const std::array<std::array<double, 2>, 4>& b) {
  for (const auto* quad : {&a, &b})
    for (int k = 0; k < 4; ++k) {
      const auto& p = (*quad)[k];
      const auto& q = (*quad)[(k + 1) % 4];
      const double nx = q[1] - p[1], ny = p[0] - q[0];
      double a0 = 1e18, a1 = -1e18, b0 = 1e18, b1 = -1e18;
      for (const auto& c : a)
        a0 = std::min(a0, c[0] * nx + c[1] * ny), a1 = std::max(a1, c[0] * nx + c[1] * ny);
      for (const auto& c : b)
        b0 = std::min(b0, c[0] * nx + c[1] * ny), b1 = std::max(b1, c[0] * nx + c[1] * ny);
      if (a1 <= b0 || b1 <= a0) return false;
    }
  return true;
}

std::array<std::array<double, 2>, 4> footprint(const Marking& m, double margin = 0.0) {
  return corners(m.x, m.y, m.heading, m.length_m / 2, m.width_m / 2, margin);
}

// A stretch of the drive that runs along an earlier one (at least
// kEarlier metres of driving before).
struct Overlap {
  double begin_s = 0.0, end_s = 0.0;
  double earlier_begin_s = 0.0, earlier_end_s = 0.0;
  bool entered_by_turn = false;
  double length() const { return end_s - begin_s; }
};
constexpr double kStep = 1.0, kEarlier = 100.0;

// Same direction: within 0.5 m of the earlier pass, heading within 20
// degrees. Opposite: the other way within the same street (1 to 12 m across
// the earlier pass, in the other direction's lanes).
std::vector<Overlap> overlaps(const Path& road, bool opposite) {
  std::vector<Pose2> poses;
  for (double s = 0.0; s <= road.length(); s += kStep) poses.push_back(road.at(s));
  const double cell = 10.0;
  const auto key = [&](double x, double y) {
    return static_cast<std::int64_t>(std::floor(x / cell)) * 1000003 +
           static_cast<std::int64_t>(std::floor(y / cell));
  };
  std::unordered_map<std::int64_t, std::vector<std::size_t>> grid;
  for (std::size_t i = 0; i < poses.size(); ++i) grid[key(poses[i].x, poses[i].y)].push_back(i);
  const auto match = [&](std::size_t i) -> std::ptrdiff_t {
    const Pose2& p = poses[i];
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy) {
        const auto it = grid.find(key(p.x + dx * cell, p.y + dy * cell));
        if (it == grid.end()) continue;
        for (const std::size_t j : it->second) {
          if (static_cast<double>(j) * kStep > static_cast<double>(i) * kStep - kEarlier) continue;
          const Pose2& q = poses[j];
          const double ex = p.x - q.x, ey = p.y - q.y;
          const double along = ex * std::cos(q.yaw) + ey * std::sin(q.yaw);
          const double across = std::abs(-ex * std::sin(q.yaw) + ey * std::cos(q.yaw));
          const double agree = std::cos(wrap_angle(p.yaw - q.yaw));
          const bool same = !opposite && std::hypot(ex, ey) < 0.5 && agree > std::cos(kPi / 9);
          const bool other = opposite && std::abs(along) < 0.6 && across > 1.0 && across < 12.0 &&
                             agree < -std::cos(kPi / 9);
          if (same || other) return static_cast<std::ptrdiff_t>(j);
        }
      }
    return -1;
  };
  std::vector<Overlap> runs;
  bool open = false;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const std::ptrdiff_t j = match(i);
    const double s = static_cast<double>(i) * kStep, earlier = static_cast<double>(j) * kStep;
    if (j >= 0 && !open) {
      Overlap o;
      o.begin_s = o.end_s = s;
      o.earlier_begin_s = o.earlier_end_s = earlier;
      const double before = road.at(std::max(0.0, s - 25.0)).yaw;
      o.entered_by_turn = std::abs(wrap_angle(poses[i].yaw - before)) > kPi / 4;
      runs.push_back(o);
    } else if (j >= 0) {
      runs.back().end_s = s;
      runs.back().earlier_end_s = earlier;
    }
    open = j >= 0;
  }
  return runs;
}

// The corners of every intersection's leg: the street it belongs to (true
// for a column), its index, the box edge it leaves from and its outward
// direction along the street's axis.
struct Leg {
  bool column;
  std::size_t street;
  double axis, edge;
  int outward;
};
std::vector<Leg> legs(const Town& town) {
  std::vector<Leg> out;
  for (std::size_t i = 0; i < town.xs.size(); ++i)
    for (std::size_t j = 0; j < town.ys.size(); ++j) {
      const auto box = town.box(i, j);
      out.push_back({false, j, town.ys[j], box[2], 1});   // east
      out.push_back({false, j, town.ys[j], box[0], -1});  // west
      out.push_back({true, i, town.xs[i], box[3], 1});    // north
      out.push_back({true, i, town.xs[i], box[1], -1});   // south
    }
  return out;
}

// Where a point lies relative to a leg: metres out from the box edge, and
// to the right of the direction into the intersection.
std::array<double, 2> leg_offset(const Leg& leg, double x, double y) {
  const double along = leg.column ? y : x, side = leg.column ? x - leg.axis : y - leg.axis;
  const double out = (along - leg.edge) * leg.outward;
  // Inbound is -outward; right of inbound: for a row heading west (+x out)
  // the right is north (+y); for a column heading south the right is west.
  const double right = leg.column ? -side * leg.outward : side * leg.outward;
  return {out, right};
}

}  // namespace

TEST_CASE("legacy scenarios are unchanged by the town") {
  // Taken before the town was added, seed 1.
  struct Expected {
    const char* name;
    std::size_t markings;
    std::uint64_t hash;
  };
  const Expected expected[] = {
      {"loop", 44, 0x68a0b1daa9ad08c7ULL},    {"ring", 113, 0x004a13689cec51a8ULL},
      {"figure8", 69, 0x1a6de2d7b56cbb94ULL}, {"long", 205, 0x75326fd97845609fULL},
      {"grid", 84, 0x8ebd1496147d75a3ULL},    {"two-days", 84, 0x8ebd1496147d75a3ULL},
  };
  for (const Expected& e : expected) {
    INFO(e.name);
    const auto s = make_scenario(e.name, 1);
    REQUIRE(s);
    CHECK(s->markings.size() == e.markings);
    CHECK(world_hash(*s) == e.hash);
  }
}

TEST_CASE("town scenarios are listed and differ with the seed") {
  const std::vector<std::string> names = scenario_names();
  for (const std::string& name : kTownScenarios) {
    INFO(name);
    CHECK(std::find(names.begin(), names.end(), name) != names.end());
    std::set<std::uint64_t> worlds;
    for (std::uint64_t seed = 1; seed <= 20; ++seed)
      worlds.insert(world_hash(make_town(name, seed, {})->scenario));
    CHECK(worlds.size() == 20);
  }
}

TEST_CASE("every leg of every intersection has a crosswalk and a stop line per approach lane") {
  const Label crosswalk = label("crosswalk"), stop_line = label("stopline");
  for (const std::string& name : kTownScenarios)
    for (const std::uint64_t seed : {1, 2}) {
      const TownScenario t = *make_town(name, seed, {});
      const double w = t.town.lane_width_m;
      for (const Leg& leg : legs(t.town)) {
        const int lanes = leg.column ? t.town.column_lanes[leg.street] : t.town.row_lanes[leg.street];
        const double inbound =
            leg.column ? (leg.outward > 0 ? -kPi / 2 : kPi / 2) : (leg.outward > 0 ? kPi : 0.0);
        double crosswalk_out = -1.0;
        std::vector<int> stop_lines(static_cast<std::size_t>(lanes), 0);
        std::vector<double> stop_line_out(static_cast<std::size_t>(lanes), 0.0);
        for (const Marking& m : t.scenario.markings) {
          const auto [out, right] = leg_offset(leg, m.x, m.y);
          if (out < 0.0 || out > 10.0 || std::abs(right) > lanes * w) continue;
          const bool along_leg = std::abs(std::sin(m.heading - inbound)) < 1e-6;
          if (m.label == crosswalk && along_leg && std::abs(right) < 0.1 && m.width_m >= 2 * lanes * w - 0.5)
            crosswalk_out = out;
          const auto lane = static_cast<int>(std::floor(lanes - right / w));  // 0 = outermost
          if (m.label == stop_line && std::cos(m.heading - inbound) > 0.999 && right > 0 && lane >= 0 &&
              lane < lanes && std::abs(right - (lanes - lane - 0.5) * w) < 0.1) {
            ++stop_lines[static_cast<std::size_t>(lane)];
            stop_line_out[static_cast<std::size_t>(lane)] = out;
          }
        }
        INFO(name << " seed " << seed << ": leg of " << (leg.column ? "column " : "row ") << leg.street
                  << " at " << leg.edge << " outward " << leg.outward);
        CHECK(crosswalk_out >= 0.0);
        for (int k = 0; k < lanes; ++k) {
          CHECK(stop_lines[static_cast<std::size_t>(k)] == 1);
          // Before the crosswalk, seen from the approach.
          CHECK(stop_line_out[static_cast<std::size_t>(k)] > crosswalk_out + 1.5);
        }
      }
    }
}

TEST_CASE("town markings never overlap and never lie in an intersection") {
  for (const std::string& name : kTownScenarios)
    for (const std::uint64_t seed : {1, 2, 3}) {
      const TownScenario t = *make_town(name, seed, {});
      const std::vector<Marking>& markings = t.scenario.markings;
      REQUIRE(markings.size() > 100);
      std::unordered_map<std::int64_t, std::vector<std::size_t>> cells;
      const auto key = [](double x, double y) {
        return static_cast<std::int64_t>(std::floor(x / 20.0)) * 1000003 +
               static_cast<std::int64_t>(std::floor(y / 20.0));
      };
      for (std::size_t k = 0; k < markings.size(); ++k) cells[key(markings[k].x, markings[k].y)].push_back(k);
      for (std::size_t a = 0; a < markings.size(); ++a) {
        const Marking& m = markings[a];
        for (int dx = -1; dx <= 1; ++dx)
          for (int dy = -1; dy <= 1; ++dy)
            for (const std::size_t b : cells[key(m.x + dx * 20.0, m.y + dy * 20.0)]) {
              if (b <= a) continue;
              INFO(name << " seed " << seed << ": markings " << a << " and " << b);
              CHECK_FALSE(quads_overlap(footprint(m, 0.05), footprint(markings[b], 0.05)));
            }
        for (std::size_t i = 0; i < t.town.xs.size(); ++i)
          for (std::size_t j = 0; j < t.town.ys.size(); ++j) {
            const auto box = t.town.box(i, j);
            const auto quad = corners((box[0] + box[2]) / 2, (box[1] + box[3]) / 2, 0.0,
                                      (box[2] - box[0]) / 2, (box[3] - box[1]) / 2);
            INFO(name << " seed " << seed << ": marking " << a << " and box " << i << "," << j);
            CHECK_FALSE(quads_overlap(footprint(m), quad));
          }
      }
    }
}

TEST_CASE("turn-ins re-enters old streets by a turn for 50 to 120 m") {
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const Scenario s = make_town("turn-ins", seed, {})->scenario;
    int turn_ins = 0;
    for (const Overlap& o : overlaps(s.road, false))
      if (o.entered_by_turn && o.length() >= 50.0 && o.length() <= 120.0) ++turn_ins;
    INFO("seed " << seed);
    CHECK(turn_ins >= 3);
  }
}

TEST_CASE("opposite drives a street back the other way past the markings of the first pass") {
  const Scenario s = make_town("opposite", 1, {})->scenario;
  std::vector<Overlap> back;
  for (const Overlap& o : overlaps(s.road, true))
    if (o.length() >= 70.0) back.push_back(o);
  REQUIRE(back.size() >= 3);
  // What the camera sees: on the way back, the markings painted for its
  // own direction; on the first pass, every marking in view.
  const perception::CameraModel camera = perception::default_camera_model();
  Renderer renderer(camera, s);
  std::vector<VisibleMarking> seen;
  std::size_t checked = 0;
  for (const Overlap& o : back) {
    std::set<std::uint32_t> first, again;
    for (double e = o.earlier_end_s - 30.0; e <= o.earlier_begin_s + 30.0; e += 1.0) {
      renderer.visible_markings(s.road.at(e), 3.0, 25.0, {}, seen);
      for (const VisibleMarking& v : seen) first.insert(v.id);
    }
    // Markings beside the stretch both passes drove straight: not those
    // by the street the first pass came in from, which its camera saw
    // only as it turned.
    const auto beside_stretch = [&](const Marking& m) {
      for (double r = o.begin_s; r <= o.end_s - 25.0; r += 1.0)
        if (std::hypot(m.x - s.road.at(r).x, m.y - s.road.at(r).y) < 8.0) return true;
      return false;
    };
    for (double r = o.begin_s; r <= o.end_s; r += 1.0) {
      const Pose2 pose = s.road.at(r);
      renderer.visible_markings(pose, 3.0, 25.0, {}, seen);
      for (const VisibleMarking& v : seen)
        if (std::cos(wrap_angle(s.markings[v.id].heading - pose.yaw)) > 0.5 &&
            beside_stretch(s.markings[v.id]))
          again.insert(v.id);
    }
    INFO("back from " << o.begin_s << " to " << o.end_s << " m along " << o.earlier_end_s << ".."
                      << o.earlier_begin_s);
    checked += again.size();
    for (const std::uint32_t id : again) {
      const Marking& m = s.markings[id];
      INFO("marking " << id << " (" << marking_class_names()[m.label] << ") at " << m.x << ", " << m.y);
      CHECK(first.count(id) == 1);
    }
  }
  CHECK(checked >= 4);  // a few blocks carry no marking between their crossings
}

TEST_CASE("far never comes back to a place it drove 30 s before") {
  WorldConfig config;
  config.route_km = 40.0;
  const Scenario s = make_town("far", 7, config)->scenario;
  CHECK(std::abs(s.road.length() - 40e3) < 100.0);
  // 30 s at 10 m/s.
  const double earlier = 300.0, near = 30.0, step = 2.0;
  std::unordered_map<std::int64_t, std::vector<double>> cells;
  const auto key = [&](double x, double y, int dx, int dy) {
    return (static_cast<std::int64_t>(std::floor(x / near)) + dx) * 1000003 +
           static_cast<std::int64_t>(std::floor(y / near)) + dy;
  };
  int too_near = 0;
  for (double r = 0.0; r <= s.road.length(); r += step) {
    const Pose2 p = s.road.at(r);
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (const double e : cells[key(p.x, p.y, dx, dy)]) {
          const Pose2 q = s.road.at(e);
          if (e <= r - earlier && std::hypot(p.x - q.x, p.y - q.y) < near) ++too_near;
        }
    cells[key(p.x, p.y, 0, 0)].push_back(r);
  }
  CHECK(too_near == 0);
}

TEST_CASE("stats", "[.stats]") {
  for (const char* name : {"turn-ins", "opposite", "closing", "avenue"})
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
      const Scenario s = make_town(name, seed, {})->scenario;
      std::printf("%s %2d len %.0f same:", name, int(seed), s.road.length());
      for (const Overlap& o : overlaps(s.road, false))
        std::printf(" %.0f%s", o.length(), o.entered_by_turn ? "t" : "");
      std::printf(" opp:");
      for (const Overlap& o : overlaps(s.road, true)) std::printf(" %.0f", o.length());
      std::printf("\n");
    }
}
