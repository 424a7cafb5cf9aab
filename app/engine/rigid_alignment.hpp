// Least-squares 2-D rigid alignment (rotation + translation, no scale).
#pragma once

#include <span>

#include <Eigen/Core>

#include "app/engine/types.hpp"

namespace markloop {

struct RigidFit {
  Pose2 transform;      // maps `from` points onto `to` points
  double rms_residual;  // metres
};

// Closed-form solution of the 2-D Procrustes problem; from and to have the
// same size (at least 2). Uses no heap.
RigidFit fit_rigid_2d(std::span<const Eigen::Vector2d> from, std::span<const Eigen::Vector2d> to);

}  // namespace markloop
