// Route files: the path a car drove, one pose per line, in either of the
// two common trajectory formats (detected from the first pose line):
//  - KITTI odometry: 12 numbers, the 3x4 matrix [R|t] row by row, camera
//    frame (x right, y down, z forward). The road is the x-z plane: world
//    x = t_z (ahead at the start), world y = -t_x (left). Poses are taken to
//    be 0.1 s apart (KITTI's 10 Hz) for the route's speed.
//  - TUM RGB-D: 8 numbers "t x y z qx qy qz qw", z up (the road is x-y);
//    the timestamps give the route's speed.
// Blank lines and lines starting with '#' are skipped. Every pose line must
// have the same count of numbers.
//
// The world is laid along the whole route, in memory and time that grow
// with its length (faster than linearly), so a route is refused when it
// implies no real drive: longer than any drive of the public driving
// datasets, a jump between successive poses that no recording gap explains,
// or a position that is no distance in metres.
#pragma once

#include <cstddef>
#include <string>

#include "app/common/result.hpp"
#include "sim/world.hpp"

namespace markloop::sim {

enum class RouteFormat : std::uint8_t { kKitti, kTum };

struct Route {
  Path path;  // resampled every 0.5 m and lightly smoothed
  RouteFormat format = RouteFormat::kKitti;
  std::size_t poses = 0;
  double duration_s = 0.0;  // first to last pose
  double average_speed_mps() const { return duration_s > 0 ? path.length() / duration_s : 0.0; }
};

inline constexpr std::size_t kMaxRouteBytes = std::size_t{64} << 20;  // read whole
inline constexpr double kMaxRouteLength_m = 100e3;
inline constexpr double kMaxRouteStep_m = 1000.0;  // between successive poses
inline constexpr double kMaxRouteCoordinate_m = 1e8;

// The route in the file `path`, or an error "FILE:LINE: what is wrong" (or
// "FILE: ..." for whole-file problems).
Result<Route> load_route(const std::string& path);

}  // namespace markloop::sim
