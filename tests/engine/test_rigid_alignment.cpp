#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include <array>
#include <cmath>

#include "app/engine/rigid_alignment.hpp"

using namespace markloop;
using Catch::Approx;

TEST_CASE("rigid alignment recovers a known transform", "[alignment]") {
  const std::array<Eigen::Vector2d, 4> from{{{0, 0}, {10, 1}, {25, -2}, {40, 3}}};
  const Pose2 truth{3.0, -1.5, 0.2};
  std::array<Eigen::Vector2d, 4> to;
  for (std::size_t i = 0; i < from.size(); ++i) {
    const Pose2 p = compose(truth, Pose2{from[i].x(), from[i].y(), 0});
    to[i] = {p.x, p.y};
  }
  const RigidFit fit = fit_rigid_2d(from, to);
  CHECK(fit.transform.x == Approx(3.0).margin(1e-9));
  CHECK(fit.transform.y == Approx(-1.5).margin(1e-9));
  CHECK(fit.transform.yaw == Approx(0.2).margin(1e-12));
  CHECK(fit.rms_residual < 1e-9);
}

TEST_CASE("rigid alignment reports the residual of inconsistent points", "[alignment]") {
  // Distances differ: no rigid transform fits, and a mirror image must not.
  const std::array<Eigen::Vector2d, 3> from{{{0, 0}, {10, 0}, {10, 10}}};
  const std::array<Eigen::Vector2d, 3> mirrored{{{0, 0}, {10, 0}, {10, -10}}};
  CHECK(fit_rigid_2d(from, mirrored).rms_residual > 2.0);
  const std::array<Eigen::Vector2d, 3> moved{{{0, 0}, {10, 0}, {10, 10.6}}};
  const RigidFit fit = fit_rigid_2d(from, moved);
  CHECK(fit.rms_residual > 0.1);
  CHECK(fit.rms_residual < 0.4);
}

TEST_CASE("pose composition and inverse", "[alignment]") {
  const Pose2 a{1, 2, 0.5}, b{-3, 4, -1.2};
  const Pose2 identity = compose(inverse(a), a);
  CHECK(identity.x == Approx(0).margin(1e-12));
  CHECK(identity.y == Approx(0).margin(1e-12));
  CHECK(identity.yaw == Approx(0).margin(1e-12));
  const Pose2 ab = compose(a, b);
  const Pose2 back = compose(inverse(a), ab);
  CHECK(back.x == Approx(b.x));
  CHECK(back.y == Approx(b.y));
  CHECK(back.yaw == Approx(b.yaw));
}
