// markloop-detect: runs the road-marking detector on still images and prints
// one JSON object per detection and line. A file that cannot be read, or
// whose size is not the camera's, is reported on stderr and skipped; the
// exit status is then 1 (2 for bad usage or a bad calibration).
#include <cmath>
#include <filesystem>
#include <cstdio>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "cli/cli.hpp"
#include "perception/camera_model.hpp"
#include "perception/marking_classes.hpp"
#include "perception/marking_detector.hpp"

namespace {

constexpr const char* kUsage =
    "usage: markloop-detect --camera FILE [--min-score S] [--whole-only] IMAGE...\n"
    "\n"
    "Detects and classifies road markings in still images (PNG or JPEG, any\n"
    "colour; converted to grey) taken by the camera FILE describes (OpenCV\n"
    "YAML calibration, e.g. app/cameras/honda.yaml; its detector_* keys set the\n"
    "road region searched). Prints one JSON object per detection and line:\n"
    "  {\"image\": NAME, \"label\": LABEL, \"score\": S, \"quad\": [[x,y],...4],\n"
    "   \"ground\": [x, y]}\n"
    "quad: corners in the image's pixels (near left, near right, far right, far\n"
    "left); ground: centre on the road in metres, vehicle frame (x ahead, y left).\n"
    "A marking cut only by the view's near edge (the bonnet, the image's bottom,\n"
    "the region's near end; its far end seen whole) is reported with\n"
    "\"partial\": true, its quad and ground the visible part's.\n"
    "With detector_horizon_from_lanes: 1 in FILE, each image's lane lines place\n"
    "the horizon (a camera pitched other than calibrated) before detection.\n"
    "\n"
    "  --camera FILE   calibration (required)\n"
    "  --min-score S   report detections scoring at least S (0..1; default the\n"
    "                  detector's, 0.6)\n"
    "  --whole-only    report no partial markings\n";

// JSON string escaping for file names.
std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

}  // namespace

int main(int argc, char** argv) {
  using namespace markloop::perception;
  markloop::cli::program_name() = "markloop-detect";
  std::string camera_path;
  double min_score = -1.0;
  bool whole_only = false;
  std::vector<std::string> images;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (arg == "--whole-only") {
      whole_only = true;
      continue;
    }
    if (arg == "--camera" || arg == "--min-score") {
      if (i + 1 >= argc) markloop::cli::fail(arg + ": needs a value (see --help)");
      const char* value = argv[++i];
      if (arg == "--camera") {
        camera_path = value;
      } else {
        min_score = markloop::cli::parse_number(arg, value);
        if (min_score < 0.0 || min_score > 1.0)
          markloop::cli::fail("--min-score: must be 0..1, got " + std::string(value));
      }
      continue;
    }
    if (arg.size() > 1 && arg[0] == '-') markloop::cli::fail("unknown option " + arg + " (see --help)");
    images.push_back(arg);
  }
  if (camera_path.empty()) markloop::cli::fail("--camera FILE is required (see --help)");
  if (images.empty()) markloop::cli::fail("no images given (see --help)");

  // Missing files are reported here, plainly, before OpenCV would log them.
  std::error_code ec;
  if (!std::filesystem::is_regular_file(camera_path, ec))
    markloop::cli::fail(camera_path + ": no such calibration file");
  std::string error;
  const auto camera = load_camera_model(camera_path, error);
  if (!camera) markloop::cli::fail(error);
  DetectorConfig config;
  if (!load_detector_config(camera_path, config, error)) markloop::cli::fail(error);
  if (min_score >= 0.0) config.min_score = static_cast<float>(min_score);
  if (whole_only) config.report_partial_in_stills = false;
  MarkingDetector detector(*camera, config);

  int failures = 0;
  for (const std::string& path : images) {
    if (!std::filesystem::is_regular_file(path, ec)) {
      std::fprintf(stderr, "markloop-detect: %s: no such file\n", path.c_str());
      ++failures;
      continue;
    }
    cv::Mat grey;
    try {
      grey = cv::imread(path, cv::IMREAD_GRAYSCALE);
    } catch (const std::exception& e) {
      grey.release();
    }
    if (grey.empty()) {
      std::fprintf(stderr, "markloop-detect: %s: cannot read as an image (PNG or JPEG)\n",
                   path.c_str());
      ++failures;
      continue;
    }
    if (grey.cols != camera->width() || grey.rows != camera->height()) {
      std::fprintf(stderr, "markloop-detect: %s: image is %dx%d but the camera (%s) is %dx%d\n",
                   path.c_str(), grey.cols, grey.rows, camera_path.c_str(), camera->width(),
                   camera->height());
      ++failures;
      continue;
    }
    const std::string name = json_string(path.substr(path.find_last_of('/') + 1));
    // Each image on its own: its own lane lines place the horizon (when the
    // calibration asks for it, detector_horizon_from_lanes).
    for (const Detection& d : detector.detect_still(grey)) {
      std::printf("{\"image\": %s, \"label\": \"%s\", \"score\": %.3f, \"quad\": [", name.c_str(),
                  std::string(marking_class_name(d.label)).c_str(), static_cast<double>(d.score));
      for (int k = 0; k < 4; ++k)
        std::printf("%s[%.1f, %.1f]", k ? ", " : "", static_cast<double>(d.quad[k][0]),
                    static_cast<double>(d.quad[k][1]));
      std::printf("], \"ground\": [%.2f, %.2f]%s}\n", static_cast<double>(d.ground_x),
                  static_cast<double>(d.ground_y), d.partial ? ", \"partial\": true" : "");
    }
  }
  if (std::fflush(stdout) != 0) markloop::cli::fail("error writing the output");
  return failures > 0 ? 1 : 0;
}
