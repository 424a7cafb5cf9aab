// A camera calibration file (OpenCV YAML, markloop --calibration and
// markloop-detect --camera): any bytes load or give an error naming the
// file; a calibration that loads builds a detector that runs on a frame.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "app/perception/camera_model.hpp"
#include "app/perception/marking_detector.hpp"
#include "tests/fuzz/fuzz_input.hpp"

using namespace markloop::perception;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const markloop::fuzz::InputFile file(data, size, ".yaml");
  const markloop::Result<CameraModel> camera = load_camera_model(file.path());
  if (!camera) {
    if (camera.message().rfind(file.path(), 0) != 0) std::abort();
    return 0;
  }
  const markloop::Result<DetectorConfig> config = load_detector_config(file.path());
  if (!config) {
    if (config.message().rfind(file.path(), 0) != 0) std::abort();
    return 0;
  }
  MarkingDetector detector(*camera, *config);
  // A frame of the camera's size: grey road with a bright bar across it.
  cv::Mat frame(camera->height(), camera->width(), CV_8UC1, cv::Scalar(90));
  frame.rowRange(camera->height() * 3 / 4, camera->height() * 3 / 4 + 8).setTo(230);
  for (const Detection& d : detector.detect(frame))
    if (!(d.score >= 0.0f && d.score <= 1.0f)) std::abort();
  return 0;
}
