#include "sim/drive.hpp"

#include "app/common/units.hpp"
#include "app/perception/marking_classes.hpp"

#include <cmath>
#include <numbers>

namespace markloop::sim {
namespace {
// A wrong label is one of the symbol classes (arrows, words, numbers, bike,
// diamond: the first 14); stop lines and crosswalks are not mistaken for them.
constexpr std::size_t kConfusableClasses = 14;
}  // namespace

Drive::Drive(const Scenario& scenario, const DriveConfig& config, std::uint64_t seed)
    : scenario_(scenario),
      config_(config),
      rng_(seed),
      frame_count_(
          static_cast<std::size_t>(scenario.road.length() * scenario.laps / config.speed_mps * config.fps)),
      cell_size_(config.view_far_m + 5.0) {
  for (std::uint32_t i = 0; i < scenario.markings.size(); ++i)
    grid_[cell_key(cell_of(scenario.markings[i].x), cell_of(scenario.markings[i].y))].push_back(i);
  estimate_ = scenario.road.at(0.0);
  previous_truth_ = estimate_;
}

std::int64_t Drive::cell_of(double coordinate) const {
  return static_cast<std::int64_t>(std::floor(coordinate / cell_size_));
}

std::int64_t Drive::cell_key(std::int64_t cx, std::int64_t cy) {
  return cx * 1000003 + cy;
}

bool Drive::next(DriveFrame& out) {
  if (frame_ >= frame_count_) return false;
  const double dt = 1.0 / config_.fps;
  const double t = static_cast<double>(frame_) * dt;
  const double lap_length = scenario_.road.length();
  const Pose2 truth = scenario_.road.at(std::fmod(config_.speed_mps * t, lap_length));

  // Dead reckoning from noisy wheel speed and yaw rate: the estimate drifts.
  std::normal_distribution<double> yaw_noise(0.0, config_.yaw_rate_noise_dps * kRadiansPerDegree);
  if (frame_ > 0) {
    const double yaw_rate = wrap_angle(truth.yaw - previous_truth_.yaw) / dt;
    const double measured_rate = yaw_rate + config_.yaw_rate_bias_dps * kRadiansPerDegree + yaw_noise(rng_);
    const double travelled = std::hypot(truth.x - previous_truth_.x, truth.y - previous_truth_.y);
    const double measured_distance = travelled * (1.0 + config_.speed_scale_error);
    const double mid_yaw = estimate_.yaw + 0.5 * measured_rate * dt;
    estimate_.x += measured_distance * std::cos(mid_yaw);
    estimate_.y += measured_distance * std::sin(mid_yaw);
    estimate_.yaw = wrap_angle(estimate_.yaw + measured_rate * dt);
  }
  previous_truth_ = truth;

  out.estimate = FrameInput{static_cast<FrameIndex>(frame_), t, true, estimate_};
  out.truth = truth;
  out.observations.clear();
  out.observed_marking_ids.clear();

  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const auto observe = [&](double ahead, double left, Label label, std::uint32_t id) {
    const double sigma = config_.position_noise_m + config_.position_noise_per_m * ahead;
    const Pose2 seen =
        compose(estimate_, Pose2{ahead + sigma * gauss(rng_), left + sigma * gauss(rng_), 0.0});
    if (unit(rng_) < config_.label_error_probability) label = static_cast<Label>(rng_() % kConfusableClasses);
    // Read as painted (markings painted for the other lane are skipped).
    out.observations.push_back({label, static_cast<float>(seen.x), static_cast<float>(seen.y), 1.0f,
                                perception::facing_of(label, false)});
    out.observed_marking_ids.push_back(id);
  };

  const Pose2 to_vehicle = inverse(truth);
  const std::int64_t cx = cell_of(truth.x);
  const std::int64_t cy = cell_of(truth.y);
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      const auto cell = grid_.find(cell_key(cx + dx, cy + dy));
      if (cell == grid_.end()) continue;
      for (const std::uint32_t index : cell->second) {
        const Marking& m = scenario_.markings[index];
        const Pose2 rel = compose(to_vehicle, Pose2{m.x, m.y, 0.0});
        if (rel.x < config_.view_near_m || rel.x > config_.view_far_m ||
            std::abs(rel.y) > std::min(config_.view_half_width_m, config_.view_slope * rel.x))
          continue;
        // Markings facing the other way are painted for the opposite lane:
        // upside down, only the shapes that a half turn leaves alike are
        // recognised (a stop line, a crosswalk, a diamond).
        if (std::cos(wrap_angle(m.heading - truth.yaw)) < 0.5 && !perception::same_when_turned(m.label))
          continue;
        if (unit(rng_) >= config_.detection_probability) continue;
        observe(rel.x, rel.y, m.label, m.id);
      }
    }
  }
  if (unit(rng_) < config_.false_positives_per_frame) {
    std::uniform_real_distribution<double> ahead(config_.view_near_m, config_.view_far_m);
    std::uniform_real_distribution<double> left(-config_.view_half_width_m, config_.view_half_width_m);
    observe(ahead(rng_), left(rng_), static_cast<Label>(rng_() % kConfusableClasses), UINT32_MAX);
  }
  ++frame_;
  return true;
}

}  // namespace markloop::sim
