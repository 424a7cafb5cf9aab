#include "app/engine/odometry_scale.hpp"

#include <algorithm>
#include <cmath>

namespace markloop {

namespace {

constexpr std::uint32_t kMinSightings = 4;
// Weighted variance of the odometer over a marking's sightings: about 3.5 m
// of driving, so that the camera's range noise does not make the slope.
constexpr double kMinOdometerVariance_m2 = 1.0;
// No wheel-speed error is 10 %: such a slope is a marking tracked wrongly.
constexpr double kMaxSlopeError = 0.1;

}  // namespace

void OdometryScaleEstimator::add_marking(const RangeFit& fit, bool straight) {
  if (!straight) {
    ++counters_.markings_turning;
    return;
  }
  if (fit.count < kMinSightings || !(fit.weight > 0.0)) {
    ++counters_.markings_short;
    return;
  }
  const double sxx = fit.xx - fit.x * fit.x / fit.weight;
  const double sxy = fit.xy - fit.x * fit.y / fit.weight;
  const double syy = fit.yy - fit.y * fit.y / fit.weight;
  if (!(sxx >= kMinOdometerVariance_m2 * fit.weight) || !std::isfinite(sxy) || !std::isfinite(syy)) {
    ++counters_.markings_short;
    return;
  }
  if (std::abs(sxy / sxx + 1.0) > kMaxSlopeError) {
    ++counters_.markings_outlier;
    return;
  }
  sxx_ += sxx;
  sxy_ += sxy;
  syy_ += syy;
  points_ += fit.count;
  ++counters_.markings_used;
}

std::optional<ScaleEstimate> OdometryScaleEstimator::estimate() const {
  const std::uint64_t markings = counters_.markings_used;
  if (markings < kMinMarkings || !(sxy_ < 0.0)) return std::nullopt;
  const double slope = sxy_ / sxx_;
  // Residual variance per unit weight of the pooled fit: one intercept per
  // marking and the common slope are fitted.
  const double dof = double(points_) - double(markings) - 1.0;
  const double residual = std::max(0.0, syy_ - sxy_ * slope);
  const double slope_error = std::sqrt(residual / dof / sxx_);
  ScaleEstimate e;
  e.scale = -1.0 / slope;
  e.standard_error = slope_error / (slope * slope);
  e.markings = markings > UINT32_MAX ? UINT32_MAX : static_cast<std::uint32_t>(markings);
  return e;
}

}  // namespace markloop
