#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include <cmath>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

#include "app/engine/landmark_tracker.hpp"

using namespace markloop;

namespace {

// A car driving a road that turns `bend_deg_per_m`, its wheel speed reading
// `scale` times the truth, a marking on the road every 12 m. The camera
// sees each marking from 16 to 5.5 m ahead and measures it in the car's
// frame, with noise that grows with the range; the tracker gets it placed
// by the odometry, as the ECU places it.
struct Drive {
  double scale = 1.0;
  double bend_deg_per_m = 0.0;
  double noise_m = 0.05;
  double step_m = 1.0;  // 10 m/s at 10 frames/s

  std::optional<ScaleEstimate> run(double metres, LandmarkTracker& tracker) const {
    std::mt19937 rng(7);
    std::normal_distribution<double> unit(0.0, 1.0);
    const double turn = bend_deg_per_m * step_m * std::numbers::pi / 180.0;
    std::vector<Pose2> markings;
    for (Pose2 p; static_cast<double>(markings.size()) * 12.0 < metres + 30.0;) {
      markings.push_back(p);
      for (int i = 0; i < 12; ++i) p = compose(p, Pose2{1.0, 0.0, turn / step_m});
    }
    FixedVector<Landmark, 64> landmarks;
    Pose2 truth, odometry;
    double odometer = 0.0;
    for (FrameIndex f = 0; double(f) * step_m < metres; ++f) {
      std::vector<Observation> seen;
      for (const Pose2& m : markings) {
        const Pose2 in_car = compose(inverse(truth), m);
        if (in_car.x < 5.5 || in_car.x > 16.0) continue;
        const double sigma = noise_m * (1.0 + in_car.x / 5.0);
        const Pose2 placed =
            compose(odometry, Pose2{in_car.x + sigma * unit(rng), in_car.y + sigma * unit(rng), 0.0});
        const auto weight = static_cast<float>(1.0 / std::pow(1.0 + in_car.x / 5.0, 2));
        seen.push_back({1, static_cast<float>(placed.x), static_cast<float>(placed.y), weight});
      }
      const double t = double(f) / 10.0;
      tracker.observe(FrameInput{f, t, true, odometry}, odometer, seen);
      landmarks.clear();
      REQUIRE(tracker.commit(t, false, landmarks));
      truth = compose(truth, Pose2{step_m, 0.0, turn});
      odometry = compose(odometry, Pose2{step_m * scale, 0.0, turn});
      odometer += step_m * scale;
    }
    return tracker.odometry_scale().estimate();
  }
};

}  // namespace

TEST_CASE("the camera measures the odometry's scale on markings passed, straight or on a bend", "[scale]") {
  for (const double bend : {0.0, 0.5, -1.5}) {  // 1.5 deg/m: a 38 m radius
    for (const double scale : {0.985, 1.0, 1.005, 1.02}) {
      LandmarkTracker tracker(TrackerConfig{});
      Drive drive;
      drive.scale = scale;
      drive.bend_deg_per_m = bend;
      const std::optional<ScaleEstimate> e = drive.run(1200.0, tracker);
      REQUIRE(e.has_value());
      CHECK(e->markings >= 90);
      CHECK(e->scale == Catch::Approx(scale).margin(0.003));
      // The standard error tells how far off the estimate can be.
      CHECK(std::abs(e->scale - scale) < 4.0 * e->standard_error);
      CHECK(e->standard_error < 0.002);
    }
  }
}

TEST_CASE("no scale before enough markings", "[scale]") {
  Drive drive;
  drive.scale = 1.01;
  LandmarkTracker tracker(TrackerConfig{});
  CHECK_FALSE(drive.run(12.0 * (OdometryScaleEstimator::kMinMarkings - 3), tracker).has_value());
  CHECK(tracker.odometry_scale().counters().markings_used < OdometryScaleEstimator::kMinMarkings);
}

TEST_CASE("a marking whose drift does not follow the driving is left out", "[scale]") {
  OdometryScaleEstimator estimator;
  MarkingFit wrong;  // moves with the car: a vehicle ahead taken for a marking
  for (int i = 0; i < 10; ++i) wrong.add(i, 0.0, 12.0 + i, 0.0, 1.0);
  estimator.add_marking(wrong);
  MarkingFit brief;  // seen over too little driving
  brief.add(0.0, 0.0, 12.0, 0.0, 1.0);
  brief.add(1.0, 0.0, 12.0, 0.0, 1.0);
  estimator.add_marking(brief);
  CHECK(estimator.counters().markings_outlier == 1);
  CHECK(estimator.counters().markings_short == 1);
  CHECK(estimator.counters().markings_used == 0);
}
