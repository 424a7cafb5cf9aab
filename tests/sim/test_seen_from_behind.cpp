// The detector on the simulator's frames: a marking seen from behind (an
// arrow in the oncoming lane, a number driven past the other way) is named
// as it was painted, because each candidate is also read turned half way
// round (ClassifierConfig::turned_min_score).
#include <catch2/catch_test_macros.hpp>

#include <cmath>
#include <cstddef>
#include <numbers>

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

constexpr double kAhead_m = 10.0;

// Whether `detector` names the marking 10 m straight ahead of `pose`
// `label` in the frame rendered there.
bool named_ahead(Renderer& renderer, perception::MarkingDetector& detector, const Pose2& pose, Label label) {
  const cv::Mat image = clean_frame(renderer, pose);
  for (const perception::Detection& d : detector.detect(image))
    if (std::hypot(d.ground_x - kAhead_m, d.ground_y) < 1.5) return d.label == label;
  return false;
}

// Of the `scenario`'s markings of a class that a half turn changes
// (arrows, words, numbers), how many the detector names right seen from
// ahead and seen from behind, each from 10 m away in its lane.
struct Named {
  int markings = 0, ahead = 0, behind = 0;
};
Named named_both_ways(const Scenario& scenario, float turned_min_score) {
  const perception::CameraModel camera = perception::default_camera_model();
  Renderer renderer(camera, scenario);
  perception::DetectorConfig config;
  config.turned_min_score = turned_min_score;
  perception::MarkingDetector detector(camera, config);
  Named named;
  for (const Marking& m : scenario.markings) {
    if (perception::same_when_turned(m.label)) continue;
    const double dx = std::cos(m.heading) * kAhead_m, dy = std::sin(m.heading) * kAhead_m;
    const Pose2 ahead{m.x - dx, m.y - dy, m.heading};
    const Pose2 behind{m.x + dx, m.y + dy, m.heading + std::numbers::pi};
    ++named.markings;
    named.ahead += named_ahead(renderer, detector, ahead, m.label) ? 1 : 0;
    named.behind += named_ahead(renderer, detector, behind, m.label) ? 1 : 0;
    if (named.markings == 40) break;
  }
  return named;
}

}  // namespace

TEST_CASE("arrows and words seen from behind are named as they were painted") {
  const auto scenario = make_scenario("opposite", 1);
  REQUIRE(scenario.has_value());
  const Named turned = named_both_ways(*scenario, perception::DetectorConfig{}.turned_min_score);
  const Named upright = named_both_ways(*scenario, 2.0f);  // never read turned
  INFO("of " << turned.markings << ": read turned too, ahead " << turned.ahead << ", behind " << turned.behind
             << "; upright only, ahead " << upright.ahead << ", behind " << upright.behind);
  REQUIRE(turned.markings == 40);
  // From behind as from ahead; read upright only, few from behind.
  CHECK(turned.ahead >= 38);
  CHECK(turned.behind >= 38);
  CHECK(upright.behind <= 10);
  // Reading a marking seen ahead turned as well costs nothing there.
  CHECK(turned.ahead >= upright.ahead);
}
