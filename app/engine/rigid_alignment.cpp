#include "app/engine/rigid_alignment.hpp"

#include <cassert>
#include <cmath>

#include <Eigen/Geometry>

namespace markloop {

RigidFit fit_rigid_2d(std::span<const Eigen::Vector2d> from, std::span<const Eigen::Vector2d> to) {
  assert(from.size() == to.size() && from.size() >= 2);
  const double n = static_cast<double>(from.size());
  Eigen::Vector2d from_mean = Eigen::Vector2d::Zero();
  Eigen::Vector2d to_mean = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) {
    from_mean += from[i];
    to_mean += to[i];
  }
  from_mean /= n;
  to_mean /= n;

  // In 2-D the optimal rotation angle is atan2 of the summed cross and dot
  // products of the centred points (the SVD solution, without reflections).
  double dot = 0.0;
  double cross = 0.0;
  for (std::size_t i = 0; i < from.size(); ++i) {
    const Eigen::Vector2d a = from[i] - from_mean;
    const Eigen::Vector2d b = to[i] - to_mean;
    dot += a.dot(b);
    cross += a.x() * b.y() - a.y() * b.x();
  }
  const double angle = std::atan2(cross, dot);
  const Eigen::Rotation2Dd rotation(angle);
  const Eigen::Vector2d translation = to_mean - rotation * from_mean;

  double squared = 0.0;
  for (std::size_t i = 0; i < from.size(); ++i)
    squared += (rotation * from[i] + translation - to[i]).squaredNorm();

  return {{translation.x(), translation.y(), angle}, std::sqrt(squared / n)};
}

}  // namespace markloop
