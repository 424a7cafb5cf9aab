// Proves detect() does not touch the heap: operator new is replaced, and so
// are the C allocation functions (OpenCV allocates matrices with malloc and
// posix_memalign), all counted while frames are processed.
#include <cmath>
#include <cstdlib>
#include <numbers>

#include <catch2/catch_test_macros.hpp>

#include "app/perception/marking_detector.hpp"
#include "tests/perception/synthetic_road.hpp"

// The C functions too, except under AddressSanitizer (it owns malloc).
#define MARKLOOP_COUNT_C_ALLOCATIONS 1
#include "tests/support/count_allocations.hpp"

using namespace markloop::perception;
using markloop::perception::testing::clutter_frame;
using markloop::perception::testing::garbage_frame;
using markloop::perception::testing::GroundRect;
using markloop::perception::testing::render_road;
using markloop::test::AllocationCounter;

TEST_CASE("the counters see C, C++ and OpenCV allocations", "[perception][memory]") {
  AllocationCounter heap;
  void* p = std::malloc(64);
  int* q = new int(3);
  cv::Mat m(64, 64, CV_8UC1);
  const std::size_t allocations = heap.stop();
  std::free(p);
  delete q;
  // new + malloc + the Mat's buffer; under ASan only the new.
  CHECK(allocations >= (markloop::test::counts_c_allocations ? 3u : 1u));
}

TEST_CASE("detect() allocates nothing, frame after frame", "[perception][memory]") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  // Frames with markings moving towards the car, lane lines and a crowd of
  // specks, so that every stage (labelling, grouping, features, classifier)
  // runs.
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 12; ++k) {
    const double x = 18.0 - 1.2 * k;
    std::vector<GroundRect> paint = {{x, x + 2.4, 0.5, 1.1},     {x, x + 2.4, -0.2, 0.3},
                                     {x - 1, x + 2, -3.0, -2.0}, {3.0, 25.0, 1.7, 1.85},
                                     {3.0, 25.0, -1.85, -1.7},   {x + 3, x + 3.4, -5, 5}};
    for (int s = 0; s < 30; ++s) {
      const double sx = 4.0 + 0.5 * s, sy = -5.0 + 0.33 * s;
      paint.push_back({sx, sx + 0.25, sy, sy + 0.2});
    }
    frames.push_back(render_road(camera, paint));
  }
  detector.detect(frames[0]);  // first call: nothing lazy may remain either
  std::size_t detections = 0, candidates = 0;
  AllocationCounter heap;
  for (int round = 0; round < 10; ++round)
    for (const cv::Mat& frame : frames) {
      detections += detector.detect(frame).size();
      candidates += detector.candidates().size();
    }
  const std::size_t allocations = heap.stop();
  CHECK(allocations == 0);
  CHECK(candidates > 0);
  CHECK(detector.counters().frames == 121);
  (void)detections;
}

TEST_CASE("detect() allocates nothing at its caps either, nor on noise (paint everywhere, garbage)",
          "[perception][memory]") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 8; ++k) frames.push_back(clutter_frame(camera, k));
  for (int k = 0; k < 4; ++k) frames.push_back(garbage_frame(camera, k));
  detector.detect(frames[0]);
  AllocationCounter heap;
  for (int round = 0; round < 2; ++round)
    for (const cv::Mat& frame : frames) detector.detect(frame);
  const std::size_t allocations = heap.stop();
  CHECK(allocations == 0);
  CHECK(detector.counters().candidates_dropped > 0);
  CHECK(detector.counters().noisy_frames > 0);
}

TEST_CASE("the horizon from the lane lines allocates nothing, when it moves the view either",
          "[perception][memory]") {
  const CameraModel calibrated = default_camera_model();
  // Frames from the camera pitched 1 degree up and down: each still image
  // moves the view's row shift, which recomputes its masks.
  std::vector<cv::Mat> frames;
  for (const double pitch_deg : {-1.0, 1.0}) {
    CameraMounting mounting = calibrated.mounting();
    mounting.pitch_rad += pitch_deg * std::numbers::pi / 180.0;
    const CameraModel actual =
        CameraModel::pinhole(calibrated.width(), calibrated.height(), calibrated.intrinsics(), mounting);
    frames.push_back(render_road(
        actual,
        {{3.0, 40.0, 1.7, 1.85}, {3.0, 40.0, -1.85, -1.7}, {3.0, 40.0, 5.3, 5.45}, {8.8, 11.2, 0.6, 1.2}}));
  }
  DetectorConfig config;
  config.horizon_from_lanes = true;
  MarkingDetector detector(calibrated, config);
  detector.detect_still(frames[0]);
  AllocationCounter heap;
  for (int round = 0; round < 5; ++round)
    for (const cv::Mat& frame : frames) {
      detector.detect_still(frame);
      detector.detect(frame);
    }
  const std::size_t allocations = heap.stop();
  CHECK(allocations == 0);
  CHECK(detector.counters().horizon_moves >= 10);
}
