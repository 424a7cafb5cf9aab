#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include <cmath>
#include <optional>
#include <random>
#include <vector>

#include "app/engine/landmark_tracker.hpp"

using namespace markloop;

namespace {

// A car driving along a road, its wheel speed reading `scale` times the
// truth, passing a marking every 12 m. The camera sees each marking from 16
// to 5.5 m ahead, its range with noise that grows with the range. With
// `bend_deg_per_m` the road curves.
struct Drive {
  double scale = 1.0;
  double range_noise_m = 0.05;
  double bend_deg_per_m = 0.0;
  double fps = 10.0;
  double speed_mps = 10.0;

  std::optional<ScaleEstimate> run(double metres, LandmarkTracker& tracker) const {
    std::mt19937 rng(7);
    std::normal_distribution<double> unit(0.0, 1.0);
    FixedVector<Landmark, 64> landmarks;
    const double step = speed_mps / fps;
    Pose2 odometry;
    double odometer = 0.0;
    for (FrameIndex f = 0; double(f) * step < metres; ++f) {
      const double t = double(f) / fps;
      FrameInput frame{f, t, true, odometry};
      std::vector<Observation> seen;
      // Markings every 12 m along the road, at true arc length s.
      const double travelled = double(f) * step;
      for (double s = 12.0 * std::ceil((travelled + 5.5) / 12.0); s <= travelled + 16.0; s += 12.0) {
        const double ahead = s - travelled;  // along a gentle bend, near enough
        const double measured = ahead + range_noise_m * (1.0 + ahead / 5.0) * unit(rng);
        const double c = std::cos(odometry.yaw), sn = std::sin(odometry.yaw);
        const float weight = static_cast<float>(1.0 / std::pow(1.0 + ahead / 5.0, 2));
        seen.push_back({1, static_cast<float>(odometry.x + c * measured),
                        static_cast<float>(odometry.y + sn * measured), weight});
      }
      tracker.observe(frame, odometer, seen);
      landmarks.clear();
      REQUIRE(tracker.commit(t, false, landmarks));
      // The car drives `step`; the odometry says `step * scale`.
      const double turn = bend_deg_per_m * step / 57.29577951308232;
      odometry = compose(odometry, Pose2{step * scale, 0.0, turn});
      odometer += step * scale;
    }
    return tracker.odometry_scale().estimate();
  }
};

}  // namespace

TEST_CASE("the camera measures the odometry's scale on markings passed on a straight road", "[scale]") {
  for (const double scale : {0.985, 1.0, 1.005, 1.02}) {
    LandmarkTracker tracker(TrackerConfig{});
    Drive drive;
    drive.scale = scale;
    const std::optional<ScaleEstimate> e = drive.run(1200.0, tracker);
    REQUIRE(e.has_value());
    CHECK(e->markings >= 90);
    CHECK(e->scale == Catch::Approx(scale).margin(0.003));
    // The standard error tells how far off the estimate can be.
    CHECK(std::abs(e->scale - scale) < 4.0 * e->standard_error);
    CHECK(e->standard_error < 0.002);
  }
}

TEST_CASE("no scale before enough markings, none from markings passed while turning", "[scale]") {
  Drive drive;
  drive.scale = 1.01;
  {
    LandmarkTracker tracker(TrackerConfig{});
    CHECK_FALSE(drive.run(12.0 * (OdometryScaleEstimator::kMinMarkings - 3), tracker).has_value());
    CHECK(tracker.odometry_scale().counters().markings_used < OdometryScaleEstimator::kMinMarkings);
  }
  {
    // 0.2 deg per m: the car turns 2 degrees while it sees a marking.
    drive.bend_deg_per_m = 0.2;
    LandmarkTracker tracker(TrackerConfig{});
    CHECK_FALSE(drive.run(600.0, tracker).has_value());
    const ScaleCounters& c = tracker.odometry_scale().counters();
    CHECK(c.markings_used == 0);
    CHECK(c.markings_turning >= 45);
  }
}

TEST_CASE("a marking whose ranges do not follow the driving is left out", "[scale]") {
  OdometryScaleEstimator estimator;
  RangeFit wrong;  // a marking that keeps its range: tracked onto a vehicle ahead
  for (int i = 0; i < 10; ++i) wrong.add(i, 12.0, 1.0);
  estimator.add_marking(wrong, true);
  RangeFit brief;
  brief.add(0.0, 12.0, 1.0);
  brief.add(1.0, 11.0, 1.0);
  estimator.add_marking(brief, true);
  CHECK(estimator.counters().markings_outlier == 1);
  CHECK(estimator.counters().markings_short == 1);
  CHECK(estimator.counters().markings_used == 0);
}
