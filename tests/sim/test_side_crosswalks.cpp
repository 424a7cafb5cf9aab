// The detector on the simulator's frames: a side street's crosswalk, seen
// from the side as the car crosses the intersection (its stripes bars
// across the car's road, one behind the other), is named a crosswalk once,
// where it lies, not a row of stop lines (SideCrosswalkConfig).
#include <catch2/catch_test_macros.hpp>

#include <cmath>
#include <vector>

#include <opencv2/core.hpp>

#include "app/perception/camera_model.hpp"
#include "app/perception/marking_classes.hpp"
#include "app/perception/marking_detector.hpp"
#include "sim/render.hpp"
#include "sim/world.hpp"
#include "tests/support/clean_frame.hpp"

using namespace markloop;
using namespace markloop::sim;

namespace {

const Label kCrosswalk = *perception::marking_class_from_name("crosswalk");
const Label kStopline = *perception::marking_class_from_name("stopline");

// The poses on the drive's road from which the crosswalk `m`, painted
// across a road at right angles to it, lies on the right wholly within the
// detector's view (6 m either side and its 0.3 m guard band), 18 m ahead down to 10 m, every half
// metre.
std::vector<Pose2> side_views_of(const Scenario& scenario, const Marking& m) {
  std::vector<Pose2> poses;
  for (double s = 0.0; s < scenario.road.length() && poses.size() < 17; s += 0.05) {
    const Pose2 p = scenario.road.at(s);
    const double dx = m.x - p.x, dy = m.y - p.y;
    const double ahead = std::cos(p.yaw) * dx + std::sin(p.yaw) * dy;
    const double left = -std::sin(p.yaw) * dx + std::cos(p.yaw) * dy;
    const double across = std::abs(std::cos(m.heading - p.yaw));
    const double wanted = 18.0 - 0.5 * static_cast<double>(poses.size());
    const bool on_right = left + 0.5 * m.length_m < -1.0 && left - 0.5 * m.length_m > -6.25;
    if (across < 0.05 && std::abs(ahead - wanted) < 0.03 && on_right) poses.push_back(p);
  }
  return poses;
}

struct Seen {
  int crosswalks = 0;        // named crosswalk within 1 m of its centre
  int stop_lines = 0;        // stop lines within its footprint
  double worst_error = 0.0;  // metres, of the crosswalks
};

Seen seen_from_side(perception::MarkingDetector& detector, Renderer& renderer, const Pose2& pose,
                    const Marking& m) {
  const cv::Mat image = clean_frame(renderer, pose);
  const double dx = m.x - pose.x, dy = m.y - pose.y;
  const double ahead = std::cos(pose.yaw) * dx + std::sin(pose.yaw) * dy;
  const double left = -std::sin(pose.yaw) * dx + std::cos(pose.yaw) * dy;
  Seen seen;
  for (const perception::Detection& d : detector.detect(image)) {
    const double error = std::hypot(d.ground_x - ahead, d.ground_y - left);
    if (d.label == kCrosswalk && error < 1.0) {
      ++seen.crosswalks;
      seen.worst_error = std::max(seen.worst_error, error);
    }
    // The stripes' footprint seen from the side: along the car's road it
    // spans the crosswalk's width, across it the crosswalk's length.
    if (d.label == kStopline && std::abs(d.ground_x - ahead) < 0.5 * m.width_m + 0.5 &&
        std::abs(d.ground_y - left) < 0.5 * m.length_m + 0.5)
      ++seen.stop_lines;
  }
  return seen;
}

}  // namespace

TEST_CASE("a crosswalk seen from the side is named a crosswalk once, where it lies") {
  const auto scenario = make_scenario("turn-ins", 2);
  REQUIRE(scenario.has_value());
  const perception::CameraModel camera = perception::default_camera_model();
  Renderer renderer(camera, *scenario);
  perception::DetectorConfig joined_config, apart_config;
  apart_config.side_crosswalks = false;
  perception::MarkingDetector joined(camera, joined_config), apart(camera, apart_config);
  int crosswalks = 0, named = 0, named_twice = 0, stop_lines_joined = 0, stop_lines_apart = 0;
  double worst_error = 0.0;
  for (const Marking& m : scenario->markings) {
    if (m.label != kCrosswalk) continue;
    const std::vector<Pose2> poses = side_views_of(*scenario, m);
    if (poses.size() < 17) continue;
    ++crosswalks;
    bool seen = false;
    for (const Pose2& pose : poses) {
      const Seen with = seen_from_side(joined, renderer, pose, m);
      seen = seen || with.crosswalks > 0;
      named_twice += with.crosswalks > 1 ? 1 : 0;
      worst_error = std::max(worst_error, with.worst_error);
      stop_lines_joined += with.stop_lines;
      stop_lines_apart += seen_from_side(apart, renderer, pose, m).stop_lines;
    }
    named += seen ? 1 : 0;
    if (crosswalks == 8) break;
  }
  INFO(crosswalks << " crosswalks passed on the right: named " << named << ", twice in a frame "
                  << named_twice << ", worst centre error " << worst_error << " m; stop lines on them "
                  << stop_lines_joined << ", without joining " << stop_lines_apart);
  REQUIRE(crosswalks >= 4);
  CHECK(named >= crosswalks - 1);
  CHECK(named_twice == 0);
  CHECK(worst_error < 0.2);
  // Left: the first bars coming into view, fewer than a stack.
  CHECK(stop_lines_joined * 4 <= stop_lines_apart);
}
