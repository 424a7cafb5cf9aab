// Drives a car through a scenario and produces, per camera frame, what the
// perception stage would: labelled marking observations on the ground placed
// with the car's estimated (drifting) pose, together with the ground truth.
#pragma once

#include <cstdint>
#include <random>
#include <unordered_map>
#include <vector>

#include "app/engine/types.hpp"
#include "sim/world.hpp"

namespace markloop::sim {

struct DriveConfig {
  double speed_mps = 10.0;
  double fps = 10.0;
  // Camera footprint on the ground, in the vehicle frame (x ahead, y left):
  // the detector's region (two lanes over either side) within the camera's
  // field of view (|y| at most view_slope * x).
  double view_near_m = 4.0;
  double view_far_m = 20.0;
  double view_half_width_m = 8.5;
  double view_slope = 0.7;
  // Perception errors.
  double detection_probability = 0.85;
  double label_error_probability = 0.03;
  double position_noise_m = 0.05;  // plus position_noise_per_m per metre of range
  double position_noise_per_m = 0.01;
  double false_positives_per_frame = 0.02;
  // Odometry errors (integrated into the estimated pose: slow drift).
  double speed_scale_error = 0.005;
  double yaw_rate_bias_dps = 0.02;
  double yaw_rate_noise_dps = 0.1;
};

struct DriveFrame {
  FrameInput estimate;  // frame, time and the estimated pose
  Pose2 truth;
  std::vector<Observation> observations;
  std::vector<std::uint32_t> observed_marking_ids;  // parallel; UINT32_MAX = false positive
};

class Drive {
 public:
  Drive(const Scenario& scenario, const DriveConfig& config, std::uint64_t seed);

  std::size_t frame_count() const { return frame_count_; }
  // Fills the next frame; false when the drive is over.
  bool next(DriveFrame& out);

 private:
  // The markings are kept in a grid of cells a camera footprint wide.
  std::int64_t cell_of(double coordinate) const;
  static std::int64_t cell_key(std::int64_t cx, std::int64_t cy);

  const Scenario& scenario_;
  DriveConfig config_;
  std::mt19937_64 rng_;
  std::size_t frame_count_;
  std::size_t frame_ = 0;
  Pose2 estimate_{};
  Pose2 previous_truth_{};
  double cell_size_;
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> grid_;
};

}  // namespace markloop::sim
