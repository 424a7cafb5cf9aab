// Writes a simulated drive in the formats the ECU and the evaluation read
// (see README, "Simulator"): frames.y4m, odometry.log, frames.csv,
// markings.csv, visible.csv, camera.yaml and the legacy markings.txt /
// poses.txt that markloop-replay reads. And the classifier's training set.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "app/common/result.hpp"
#include "app/perception/camera_model.hpp"
#include "sim/drive.hpp"
#include "sim/render.hpp"
#include "sim/world.hpp"

namespace markloop::sim {

struct OdometryConfig {
  double period_s = 0.02;            // VehicleOdometry cycle time (dbc/markloop.dbc)
  double speed_noise_mps = 0.02;     // per message, Gaussian
  double speed_scale_error = 0.005;  // wheel circumference error
  double yaw_rate_noise_dps = 0.1;
  double yaw_rate_bias_dps = 0.02;
};

struct RecordOptions {
  std::string out_dir;
  std::uint64_t seed = 1;
  DriveConfig drive;
  OdometryConfig odometry;
  Conditions conditions;        // the first day's; conditions.seed is derived from `seed`
  bool render = true;           // frames.y4m and visible.csv
  std::size_t max_frames = 0;   // 0 = the whole drive
  double visible_near_m = 3.0;  // visible.csv: centre this far ahead ...
  double visible_far_m = 25.0;  // ... up to this
  // Frames from lens_covered_from_s until lens_covered_until_s (seconds of
  // the drive) show a covered lens: black but for the sensor's noise, no
  // marking visible (the ECU's blind camera, FaultCameraBlind).
  double lens_covered_from_s = 0.0;
  double lens_covered_until_s = 0.0;
  bool progress = true;  // every 10 % on stderr
};

struct RecordSummary {
  std::size_t frames = 0;
  std::size_t odometry_messages = 0;
  std::size_t visible_rows = 0;
  std::size_t detections = 0;   // legacy observation records
  double render_seconds = 0.0;  // CPU time spent rendering frames
};

// The conditions of day `day` (0-based) of a multi-day scenario: day 0 is
// `first`; later days have their own sensor seed, no sun and dusk light.
Conditions conditions_for_day(const Conditions& first, int day);

// What was written, or an error when an output cannot be written.
Result<RecordSummary> record_drive(const Scenario& scenario, const perception::CameraModel& camera,
                                   const RecordOptions& options);

struct TrainingSetOptions {
  std::string out_dir;
  std::uint64_t seed = 1;
  std::size_t frames = 200;
  double visible_near_m = 3.0;
  double visible_far_m = 30.0;
  bool progress = true;
};

// Training frames: seeds offset by 2^32 from every drive seed (drives take
// seeds below 2^32), a world of its own with denser markings of every class
// in equal shares, and conditions drawn at random per frame.
inline constexpr std::uint64_t kTrainingSeedOffset = std::uint64_t{1} << 32;
// The count of annotated markings, or an error when an output cannot be
// written.
Result<std::size_t> record_training_set(const perception::CameraModel& camera,
                                        const TrainingSetOptions& options);

}  // namespace markloop::sim
