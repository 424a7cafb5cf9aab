// markloop-detect: runs the road-marking detector on still images and prints
// one JSON object per detection and line. A file that cannot be read, or
// whose size is not the camera's, is reported on stderr and skipped; the
// exit status is then 2, as for bad usage or a bad calibration (1: a view or
// the output could not be written).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <span>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "app/common/cli.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/marking_classes.hpp"
#include "app/perception/marking_classifier.hpp"
#include "app/perception/marking_detector.hpp"
#include "app/tools/common/still_image.hpp"
#include "app/tools/common/tool_files.hpp"

namespace {

constexpr const char* kUsage =
    "usage: markloop-detect --camera FILE [--min-score S] [--whole-only] [--view DIR]\n"
    "                       IMAGE...\n"
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
    "  --whole-only    report no partial markings\n"
    "  --view DIR      also write what the detector saw, per image DIR/NAME.png\n"
    "                  (NAME without its extension): the bird's-eye view at twice\n"
    "                  its size, bright paint in red, each candidate's box with its\n"
    "                  class and score: green reported, yellow a marking class not\n"
    "                  reported (C: cut by the view's edge; or below the score, a\n"
    "                  piece of a larger marking, beyond the region), grey rejected;\n"
    "                  J: a word split by its I (a letter taken for a line),\n"
    "                  its candidates reported together\n"
    "\n"
    "Images are read whole, up to 256 MiB each.\n"
    "Exit status: 0 on success; 1 when a view or the output cannot be written;\n"
    "2 on bad options, a bad calibration or an image that cannot be used (the\n"
    "other images are still run).\n";

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

// The view a user checks a miss against: which paint the threshold found,
// how it was grouped, and what each group was called.
markloop::Status write_view(const markloop::perception::MarkingDetector& detector,
                            std::span<const markloop::perception::Detection> reported,
                            const std::string& path) {
  using namespace markloop::perception;
  constexpr int kScale = 2;
  cv::Mat view;
  cv::cvtColor(detector.birdseye_image(), view, cv::COLOR_GRAY2BGR);
  const cv::Mat& paint = detector.paint_mask();
  for (int r = 0; r < view.rows; ++r)
    for (int c = 0; c < view.cols; ++c)
      if (paint.at<std::uint8_t>(r, c) != 0) {
        auto& pixel = view.at<cv::Vec3b>(r, c);
        pixel = {static_cast<std::uint8_t>(pixel[0] / 3), static_cast<std::uint8_t>(pixel[1] / 3), 255};
      }
  cv::resize(view, view, {}, kScale, kScale, cv::INTER_NEAREST);
  const auto candidates = detector.candidates();
  const auto reported_by = detector.reported_by();
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const Candidate& c = candidates[i];
    // A word split by its I is reported as one, where its first candidate says.
    const auto first = static_cast<std::size_t>(reported_by[i]);
    const bool joined = first != i || reports_others(reported_by, i);
    Detection where{};
    detector.locate(joined ? joined_candidate(candidates, reported_by, first) : c, where);
    const bool marking = c.predicted != kRejectClass;
    bool was_reported = false;
    for (const Detection& d : reported)
      was_reported = was_reported || (static_cast<int>(d.label) == c.predicted &&
                                      d.ground_x == where.ground_x && d.ground_y == where.ground_y);
    const cv::Scalar colour = was_reported ? cv::Scalar(0, 220, 0)
                              : marking    ? cv::Scalar(0, 220, 255)
                                           : cv::Scalar(160, 160, 160);
    const cv::Point top_left(c.col0 * kScale, c.row0 * kScale);
    cv::rectangle(view, top_left, {(c.col1 + 1) * kScale - 1, (c.row1 + 1) * kScale - 1}, colour, 1);
    char text[48];
    std::snprintf(text, sizeof text, "%s %.2f%s%s",
                  marking ? std::string(marking_class_name(static_cast<markloop::Label>(c.predicted))).c_str()
                          : "reject",
                  static_cast<double>(c.score), c.clipped ? " C" : "", joined ? " J" : "");
    cv::putText(view, text, top_left + cv::Point(0, -3), cv::FONT_HERSHEY_PLAIN, 0.8, colour, 1);
  }
  return markloop::io::write_png(path, view);
}

