#include "app/engine/odometry_scale.hpp"

#include <algorithm>
#include <cmath>

namespace markloop {

namespace {

constexpr std::uint32_t kMinSightings = 4;
// Weighted variance of the car's displacement over a marking's sightings:
// about 3.5 m of driving, so that the camera's noise does not make the slope.
constexpr double kMinDisplacementVariance_m2 = 1.0;
// No wheel-speed error is 10 %: such a drift is a marking tracked wrongly.
constexpr double kMaxSlope = 0.1;

}  // namespace

void OdometryScaleEstimator::add_marking(const MarkingFit& fit) {
  if (fit.count < kMinSightings || !(fit.weight > 0.0)) {
    ++counters_.markings_short;
    return;
  }
  const double w = fit.weight;
  const double sxx = fit.xx - (fit.x[0] * fit.x[0] + fit.x[1] * fit.x[1]) / w;
  const double sxy = fit.xy - (fit.x[0] * fit.y[0] + fit.x[1] * fit.y[1]) / w;
  const double syy = fit.yy - (fit.y[0] * fit.y[0] + fit.y[1] * fit.y[1]) / w;
  if (!(sxx >= kMinDisplacementVariance_m2 * w) || !std::isfinite(sxy) || !std::isfinite(syy)) {
    ++counters_.markings_short;
    return;
  }
  if (std::abs(sxy / sxx) > kMaxSlope) {
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
  if (markings < kMinMarkings) return std::nullopt;
  const double slope = sxy_ / sxx_;
  // Residual variance per unit weight and coordinate of the pooled fit: two
  // intercept coordinates per marking and the common slope are fitted.
  const double dof = 2.0 * double(points_) - 2.0 * double(markings) - 1.0;
  const double residual = std::max(0.0, syy_ - sxy_ * slope);
  const double slope_error = std::sqrt(residual / dof / sxx_);
  ScaleEstimate e;
  e.scale = 1.0 / (1.0 - slope);
  e.standard_error = slope_error * e.scale * e.scale;
  e.markings = markings > UINT32_MAX ? UINT32_MAX : static_cast<std::uint32_t>(markings);
  return e;
}

}  // namespace markloop
