// The odometry's distance scale, measured by the camera.
//
// The camera places a marking on the ground in metres, from its height and
// calibration; the odometry says how far the car drove. Placed in the world
// by the odometry, a marking that stands still stays put only when the
// odometry's distances are true: with distances `scale` times the truth, its
// world position moves by (1 - 1 / scale) times the car's displacement while
// it is in view, along straight roads and bends alike. Each tracked marking
// is one such line with its own intercept; the slope is pooled over markings
// (the least-squares fit of all lines with a common slope). A loop closure
// cannot tell this scale: a lap closes at any scale.
#pragma once

#include <cstdint>
#include <optional>

namespace markloop {

// Weighted sums of one marking's sightings: the car's displacement since the
// first sighting (x) and the marking's world position relative to the car
// at the first sighting (y), both by the odometry, in metres.
struct MarkingFit {
  double weight = 0.0;
  double x[2] = {0.0, 0.0};
  double y[2] = {0.0, 0.0};
  double xx = 0.0;  // sums of dot products
  double xy = 0.0;
  double yy = 0.0;
  std::uint32_t count = 0;

  void add(double car_dx, double car_dy, double marking_x, double marking_y, double w) {
    weight += w;
    x[0] += w * car_dx;
    x[1] += w * car_dy;
    y[0] += w * marking_x;
    y[1] += w * marking_y;
    xx += w * (car_dx * car_dx + car_dy * car_dy);
    xy += w * (car_dx * marking_x + car_dy * marking_y);
    yy += w * (marking_x * marking_x + marking_y * marking_y);
    ++count;
  }
};

struct ScaleEstimate {
  double scale = 1.0;           // odometry metres per true metre
  double standard_error = 0.0;  // of scale, from the lines' residuals
  std::uint32_t markings = 0;
};

struct ScaleCounters {
  std::uint64_t markings_used = 0;
  std::uint64_t markings_short = 0;    // too few sightings or too little driving
  std::uint64_t markings_outlier = 0;  // a drift implausible for any wheel-speed error
};

class OdometryScaleEstimator {
 public:
  // Fewer pooled markings give no estimate.
  static constexpr std::uint32_t kMinMarkings = 20;

  // One marking's fit, once it has left view.
  void add_marking(const MarkingFit& fit);
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
