#include "sim/world.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace markloop::sim {

namespace {

constexpr double kPi = std::numbers::pi;

struct ClassWeight {
  const char* name;
  double weight;
};
// Roughly the mix seen on urban roads; arrows dominate.
constexpr ClassWeight kClasses[] = {
    {"forward", 0.18},     {"leftturn", 0.15}, {"rightturn", 0.10}, {"forward&left", 0.05},
    {"forward&right", 0.05}, {"stop", 0.05},   {"ped", 0.05},       {"xing", 0.05},
    {"bike", 0.08},        {"rail", 0.02},     {"25", 0.05},        {"35", 0.10},
    {"40", 0.05},          {"diamond", 0.02},
};

// Arc of a circle from angle a0 to a1 (radians), centre (cx, cy).
void add_arc(Path& path, double cx, double cy, double radius, double a0, double a1) {
  const int steps = std::max(2, static_cast<int>(std::abs(a1 - a0) * radius / 0.5));
  for (int i = 0; i <= steps; ++i) {
    const double a = a0 + (a1 - a0) * i / steps;
    path.add_point(cx + radius * std::cos(a), cy + radius * std::sin(a));
  }
}

void add_line(Path& path, double x0, double y0, double x1, double y1) {
  const int steps = std::max(1, static_cast<int>(std::hypot(x1 - x0, y1 - y0) / 0.5));
  for (int i = 0; i <= steps; ++i)
    path.add_point(x0 + (x1 - x0) * i / steps, y0 + (y1 - y0) * i / steps);
}

// Counter-clockwise rounded rectangle starting mid bottom edge.
Path rounded_rectangle(double width, double height, double radius) {
  Path p;
  const double w = width / 2, h = height / 2, r = radius;
  add_line(p, 0, -h, w - r, -h);
  add_arc(p, w - r, -h + r, r, -kPi / 2, 0);
  add_line(p, w, -h + r, w, h - r);
  add_arc(p, w - r, h - r, r, 0, kPi / 2);
  add_line(p, w - r, h, -w + r, h);
  add_arc(p, -w + r, h - r, r, kPi / 2, kPi);
  add_line(p, -w, h - r, -w, -h + r);
  add_arc(p, -w + r, -h + r, r, kPi, 1.5 * kPi);
  add_line(p, -w + r, -h, 0, -h);
  return p;
}

void lay_markings(Scenario& scenario, std::mt19937_64& rng, const WorldConfig& config) {
  std::uniform_real_distribution<double> spacing(config.row_spacing_min_m,
                                                 config.row_spacing_max_m);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> weights;
  for (const ClassWeight& c : kClasses) weights.push_back(c.weight);
  std::discrete_distribution<int> pick_class(weights.begin(), weights.end());

  std::uint32_t next_id = 0;
  const double length = scenario.road.length();
  for (double s = spacing(rng) / 2; s < length - 5.0; s += spacing(rng)) {
    const Pose2 centre = scenario.road.at(s);
    bool any = false;
    for (int lane = 0; lane < config.lanes; ++lane) {
      const bool last_chance = lane == config.lanes - 1 && !any;
      if (!last_chance && unit(rng) >= config.marking_probability) continue;
      any = true;
      const double left = lane * config.lane_width_m;  // lanes to the left of the car's
      Marking m;
      m.id = next_id++;
      m.label = static_cast<Label>(pick_class(rng));
      m.x = centre.x - std::sin(centre.yaw) * left;
      m.y = centre.y + std::cos(centre.yaw) * left;
      m.heading = centre.yaw;
      m.lane = lane;
      scenario.markings.push_back(m);
    }
  }
}

}  // namespace

const std::vector<std::string>& marking_class_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const ClassWeight& c : kClasses) n.emplace_back(c.name);
    return n;
  }();
  return names;
}

void Path::add_point(double x, double y) {
  if (!xs_.empty()) {
    const double step = std::hypot(x - xs_.back(), y - ys_.back());
    if (step < 1e-9) return;
    cumulative_.push_back(cumulative_.back() + step);
  } else {
    cumulative_.push_back(0.0);
  }
  xs_.push_back(x);
  ys_.push_back(y);
}

Pose2 Path::at(double s) const {
  if (xs_.size() < 2) return {};
  s = std::clamp(s, 0.0, length());
  const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), s);
  const std::size_t i = std::min<std::size_t>(
      static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - cumulative_.begin() - 1, 0)),
      xs_.size() - 2);
  const double span = cumulative_[i + 1] - cumulative_[i];
  const double f = span > 0 ? (s - cumulative_[i]) / span : 0.0;
  const double dx = xs_[i + 1] - xs_[i];
  const double dy = ys_[i + 1] - ys_[i];
  return {xs_[i] + f * dx, ys_[i] + f * dy, std::atan2(dy, dx)};
}

std::vector<std::string> scenario_names() { return {"loop", "ring", "figure8", "long"}; }

std::optional<Scenario> make_scenario(std::string_view name, std::uint64_t seed,
                                      const WorldConfig& config) {
  Scenario s;
  s.name = std::string(name);
  if (name == "loop") {
    s.description = "a 1.2 km city block driven twice";
    s.road = rounded_rectangle(400, 200, 20);
    s.laps = 2;
  } else if (name == "ring") {
    s.description = "a 3.1 km ring road driven twice";
    add_arc(s.road, 0, 0, 500, -kPi / 2, 1.5 * kPi);
    s.laps = 2;
  } else if (name == "figure8") {
    s.description = "a figure eight of two 150 m circles driven twice";
    add_arc(s.road, 0, 150, 150, -kPi / 2, 1.5 * kPi);
    add_arc(s.road, 0, -150, 150, kPi / 2, -1.5 * kPi);
    s.laps = 2;
  } else if (name == "long") {
    s.description = "a 6 km block driven ten times (60 km)";
    s.road = rounded_rectangle(2000, 1000, 30);
    s.laps = 10;
  } else {
    return std::nullopt;
  }
  std::mt19937_64 rng(seed);
  lay_markings(s, rng, config);
  return s;
}

}  // namespace markloop::sim