// Why a path named as an image cannot be read as one, or nothing (a file, a
// pipe: read_grey_still reads either, up to its limit).
std::string not_a_file_reason(const std::filesystem::file_status& status, const std::error_code& error) {
  if (std::filesystem::is_directory(status)) return "is a directory, not an image";
  if (std::filesystem::exists(status)) return {};
  if (error && error != std::errc::no_such_file_or_directory) return error.message();  // no access
  return "no such file";
}

// The view of `image` under `view_dir`.
std::string view_path(const std::string& view_dir, const std::string& image) {
  return (std::filesystem::path(view_dir) / std::filesystem::path(image).stem()).string() + ".png";
}

// A view that would overwrite one of the images: refused before any is read.
void check_views(const std::string& view_dir, const std::vector<std::string>& images) {
  std::vector<markloop::platform::FileId> inputs;
  for (const std::string& image : images)
    if (const auto id = markloop::platform::regular_file_id(image)) inputs.push_back(*id);
  for (const std::string& image : images) {
    const std::string view = view_path(view_dir, image);
    const auto id = markloop::platform::regular_file_id(view);
    if (id && std::find(inputs.begin(), inputs.end(), *id) != inputs.end())
      markloop::cli::fail(view + ": the view of " + image + " would overwrite an input image");
  }
}

struct Options {
  std::string camera_path;
  double min_score = -1.0;  // below 0: the calibration's
  bool whole_only = false;
  std::string view_dir;
  std::vector<std::string> images;
};

// The option table; kUsage above is the help text a user reads.
constexpr markloop::cli::OptionSpec kOptions[] = {
    {"--camera", "FILE", "calibration (required)"},
    {"--min-score", "S", "report detections scoring at least S (0..1)"},
    {"--whole-only", "", "report no partial markings"},
    {"--view", "DIR", "also write what the detector saw, per image DIR/NAME.png"},
};

// One option as given, checked where it stands on the command line.
void apply_option(std::string_view name, std::string_view value, Options& o) {
  if (name == "--whole-only") {
    o.whole_only = true;
  } else if (name == "--camera") {
    o.camera_path = value;
  } else if (name == "--view") {
    o.view_dir = value;
  } else if (name == "--min-score") {
    const std::string text(value);
    o.min_score = markloop::cli::parse_number(name, text.c_str());
    if (o.min_score < 0.0 || o.min_score > 1.0) markloop::cli::fail("--min-score: must be 0..1, got " + text);
  }
}

Options parse(int argc, char** argv) {
  const auto args =
      markloop::cli::parse_args_or_fail(argc, argv, kOptions, 0, static_cast<std::size_t>(argc));
  Options o;
  // The options before --help are checked as given, as without it.
  for (const auto& given : args.given()) apply_option(given.name, given.value, o);
  if (args.help()) {
    std::fputs(kUsage, stdout);
    std::exit(markloop::cli::kExitOk);
  }
  o.images.assign(args.positional().begin(), args.positional().end());
  if (o.camera_path.empty()) markloop::cli::fail("--camera FILE is required (see --help)");
  if (o.images.empty()) markloop::cli::fail("no image given: IMAGE... is required (see --help)");
  return o;
}

// The calibration must be a regular file: it is opened twice (camera, then
// detector keys), and a pipe would be empty the second time. Missing files
// are reported here, plainly, before OpenCV would log them.
void check_calibration_file(const std::string& camera_path) {
  std::error_code ec;
  const std::filesystem::file_status camera_status = std::filesystem::status(camera_path, ec);
  if (std::filesystem::is_directory(camera_status))
    markloop::cli::fail(camera_path + ": is a directory, not a calibration file");
  if (!std::filesystem::exists(camera_status))
    markloop::cli::fail(camera_path + ": no such calibration file");
  if (!std::filesystem::is_regular_file(camera_status))
    markloop::cli::fail(camera_path + ": not a regular file, which a calibration must be");
}

// The camera and the detector settings the options and the calibration describe.
struct Setup {
  markloop::perception::CameraModel camera;
  markloop::perception::DetectorConfig config;
};

