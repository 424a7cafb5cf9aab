#include <catch2/catch_test_macros.hpp>

#include <cmath>
#include <vector>

#include "app/engine/landmark_tracker.hpp"

using namespace markloop;

namespace {

FrameInput frame_at(FrameIndex f, double fps = 10.0) {
  FrameInput in;
  in.frame = f;
  in.t = f / fps;
  in.has_pose = true;
  in.pose = {static_cast<double>(f), 0.0, 0.0};  // 1 m per frame along x
  return in;
}

}  // namespace

TEST_CASE("observations of one marking fuse into one landmark, labelled by vote", "[tracker]") {
  LandmarkTracker tracker(TrackerConfig{});
  FixedVector<Landmark, 8> out;
  // Frames 0..9 see a marking near (20, 0); frame 3 misreads its label.
  for (FrameIndex f = 0; f < 10; ++f) {
    const Label label = f == 3 ? 7 : 2;
    const Observation obs{label, 20.0f + 0.1f * static_cast<float>(f % 3), 0.05f};
    tracker.observe(frame_at(f), f, {&obs, 1});
    REQUIRE(tracker.commit(f / 10.0, false, out));
    REQUIRE(out.empty());
  }
  // Unseen for more than commit_after_s: it has left view.
  tracker.observe(frame_at(16), 16, {});
  REQUIRE(tracker.commit(1.6, false, out));
  REQUIRE(out.size() == 1);
  CHECK(out[0].label == 2);
  CHECK(out[0].observations == 10);
  CHECK(out[0].first_frame == 0);
  CHECK(out[0].last_frame == 9);
  CHECK(out[0].x > 20.0f);
  CHECK(out[0].x < 20.2f);
  // Station: the car was at odometer 9 and x = 9, the marking 11 m ahead.
  CHECK(out[0].station > 20.0);
  CHECK(out[0].station < 20.2);
  CHECK(tracker.active() == 0);
}

TEST_CASE("a landmark faces the way most readings of its label did", "[tracker]") {
  // (facing of frames 0..4, of frame 5 on, landmark's facing)
  struct Case {
    Facing first, then, expected;
  };
  for (const Case c : {Case{Facing::kAlong, Facing::kAlong, Facing::kAlong},
                       Case{Facing::kAgainst, Facing::kAlong, Facing::kAgainst},
                       Case{Facing::kAny, Facing::kAny, Facing::kAny}}) {
    LandmarkTracker tracker(TrackerConfig{});
    // Seven readings; from frame 5 two more facing `then`, and a misread
    // label whose facing does not count.
    for (FrameIndex f = 0; f < 8; ++f) {
      const Observation obs{f == 7 ? Label{4} : Label{2}, 20.0f, 0.0f, 1.0f, f < 5 ? c.first : c.then};
      tracker.observe(frame_at(f), f, {&obs, 1});
    }
    FixedVector<Landmark, 8> out;
    REQUIRE(tracker.commit(100.0, false, out));
    REQUIRE(out.size() == 1);
    CHECK(out[0].label == 2);
    CHECK(out[0].facing == c.expected);
  }
}

TEST_CASE("markings side by side in one frame stay separate", "[tracker]") {
  TrackerConfig config;
  config.association_radius_m = 5.0;  // wider than the lane gap on purpose
  LandmarkTracker tracker(config);
  for (FrameIndex f = 0; f < 5; ++f) {
    const Observation obs[2] = {{1, 20.0f, 0.0f}, {2, 20.0f, 3.5f}};
    tracker.observe(frame_at(f), f, obs);
  }
  FixedVector<Landmark, 8> out;
  REQUIRE(tracker.commit(100.0, false, out));
  REQUIRE(out.size() == 2);
  CHECK(out[0].label != out[1].label);
}

TEST_CASE("a single-frame detection is dropped as spurious", "[tracker]") {
  LandmarkTracker tracker(TrackerConfig{});
  const Observation obs{1, 10.0f, 0.0f};
  tracker.observe(frame_at(0), 0, {&obs, 1});
  FixedVector<Landmark, 8> out;
  REQUIRE(tracker.commit(10.0, false, out));
  CHECK(out.empty());
  CHECK(tracker.counters().tracks_spurious == 1);
}

TEST_CASE("a track without a label majority is not committed", "[tracker]") {
  LandmarkTracker tracker(TrackerConfig{});
  for (FrameIndex f = 0; f < 6; ++f) {
    const Observation obs{static_cast<Label>(f % 3), 10.0f, 0.0f};
    tracker.observe(frame_at(f), f, {&obs, 1});
  }
  FixedVector<Landmark, 8> out;
  REQUIRE(tracker.commit(10.0, false, out));
  CHECK(out.empty());
  CHECK(tracker.counters().tracks_label_ambiguous == 1);
}

TEST_CASE("non-finite positions are rejected and counted", "[tracker]") {
  LandmarkTracker tracker(TrackerConfig{});
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const Observation obs[2] = {{1, nan, 0.0f}, {1, 0.0f, std::numeric_limits<float>::infinity()}};
  tracker.observe(frame_at(0), 0, obs);
  CHECK(tracker.counters().observations_rejected == 2);
  CHECK(tracker.active() == 0);
}

TEST_CASE("more markings than tracks are dropped, not stored", "[tracker]") {
  LandmarkTracker tracker(TrackerConfig{});
  std::vector<Observation> many;
  for (int i = 0; i < 100; ++i) many.push_back({1, static_cast<float>(i) * 10.0f, 0.0f});
  tracker.observe(frame_at(0), 0, many);
  CHECK(tracker.active() == LandmarkTracker::kMaxTracks);
  CHECK(tracker.counters().observations_dropped == 100 - LandmarkTracker::kMaxTracks);
}

TEST_CASE("a landmark's position weighs each observation by its precision", "[tracker]") {
  LandmarkTracker tracker(TrackerConfig{});
  FixedVector<Landmark, 8> out;
  // Far (weight 1) at x = 21, near (weight 3) at x = 20: the mean is 20.25.
  const Observation far{2, 21.0f, 0.0f, 1.0f};
  const Observation near{2, 20.0f, 0.4f, 3.0f};
  const Observation no_weight{2, 20.0f, 0.0f, 0.0f};
  tracker.observe(frame_at(0), 0, {&far, 1});
  tracker.observe(frame_at(1), 1, {&near, 1});
  tracker.observe(frame_at(2), 2, {&no_weight, 1});  // rejected, not a division by zero
  tracker.observe(frame_at(20), 20, {});
  REQUIRE(tracker.commit(2.0, false, out));
  REQUIRE(out.size() == 1);
  CHECK(out[0].observations == 2);
  CHECK(std::abs(out[0].x - 20.25f) < 1e-4f);
  CHECK(std::abs(out[0].y - 0.3f) < 1e-4f);
  CHECK(tracker.counters().observations_rejected == 1);
}
