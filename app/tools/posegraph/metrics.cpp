#include "app/tools/posegraph/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "app/common/units.hpp"
#include "app/tools/common/trajectory.hpp"

namespace markloop::posegraph {

namespace {

struct Paired {
  std::vector<Pose2> estimate, truth;
};

Paired paired_frames(std::span<const Pose2> estimate, const Truth& truth) {
  Paired p;
  const std::size_t n = std::min(estimate.size(), truth.poses.size());
  for (std::size_t k = 0; k < n; ++k) {
    if (!truth.known[k]) continue;
    p.estimate.push_back(estimate[k]);
    p.truth.push_back(truth.poses[k]);
  }
  return p;
}

void add_rpe(const Paired& p, TrajectoryError& e) {
  std::vector<double> travelled(p.truth.size(), 0.0);
  for (std::size_t i = 1; i < p.truth.size(); ++i)
    travelled[i] =
        travelled[i - 1] + std::hypot(p.truth[i].x - p.truth[i - 1].x, p.truth[i].y - p.truth[i - 1].y);
  double sum_sq = 0.0, sum_rot = 0.0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < p.truth.size(); ++i) {
    j = std::max(j, i);
    while (j < p.truth.size() && travelled[j] - travelled[i] < kRpeStretch_m) ++j;
    if (j == p.truth.size()) break;
    const Pose2 true_rel = compose(inverse(p.truth[i]), p.truth[j]);
    const Pose2 est_rel = compose(inverse(p.estimate[i]), p.estimate[j]);
    sum_sq += std::pow(true_rel.x - est_rel.x, 2) + std::pow(true_rel.y - est_rel.y, 2);
    sum_rot += std::abs(wrap_angle(true_rel.yaw - est_rel.yaw)) * kDegreesPerRadian;
    ++e.rpe_pairs;
  }
  if (e.rpe_pairs == 0) return;
  e.rpe_translation_rmse_m = std::sqrt(sum_sq / static_cast<double>(e.rpe_pairs));
  e.rpe_rotation_mean_deg = sum_rot / static_cast<double>(e.rpe_pairs);
}

// RMSE after the best rotation, translation and scale (Umeyama in 2-D).
void add_sim2_ate(const Paired& p, TrajectoryError& e) {
  const std::size_t n = p.truth.size();
  double fx = 0, fy = 0, tx = 0, ty = 0;
  for (std::size_t i = 0; i < n; ++i)
    fx += p.estimate[i].x, fy += p.estimate[i].y, tx += p.truth[i].x, ty += p.truth[i].y;
  fx /= static_cast<double>(n), fy /= static_cast<double>(n), tx /= static_cast<double>(n),
      ty /= static_cast<double>(n);
  double dot = 0, cross = 0, spread = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double ax = p.estimate[i].x - fx, ay = p.estimate[i].y - fy;
    const double bx = p.truth[i].x - tx, by = p.truth[i].y - ty;
    dot += ax * bx + ay * by, cross += ax * by - ay * bx, spread += ax * ax + ay * ay;
  }
  if (spread <= 0) return;
  const double angle = std::atan2(cross, dot), c = std::cos(angle), s = std::sin(angle);
  e.sim2_scale = std::hypot(dot, cross) / spread;
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double ax = p.estimate[i].x - fx, ay = p.estimate[i].y - fy;
    const double x = tx + e.sim2_scale * (c * ax - s * ay), y = ty + e.sim2_scale * (s * ax + c * ay);
    sum_sq += std::pow(x - p.truth[i].x, 2) + std::pow(y - p.truth[i].y, 2);
  }
  e.ate_sim2_rmse_m = std::sqrt(sum_sq / static_cast<double>(n));
}

}  // namespace

std::optional<TrajectoryError> trajectory_error(std::span<const Pose2> estimate, const Truth& truth) {
  const Paired p = paired_frames(estimate, truth);
  if (p.truth.size() < 2) return std::nullopt;
  TrajectoryError e;
  e.frames = p.truth.size();
  e.alignment = tools::align_se2(p.estimate, p.truth);
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < p.truth.size(); ++i) {
    const Pose2 aligned = compose(e.alignment, p.estimate[i]);
    const double d = std::hypot(aligned.x - p.truth[i].x, aligned.y - p.truth[i].y);
    sum_sq += d * d;
    e.ate_max_m = std::max(e.ate_max_m, d);
  }
  e.ate_rmse_m = std::sqrt(sum_sq / static_cast<double>(e.frames));
  add_sim2_ate(p, e);
  add_rpe(p, e);
  return e;
}

}  // namespace markloop::posegraph
