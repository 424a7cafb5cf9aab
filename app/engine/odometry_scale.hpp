// The odometry's distance scale, measured by the camera.
//
// The camera places a marking on the ground in metres, from its height and
// calibration; the odometry says how far the car drove. While the car drives
// straight at a marking, the marking's range ahead shrinks by the true
// distance driven, so against the odometer it falls with slope -1 / scale,
// where scale is the odometry's metres per true metre (a wheel-speed scale
// error of +1 % is 1.01). Each tracked marking is one line with its own
// intercept; the slopes are pooled over markings (the least-squares fit of
// all lines with a common slope). A loop closure cannot tell this scale: a
// lap closes at any scale.
#pragma once

#include <cstdint>
#include <optional>

namespace markloop {

// Weighted sums of one marking's (odometer, range ahead) pairs; the odometer
// is taken from the first sighting so that the sums stay small.
struct RangeFit {
  double weight = 0.0;
  double x = 0.0;  // odometer since the first sighting, metres
  double y = 0.0;  // range ahead of the car, metres
  double xx = 0.0;
  double xy = 0.0;
  double yy = 0.0;
  std::uint32_t count = 0;

  void add(double odometer_m, double range_m, double w) {
    weight += w;
    x += w * odometer_m;
    y += w * range_m;
    xx += w * odometer_m * odometer_m;
    xy += w * odometer_m * range_m;
    yy += w * range_m * range_m;
    ++count;
  }
};

struct ScaleEstimate {
  double scale = 1.0;         // odometry metres per true metre
  double standard_error = 0;  // of scale, from the lines' residuals
  std::uint32_t markings = 0;
};

struct ScaleCounters {
  std::uint64_t markings_used = 0;
  std::uint64_t markings_turning = 0;  // the car turned while it saw them
  std::uint64_t markings_short = 0;    // too few sightings or too little driving
  std::uint64_t markings_outlier = 0;  // slope implausible for any wheel-speed error
};

class OdometryScaleEstimator {
 public:
  // Fewer pooled markings give no estimate.
  static constexpr std::uint32_t kMinMarkings = 20;
  // A marking counts when the car drove straight while it saw it.
  static constexpr double kMaxYawChangeDeg = 1.0;

  // One marking's fit, once it has left view; `straight` when the car's
  // heading stayed within kMaxYawChangeDeg of its first sighting's.
  void add_marking(const RangeFit& fit, bool straight);
  std::optional<ScaleEstimate> estimate() const;
  const ScaleCounters& counters() const { return counters_; }

 private:
  // Sums over markings of each marking's centred sums (its own intercept
  // removed).
  double sxx_ = 0.0;
  double sxy_ = 0.0;
  double syy_ = 0.0;
  std::uint64_t points_ = 0;
  ScaleCounters counters_;
};

}  // namespace markloop
