#include "app/perception/detector/lane_horizon.hpp"

#include <algorithm>
#include <cmath>

namespace markloop::perception {
namespace {

// Lines (and dashes) shorter than this on the road say too little about
// their direction to place the horizon.
constexpr double kMinHorizonLineM = 1.5;

}  // namespace

LaneHorizon::LaneHorizon(const CameraModel& camera, const BirdsEyeView& view, const BirdsEyeRegion& region,
                         int max_shift_px)
    : camera_(camera),
      view_(view),
      x_step_m_(region.x_step_m),
      y_step_m_(region.y_step_m),
      max_shift_px_(max_shift_px) {
  // The road's horizon straight ahead: where a point 100 km ahead appears.
  Eigen::Vector2d far_ahead;
  known_ = camera_.ground_to_image({1.0e5, 0.0}, far_ahead) && std::isfinite(far_ahead.y());
  calibrated_row_ = known_ ? static_cast<float>(far_ahead.y()) : 0.0f;
}

void LaneHorizon::note(const PartAxis& axis) {
  const double xs = x_step_m_, ys = y_step_m_;
  const double length = axis.length_m, width = axis.width_m, angle = axis.angle_rad;
  // Long and thin: at least seven times as long as wide (blur and a pitch
  // other than calibrated widen lines in the view, so no fixed width);
  // dashes count.
  constexpr double kMinElongation = 7.0;
  if (length < kMinHorizonLineM || length < kMinElongation * width) return;
  // Its axis, from the road's direction: lines across the road (stop lines)
  // do not run to the horizon.
  constexpr double kMaxAngleRad = 0.3;
  if (std::abs(angle) > kMaxAngleRad) return;
  const double half_rows = 0.5 * length * std::cos(angle) / xs;
  const double half_cols = 0.5 * length * std::sin(angle) / ys;
  std::array<Eigen::Vector2d, 2> ends;
  for (int k = 0; k < 2; ++k) {
    const double sign = k == 0 ? -1.0 : 1.0;
    const float row = static_cast<float>(axis.mean_row + sign * half_rows);
    const float col = static_cast<float>(axis.mean_col + sign * half_cols);
    if (!camera_.ground_to_image({view_.ground_x(row), view_.ground_y(col)}, ends[k])) return;
  }
  const float shift = static_cast<float>(view_.row_shift());
  const ImageSegment segment{static_cast<float>(ends[0].x()), static_cast<float>(ends[0].y()) + shift,
                             static_cast<float>(ends[1].x()), static_cast<float>(ends[1].y()) + shift};
  // Keep the longest: they say the most about where the lines meet.
  std::size_t slot = count_;
  if (slot == segments_.size()) {
    slot = static_cast<std::size_t>(std::min_element(lengths_.begin(), lengths_.end()) - lengths_.begin());
    if (!(static_cast<float>(length) > lengths_[slot])) return;
  } else {
    ++count_;
  }
  segments_[slot] = segment;
  lengths_[slot] = static_cast<float>(length);
}

std::optional<float> LaneHorizon::measure_shift() const {
  const float reach = static_cast<float>(max_shift_px_);
  const float width = static_cast<float>(camera_.width());
  const VanishingSearch search{calibrated_row_ - reach, calibrated_row_ + reach, -0.5f * width, 1.5f * width};
  const std::optional<float> row = vanishing_row(segments(), search);
  if (!row) return std::nullopt;
  return *row - calibrated_row_;
}

}  // namespace markloop::perception
