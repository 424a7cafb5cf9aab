#include "sim/route.hpp"

#include <cerrno>
#include <cmath>
#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <vector>

namespace markloop::sim {

namespace {

// Splits on blanks and parses every field as a finite number; on a bad
// field returns false with `bad` set to it.
bool parse_numbers(const std::string& line, std::vector<double>& out, std::string& bad) {
  out.clear();
  std::size_t pos = 0;
  while (true) {
    pos = line.find_first_not_of(" \t\r", pos);
    if (pos == std::string::npos) return true;
    const std::size_t end = line.find_first_of(" \t\r", pos);
    const std::string field = line.substr(pos, end == std::string::npos ? std::string::npos : end - pos);
    char* stop = nullptr;
    errno = 0;
    const double v = std::strtod(field.c_str(), &stop);
    if (*stop != '\0' || errno != 0 || !std::isfinite(v)) {
      bad = field;
      return false;
    }
    out.push_back(v);
    if (end == std::string::npos) return true;
    pos = end;
  }
}

}  // namespace

std::optional<Route> load_route(const std::string& path, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open the route file";
    return std::nullopt;
  }
  Route route;
  std::size_t expected = 0;
  std::vector<double> numbers;
  std::vector<std::array<double, 2>> points;
  double first_t = 0.0, last_t = 0.0;
  std::string line, bad;
  std::size_t line_number = 0;
  const auto fail = [&](const std::string& what) {
    error = path + ":" + std::to_string(line_number) + ": " + what;
    return std::nullopt;
  };
  while (std::getline(in, line)) {
    ++line_number;
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    if (!parse_numbers(line, numbers, bad)) return fail("'" + bad + "' is not a number");
    if (expected == 0) {
      if (numbers.size() != 12 && numbers.size() != 8)
        return fail("expected 12 numbers (KITTI 3x4 pose) or 8 (TUM: t x y z qx qy qz qw), found " +
                    std::to_string(numbers.size()));
      expected = numbers.size();
      route.format = expected == 12 ? RouteFormat::kKitti : RouteFormat::kTum;
    } else if (numbers.size() != expected) {
      return fail(std::string("expected ") + std::to_string(expected) + " numbers like the first pose (" +
                  (expected == 12 ? "KITTI" : "TUM") + "), found " + std::to_string(numbers.size()));
    }
    if (route.format == RouteFormat::kKitti) {
      points.push_back({numbers[11], -numbers[3]});
    } else {
      const double t = numbers[0];
      if (route.poses > 0 && !(t > last_t))
        return fail("timestamp " + std::to_string(t) + " does not increase");
      if (route.poses == 0) first_t = t;
      last_t = t;
      points.push_back({numbers[1], numbers[2]});
    }
    ++route.poses;
  }
  if (in.bad()) {
    error = path + ": read error";
    return std::nullopt;
  }
  if (route.poses < 2) {
    error = path + ": a route needs at least 2 poses, found " + std::to_string(route.poses);
    return std::nullopt;
  }
  route.duration_s = route.format == RouteFormat::kKitti ? 0.1 * double(route.poses - 1)
                                                          : last_t - first_t;

  // Resample every 0.5 m along the polyline, then smooth with a 5-point
  // moving average: recorded poses jitter, a car's path does not.
  Path raw;
  for (const auto& p : points) raw.add_point(p[0], p[1]);
  if (raw.length() < 10.0) {
    error = path + ": the route is only " + std::to_string(raw.length()) +
            " m long (at least 10 m needed)";
    return std::nullopt;
  }
  std::vector<std::array<double, 2>> even;
  for (double s = 0.0; s <= raw.length(); s += 0.5) {
    const Pose2 p = raw.at(s);
    even.push_back({p.x, p.y});
  }
  if (raw.length() - 0.5 * double(even.size() - 1) > 1e-6) {
    const Pose2 end = raw.at(raw.length());
    even.push_back({end.x, end.y});
  }
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
    route.path.add_point(x / k, y / k);
  }
  return route;
}

}  // namespace markloop::sim
