#include "sim/route.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string_view>
#include <vector>

#include "app/common/result.hpp"
#include "app/tools/common/tool_files.hpp"

namespace markloop::sim {

namespace {

// Splits on blanks and parses every field as a finite number; on a bad
// field returns false with `bad` set to it.
bool parse_numbers(std::string_view line, std::vector<double>& out, std::string& bad) {
  out.clear();
  std::size_t pos = 0;
  while (true) {
    pos = line.find_first_not_of(" \t\r", pos);
    if (pos == std::string_view::npos) return true;
    const std::size_t end = std::min(line.find_first_of(" \t\r", pos), line.size());
    const std::string_view field = line.substr(pos, end - pos);
    const char* first = field.data();
    if (*first == '+') ++first;  // from_chars takes no '+', strtod did
    double v = 0.0;
    const auto [stop, ec] = std::from_chars(first, field.data() + field.size(), v);
    if (ec != std::errc() || stop != field.data() + field.size() || !std::isfinite(v)) {
      bad = std::string(field);
      return false;
    }
    out.push_back(v);
    pos = end;
  }
}

// "850 m" or "12 km" (adding 0.0 prints -0 as 0).
std::string distance_text(double metres) {
  char text[64];
  if (std::abs(metres) < 10e3)
    std::snprintf(text, sizeof text, "%.0f m", metres + 0.0);
  else
    std::snprintf(text, sizeof text, "%.0f km", metres / 1000.0 + 0.0);
  return text;
}

// What is absurd about the pose `point` after `previous` (the route so far
// `length` long), or nothing: the limits keep the world laid along a route
// to what a real drive needs.
std::string absurd_pose(const std::array<double, 2>& point, const std::array<double, 2>* previous,
                        double& length) {
  if (std::abs(point[0]) > kMaxRouteCoordinate_m || std::abs(point[1]) > kMaxRouteCoordinate_m)
    return "position (" + distance_text(point[0]) + ", " + distance_text(point[1]) + ") lies beyond " +
           distance_text(kMaxRouteCoordinate_m) + " of the origin";
  if (previous == nullptr) return {};
  const double step = std::hypot(point[0] - (*previous)[0], point[1] - (*previous)[1]);
  if (step > kMaxRouteStep_m)
    return distance_text(step) + " from the pose before: more than the " + distance_text(kMaxRouteStep_m) +
           " a route may step";
  length += step;
  if (length > kMaxRouteLength_m)
    return "the route grows longer than " + distance_text(kMaxRouteLength_m) + " here";
  return {};
}

// The pose lines of a route file: the points on the ground, the format
// and the time they span.
struct RoutePoints {
  std::vector<std::array<double, 2>> points;
  RouteFormat format = RouteFormat::kKitti;
  double first_t = 0.0, last_t = 0.0;
};

// Reads one pose line into `route`; `length` is the route so far. Returns
// what is wrong with the line, or nothing.
std::string add_pose(const std::vector<double>& numbers, std::size_t& expected, RoutePoints& route,
                     double& length) {
  if (expected == 0) {
    if (numbers.size() != 12 && numbers.size() != 8)
      return "expected 12 numbers (KITTI 3x4 pose) or 8 (TUM: t x y z qx qy qz qw), found " +
             std::to_string(numbers.size());
    expected = numbers.size();
    route.format = expected == 12 ? RouteFormat::kKitti : RouteFormat::kTum;
  } else if (numbers.size() != expected) {
    return std::string("expected ") + std::to_string(expected) + " numbers like the first pose (" +
           (expected == 12 ? "KITTI" : "TUM") + "), found " + std::to_string(numbers.size());
  }
  std::array<double, 2> point{};
  if (route.format == RouteFormat::kKitti) {
    point = {numbers[11], -numbers[3]};
  } else {
    const double t = numbers[0];
    if (!route.points.empty() && !(t > route.last_t))
      return "timestamp " + std::to_string(t) + " does not increase";
    if (route.points.empty()) route.first_t = t;
    route.last_t = t;
    // The orientation is not used, but a zero quaternion is no rotation:
    // the line is not a pose.
    const double norm_sq =
        numbers[4] * numbers[4] + numbers[5] * numbers[5] + numbers[6] * numbers[6] + numbers[7] * numbers[7];
    if (!(norm_sq > 1e-12)) return "quaternion qx qy qz qw is zero: not a rotation";
    point = {numbers[1], numbers[2]};
  }
  if (std::string absurd = absurd_pose(point, route.points.empty() ? nullptr : &route.points.back(), length);
      !absurd.empty())
    return absurd;
  route.points.push_back(point);
  return {};
}

// Every pose line of `text` (the file `path`), or "FILE:LINE: what is wrong".
Result<RoutePoints> read_poses(const std::string& path, const std::string& text) {
  RoutePoints route;
  std::size_t expected = 0;
  std::vector<double> numbers;
  double length = 0.0;
  std::string bad;
  tools::Lines lines(text);
  std::string_view line;
  const auto at_line = [&](const std::string& what) {
    return error(path + ":" + std::to_string(lines.number()) + ": " + what);
  };
  while (lines.next(line)) {
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string_view::npos || line[first] == '#') continue;
    if (!parse_numbers(line, numbers, bad)) return at_line("'" + bad + "' is not a number");
    if (const std::string wrong = add_pose(numbers, expected, route, length); !wrong.empty())
      return at_line(wrong);
  }
  if (route.points.size() < 2)
    return error(path + ": a route needs at least 2 poses, found " + std::to_string(route.points.size()));
  return route;
}

// `raw` resampled every 0.5 m along the polyline.
std::vector<std::array<double, 2>> resample(const Path& raw) {
  std::vector<std::array<double, 2>> even;
  for (double s = 0.0; s <= raw.length(); s += 0.5) {
    const Pose2 p = raw.at(s);
    even.push_back({p.x, p.y});
  }
  if (raw.length() - 0.5 * double(even.size() - 1) > 1e-6) {
    const Pose2 end = raw.at(raw.length());
    even.push_back({end.x, end.y});
  }
  return even;
}

// A 5-point moving average: recorded poses jitter, a car's path does not.
Path smooth(const std::vector<std::array<double, 2>>& even) {
  Path path;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(even.size());
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    double x = 0, y = 0;
    int k = 0;
    // Symmetric window, narrower at the ends so the ends stay where they are.
    const std::ptrdiff_t half = std::min<std::ptrdiff_t>({2, i, n - 1 - i});
    for (std::ptrdiff_t j = i - half; j <= i + half; ++j, ++k) {
      x += even[static_cast<std::size_t>(j)][0];
      y += even[static_cast<std::size_t>(j)][1];
    }
    path.add_point(x / k, y / k);
  }
  return path;
}

}  // namespace

Result<Route> load_route(const std::string& path) {
  const Result<std::string> read = tools::read_input(path, kMaxRouteBytes, "a route file");
  if (!read) return read.error();
  const std::string& text = *read;
  Result<RoutePoints> poses = read_poses(path, text);
  if (!poses) return poses.error();
  Route route;
  route.format = poses->format;
  route.poses = poses->points.size();
  route.duration_s =
      route.format == RouteFormat::kKitti ? 0.1 * double(route.poses - 1) : poses->last_t - poses->first_t;
  Path raw;
  for (const auto& p : poses->points) raw.add_point(p[0], p[1]);
  if (raw.length() < 10.0)
    return error(path + ": the route is only " + std::to_string(raw.length()) +
                 " m long (at least 10 m needed)");
  route.path = smooth(resample(raw));
  return route;
}

}  // namespace markloop::sim
