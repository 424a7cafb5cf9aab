// Trajectory error against the truth: ATE (RMSE of positions after the rigid
// 2-D alignment) and RPE over 100 m stretches.
#pragma once

#include <cstddef>
#include <optional>
#include <span>

#include "app/engine/types.hpp"
#include "app/tools/posegraph/inputs.hpp"

namespace markloop::posegraph {

struct TrajectoryError {
  std::size_t frames = 0;  // frames with a truth pose
  Pose2 alignment;         // truth ≈ compose(alignment, estimate)
  double ate_rmse_m = 0.0;
  double ate_max_m = 0.0;
  // The same after a similarity alignment (scale too): what remains once the
  // odometry's scale error, which revisits cannot observe, is taken out.
  double ate_sim2_rmse_m = 0.0;
  double sim2_scale = 1.0;
  // Over every pair of frames 100 m apart along the truth: RMS of the
  // relative translation's error (m) and mean of the heading's (deg).
  std::size_t rpe_pairs = 0;
  double rpe_translation_rmse_m = 0.0;
  double rpe_rotation_mean_deg = 0.0;
};

inline constexpr double kRpeStretch_m = 100.0;

// `estimate` holds a pose per frame; frames beyond the truth or unknown
// there are left out. nullopt when fewer than 2 frames are compared.
std::optional<TrajectoryError> trajectory_error(std::span<const Pose2> estimate, const Truth& truth);

}  // namespace markloop::posegraph