Setup load_setup(const Options& o) {
  using namespace markloop::perception;
  check_calibration_file(o.camera_path);
  const auto camera = load_camera_model(o.camera_path);
  if (!camera) markloop::cli::fail(camera.message());
  auto loaded = load_detector_config(o.camera_path, DetectorConfig{});
  if (!loaded) markloop::cli::fail(loaded.message());
  DetectorConfig config = *loaded;
  if (o.min_score >= 0.0) config.min_score = static_cast<float>(o.min_score);
  if (o.whole_only) config.report_partial_in_stills = false;
  return {*camera, config};
}

// The --view directory, made when missing; fails the run when it cannot be.
void prepare_view_dir(const Options& o) {
  std::error_code made, ec;
  std::filesystem::create_directories(o.view_dir, made);
  if (!std::filesystem::is_directory(o.view_dir, ec))
    markloop::tools::fail_run("--view " + o.view_dir + ": cannot create the directory" +
                              (made ? " (" + made.message() + ")" : std::string()));
  check_views(o.view_dir, o.images);
}

void print_detection(const std::string& name, const markloop::perception::Detection& d) {
  std::printf("{\"image\": %s, \"label\": \"%s\", \"score\": %.3f, \"quad\": [", name.c_str(),
              std::string(markloop::perception::marking_class_name(d.label)).c_str(),
              static_cast<double>(d.score));
  for (int k = 0; k < 4; ++k)
    std::printf("%s[%.1f, %.1f]", k ? ", " : "", static_cast<double>(d.quad[k][0]),
                static_cast<double>(d.quad[k][1]));
  std::printf("], \"ground\": [%.2f, %.2f]%s}\n", static_cast<double>(d.ground_x),
              static_cast<double>(d.ground_y), d.partial ? ", \"partial\": true" : "");
}

// What became of the images: the exit status counts them.
struct Tally {
  int bad_images = 0;
  int unwritten_views = 0;
};

// The image as the camera's grey frame, or empty after saying on stderr
// why it cannot be used.
cv::Mat read_image(const Options& o, const std::string& path, cv::Size size) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (const std::string reason = not_a_file_reason(status, ec); !reason.empty()) {
    std::fprintf(stderr, "markloop-detect: %s: %s\n", path.c_str(), reason.c_str());
    return {};
  }
  markloop::Result<cv::Mat> grey = markloop::io::read_grey_still(path, size);
  if (!grey) {
    std::string error = grey.message();
    // A size that is not the camera's may be the calibration's fault: name it.
    if (error.starts_with("image is ")) error += " (" + o.camera_path + ")";
    std::fprintf(stderr, "markloop-detect: %s: %s\n", path.c_str(), error.c_str());
    return {};
  }
  return std::move(grey).value();
}

void detect_image(const Options& o, const std::string& path, cv::Size size,
                  markloop::perception::MarkingDetector& detector, Tally& tally) {
  using namespace markloop::perception;
  const cv::Mat grey = read_image(o, path, size);
  if (grey.empty()) {
    ++tally.bad_images;
    return;
  }
  const std::string name = json_string(std::filesystem::path(path).filename().string());
  // Each image on its own: its own lane lines place the horizon (when the
  // calibration asks for it, detector_horizon_from_lanes).
  const std::span<const Detection> detections = detector.detect_still(grey);
  if (!o.view_dir.empty()) {
    if (const markloop::Status written = write_view(detector, detections, view_path(o.view_dir, path));
        !written) {
      std::fprintf(stderr, "markloop-detect: %s\n", written.message().c_str());
      ++tally.unwritten_views;
    }
  }
  for (const Detection& d : detections) print_detection(name, d);
}

}  // namespace

int main(int argc, char** argv) {
  markloop::cli::program_name() = "markloop-detect";
  const Options o = parse(argc, argv);
  const Setup setup = load_setup(o);
  markloop::perception::MarkingDetector detector(setup.camera, setup.config);
  if (!o.view_dir.empty()) prepare_view_dir(o);
  const cv::Size size(setup.camera.width(), setup.camera.height());
  Tally tally;
  for (const std::string& path : o.images) detect_image(o, path, size, detector, tally);
  if (const markloop::Status flushed = markloop::tools::flush_stdout(); !flushed)
    markloop::tools::fail_run(flushed.message());
  if (tally.bad_images > 0) return markloop::cli::kExitBadInput;
  return tally.unwritten_views > 0 ? markloop::cli::kExitOutputFailed : markloop::cli::kExitOk;
}
