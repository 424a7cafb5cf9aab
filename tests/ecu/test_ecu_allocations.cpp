// No heap after start-up, over an hour of driving through the whole
// per-frame path: every malloc (OpenCV's included) and operator new of the
// process is counted while the ECU
//   - decodes and integrates VehicleOdometry every 20 ms (E2E checked),
//   - runs the marking detector on a camera frame every 100 ms (synthetic
//     1280x512 frames with painted shapes, cycled; every 2 s under an
//     emulator, where the detector runs dozens of times slower: the same
//     code path at a cost CI can bear),
//   - feeds the markings a camera sees on a 1.2 km loop road to the sequence
//     engine (landmarks, sequences, database with rings wrapping, matching,
//     verification) and encodes every loop detection as 6 CAN pages,
//   - sends the 3 Status pages every 100 ms.
// The resident set size is sampled every 10 minutes of driving.
#include <catch2/catch_test_macros.hpp>

#include <array>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "app/ecu/ecu.hpp"
#include "app/perception/camera_model.hpp"
#include "platform/os.hpp"
#include "tests/ecu/ecu_test_support.hpp"

#define MARKLOOP_COUNT_C_ALLOCATIONS 1
#include "tests/support/count_allocations.hpp"

using namespace markloop;
using namespace markloop::ecu;
using namespace markloop::ecu::testing;
using markloop::test::AllocationCounter;
using namespace std::chrono_literals;

namespace {
#ifdef MARKLOOP_UNDER_EMULATOR
constexpr int kCameraFramesPerDetectorFrame = 20;
#else
constexpr int kCameraFramesPerDetectorFrame = 1;
#endif

EcuConfig small_ring_config() {
  EcuConfig config;
  // Small rings so that they wrap many times within the hour.
  config.engine.database.landmark_capacity = 512;
  config.engine.database.sequence_capacity = 2048;
  config.camera.fps = 10;
  return config;
}

// A coarser bird's-eye view keeps the hour affordable in CI; the code path is the same.
perception::DetectorConfig coarse_detector() {
  perception::DetectorConfig detector;
  detector.region.x_step_m = 0.10f;
  detector.region.y_step_m = 0.08f;
  return detector;
}

// Synthetic frames: road grey with painted bars and blocks where the road is.
std::vector<cv::Mat> synthetic_frames(const perception::CameraModel& camera) {
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 8; ++i) {
    cv::Mat grey(camera.height(), camera.width(), CV_8UC1, cv::Scalar(70));
    for (int j = 0; j < 6; ++j) {
      const int x = 100 + ((i * 7 + j * 13) % 10) * 100, y = 300 + ((i + j) % 4) * 45;
      cv::rectangle(grey, cv::Rect(x, y, 40 + 10 * j, 15 + 5 * (i % 3)), cv::Scalar(220), cv::FILLED);
    }
    cv::line(grey, {640, 511}, {600, 260}, cv::Scalar(230), 6);  // a lane line
    frames.push_back(grey);
  }
  return frames;
}

// Drives the ECU around the loop road, sampling the resident set every 10
// minutes after the warm-up into room reserved beforehand.
class LoopRoadDrive {
 public:
  LoopRoadDrive(Ecu& ecu, const perception::CameraModel& camera)
      : ecu_(ecu), frames_(synthetic_frames(camera)) {
    rss_samples.reserve(16);
    anonymous_samples.reserve(16);
  }

  void drive(Nanoseconds from, Nanoseconds to) {
    for (Nanoseconds t = from; t < to; t += 20ms) {
      ecu_.on_can_frame(gateway_.odometry(LoopRoad::kSpeed, road_.yaw_rate()), t);
      if (t.count() % 100'000'000 != 0) continue;
      const auto frame_index = static_cast<std::size_t>(t.count() / 100'000'000);
      // The detector's path on a real frame, then what the camera sees of the road.
      if (frame_index % kCameraFramesPerDetectorFrame == 0)
        (void)ecu_.on_frame(frames_[(frame_index / kCameraFramesPerDetectorFrame) % frames_.size()], t,
                            SteadyClock::now());
      const std::size_t n = road_.detections(std::chrono::duration<double>(t).count(), detections_);
      ecu_.on_detections(std::span<const perception::Detection>(detections_.data(), n), t + 1ns,
                         SteadyClock::now());
      ecu_.send_status(t);
      if ((t - 130s).count() % 600'000'000'000 == 0) sample_memory();
    }
  }

  std::vector<std::size_t> rss_samples, anonymous_samples;

 private:
  void sample_memory() {
    std::size_t rss = 0, anonymous = 0;
    (void)platform::resident_bytes(rss);
    (void)platform::anonymous_resident_bytes(anonymous);
    rss_samples.push_back(rss);
    anonymous_samples.push_back(anonymous);
  }

  Ecu& ecu_;
  std::vector<cv::Mat> frames_;
  Gateway gateway_;
  LoopRoad road_;
  std::array<perception::Detection, perception::kMaxDetections> detections_{};
};

// Memory: anonymous resident memory (heap, stacks, tables) does not change
// at all; the total RSS may grow by program text paged in when a code path
// runs for the first time (e.g. eviction, once the rings wrap).
void check_memory_flat(const std::vector<std::size_t>& rss_samples,
                       const std::vector<std::size_t>& anonymous_samples) {
  REQUIRE(anonymous_samples.size() >= 7);
#ifndef MARKLOOP_UNDER_EMULATOR  // under qemu-user these are the emulator's pages
  for (std::size_t i = 1; i < anonymous_samples.size(); ++i) {
    INFO("anonymous RSS at " << 10 * i << " min: " << anonymous_samples[i]
                             << " bytes, at 0: " << anonymous_samples[0]);
    CHECK(anonymous_samples[i] == anonymous_samples[0]);
  }
#endif
  WARN("RSS every 10 min (total / anonymous, bytes): " << [&] {
    std::string s;
    for (std::size_t i = 0; i < rss_samples.size(); ++i)
      s += std::to_string(rss_samples[i]) + "/" + std::to_string(anonymous_samples[i]) + " ";
    return s;
  }());
}

}  // namespace

TEST_CASE("an hour of driving through the ECU allocates nothing and RSS stays flat") {
  const EcuConfig config = small_ring_config();
  const perception::DetectorConfig detector = coarse_detector();
  RecordingBus bus;
  const perception::CameraModel camera = perception::default_camera_model();
  Ecu ecu(config, camera, detector, &bus, nullptr);
  LoopRoadDrive road(ecu, camera);

  road.drive(0s, 130s);  // warm-up: a lap and more, every path taken once
  REQUIRE(ecu.counters().loop_detections > 0);
  const auto detections_before = ecu.counters().loop_detections;
  AllocationCounter heap;
  road.drive(130s, 130s + 3600s + 20ms);  // the last sample at 60 min included
  const std::size_t allocations = heap.stop();

  INFO("allocations during the hour: " << allocations);
  CHECK(allocations == 0);
  CHECK(ecu.counters().frames_processed >= 36000 + 36000 / kCameraFramesPerDetectorFrame);
  CHECK(ecu.counters().loop_detections - detections_before > 500);
  CHECK(bus.errors == 0);
  CHECK(ecu.engine().database().stats().landmarks_evicted > 1000);
  check_memory_flat(road.rss_samples, road.anonymous_samples);
}
