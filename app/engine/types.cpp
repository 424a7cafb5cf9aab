#include "app/engine/types.hpp"

#include <cmath>
#include <numbers>

namespace markloop {

double wrap_angle(double radians) {
  return std::remainder(radians, 2.0 * std::numbers::pi);
}

Pose2 compose(const Pose2& a, const Pose2& b) {
  const double c = std::cos(a.yaw);
  const double s = std::sin(a.yaw);
  return {a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, wrap_angle(a.yaw + b.yaw)};
}

Pose2 inverse(const Pose2& p) {
  const double c = std::cos(p.yaw);
  const double s = std::sin(p.yaw);
  return {-(c * p.x + s * p.y), s * p.x - c * p.y, wrap_angle(-p.yaw)};
}

std::optional<Pose2> relative_car_pose(const Pose2& alignment, const Landmark& query, const Landmark& match) {
  if (!query.has_car_pose || !match.has_car_pose) return std::nullopt;
  const Pose2 query_car{query.car_x, query.car_y, query.car_yaw};
  const Pose2 match_car{match.car_x, match.car_y, match.car_yaw};
  return compose(inverse(compose(alignment, match_car)), query_car);
}

void copy_frame(const Landmark& passed, Landmark& landmark) {
  landmark.last_frame = passed.last_frame;
  landmark.t = passed.t;
  landmark.car_x = passed.car_x;
  landmark.car_y = passed.car_y;
  landmark.car_yaw = passed.car_yaw;
  landmark.facing = passed.facing;
}

std::optional<double> facing_yaw(const Landmark& landmark) {
  if (landmark.facing == Facing::kAny || !landmark.has_car_pose) return std::nullopt;
  return landmark.facing == Facing::kAlong ? double(landmark.car_yaw)
                                           : wrap_angle(double(landmark.car_yaw) + std::numbers::pi);
}

}  // namespace markloop
