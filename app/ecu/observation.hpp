// How the ECU turns a detection into an observation for the engine: the
// gate, its place on the ground by the car's pose, and its weight. The ECU
// and the replay of its detections (markloop-replay --ecu-detections) share
// it, so that a replay feeds the engine what the car did.
#pragma once

#include <cmath>

#include "app/ecu/config.hpp"
#include "app/engine/types.hpp"
#include "app/perception/marking_classes.hpp"

namespace markloop::ecu {

// A detection's ground position error grows about linearly with range; this
// is the range at which it is twice that of a marking at the bumper.
inline constexpr double kPositionErrorDoublingRange_m = 5.0;

// kRejected: no finite position; kGated: refused by the gate.
enum class Observed { kYes, kRejected, kGated };

// A detection `ground_x` ahead of and `ground_y` left of the vehicle
// reference point, read `turned` or not, seen with the car at `pose`: `out`
// when kYes.
inline Observed observe(Label label, float score, bool turned, double ground_x, double ground_y,
                        const Pose2& pose, const ObservationGate& gate, Observation& out) {
  if (!std::isfinite(ground_x) || !std::isfinite(ground_y)) return Observed::kRejected;
  if (score < gate.min_score || ground_x < gate.min_range_m || ground_x > gate.max_range_m)
    return Observed::kGated;
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  out.label = label;
  out.facing = perception::facing_of(label, turned);
  out.x = static_cast<float>(pose.x + c * ground_x - s * ground_y);
  out.y = static_cast<float>(pose.y + s * ground_x + c * ground_y);
  // A pixel covers more ground, and a pitch error moves it further, the
  // further ahead it lies: inverse variance, error growing with range.
  const double spread = 1.0 + ground_x / kPositionErrorDoublingRange_m;
  out.weight = static_cast<float>(1.0 / (spread * spread));
  return Observed::kYes;
}

}  // namespace markloop::ecu
