// Time per frame of MarkingDetector::detect() (capture excluded): frames are
// read from a YUV4MPEG2 file (e.g. a simulator drive's frames.y4m) or, without
// one, synthesised (a road with lane lines and legend-sized blocks). Prints a
// table of the median, p90, p99 and maximum per frame, per stage total.
// Single thread: run under `taskset -c N` to pin it to one core. Wall time
// includes being preempted by other processes on a shared machine; the
// thread's CPU time (CLOCK_THREAD_CPUTIME_ID) does not, and is printed too.
// The cores of one machine may run at different speeds (a VM's virtual CPUs
// share their hosts' cores unevenly), so the cores the frames ran on are
// printed with the figures.
#include <sched.h>

#include <algorithm>
#include <array>
#include <bitset>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <string>
#include <string_view>
#include <vector>

#include "app/common/cli.hpp"
#include "app/io/y4m.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/marking_detector.hpp"
#include "tests/perception/synthetic_road.hpp"

namespace {

constexpr const char* kUsage =
    "usage: markloop-detector-bench [--camera FILE] [--y4m FILE] [--frames N] [--skip N]\n"
    "                               [--horizon-from-lanes] [--garbage | --clutter]\n"
    "\n"
    "Times MarkingDetector::detect() per frame and prints median, p90, p99 and\n"
    "maximum. --y4m: frames from a file (mono or any YUV, luma used), else\n"
    "synthetic frames of the camera's size. --camera: calibration (default: the\n"
    "simulator's camera, 1280x512). --frames: frames timed (default 1000).\n"
    "--skip: frames of the file skipped first (default 0).\n"
    "--horizon-from-lanes: the lane lines place the horizon on every frame\n"
    "(as detector_horizon_from_lanes: 1 in a calibration file).\n"
    "--garbage: instead of a road, frames of noise and checkerboards of 1 to 4\n"
    "pixels (a failing sensor, a camera gone wrong): taken for noise, not searched.\n"
    "--clutter: a road with paint everywhere in pieces a marking's size (tiles):\n"
    "more candidates than the detector classifies, the rest counted: the worst case.\n"
    "Also printed: how many frames the detector took for road, flat, noisy or\n"
    "cluttered views (ViewKind), and the spread of their grey (ViewSpread).\n";

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const std::size_t i = std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())));
  return v[i];
}

using namespace markloop::perception;

constexpr markloop::cli::OptionSpec kOptions[] = {
    {"--camera", "FILE", "calibration (default: the simulator's camera)"},
    {"--y4m", "FILE", "frames from a file, else synthetic frames"},
    {"--frames", "N", "frames timed (default 1000)"},
    {"--skip", "N", "frames of the file skipped first (default 0)"},
    {"--horizon-from-lanes", "", "the lane lines place the horizon on every frame"},
    {"--garbage", "", "frames of noise and checkerboards"},
    {"--clutter", "", "a road with paint everywhere in pieces a marking's size"},
};

struct Options {
  std::string camera_path, y4m_path;
  unsigned frames = 1000, skip = 0;
  bool horizon_from_lanes = false;
  const char* frame_source = nullptr;  // "garbage" or "clutter"
};

// One option as given, checked where it stands on the command line.
void apply_option(std::string_view name, std::string_view value, Options& o) {
  const std::string text(value);
  if (name == "--horizon-from-lanes") o.horizon_from_lanes = true;
  if (name == "--garbage" || name == "--clutter") {
    if (o.frame_source != nullptr) markloop::cli::fail("--garbage and --clutter: give one of them");
    o.frame_source = name == "--garbage" ? "garbage" : "clutter";
  }
  if (name == "--camera") o.camera_path = text;
  if (name == "--y4m") o.y4m_path = text;
  if (name == "--frames") o.frames = markloop::cli::parse_whole(name, text.c_str());
  if (name == "--skip") o.skip = markloop::cli::parse_whole(name, text.c_str());
}

Options parse(int argc, char** argv) {
  const auto args = markloop::cli::parse_args_or_fail(argc, argv, kOptions);
  Options o;
  for (const auto& given : args.given()) apply_option(given.name, given.value, o);
  if (args.help()) {
    std::fputs(kUsage, stdout);
    std::exit(markloop::cli::kExitOk);
  }
  if (o.frames == 0) markloop::cli::fail("--frames must be at least 1");
  if (o.frame_source != nullptr && !o.y4m_path.empty())
    markloop::cli::fail(std::string("--") + o.frame_source + " and --y4m: give one of them");
  return o;
}

// Twenty frames of a road with lane lines and legend-sized blocks, or of
// garbage or clutter.
std::vector<cv::Mat> synthetic_frames(const CameraModel& camera, const char* frame_source) {
  std::vector<cv::Mat> synthetic;
  if (frame_source != nullptr) {
    const bool garbage = std::string_view(frame_source) == "garbage";
    for (int k = 0; k < 20; ++k)
      synthetic.push_back(garbage ? markloop::perception::testing::garbage_frame(camera, k)
                                  : markloop::perception::testing::clutter_frame(camera, k));
    return synthetic;
  }
  for (int k = 0; k < 20; ++k) {
    const double x = 20.0 - 0.8 * k;
    synthetic.push_back(markloop::perception::testing::render_road(camera, {{3.0, 25.0, 1.7, 1.85},
                                                                            {3.0, 25.0, -1.85, -1.7},
                                                                            {x, x + 2.4, 0.5, 1.0},
                                                                            {x, x + 2.4, -0.3, 0.2},
                                                                            {x - 3, x - 0.5, -3.2, -2.4},
                                                                            {x + 4, x + 4.4, -6, 6}}));
  }
  return synthetic;
}

// What the timed frames gave: times, and each view's spread and kind.
struct Timings {
  std::vector<double> ms, cpu_ms;
  std::size_t detections = 0, candidates = 0;
  // Each timed frame's view: how much its blocks' grey varies, and that
  // against its pixels' (ViewSpread).
  std::vector<double> block_spreads, coherences;
  std::array<std::size_t, 5> views{};  // frames by ViewKind
  std::bitset<1024> cores;             // the CPUs the timed frames started on

  explicit Timings(unsigned frames) {
    ms.reserve(frames);
    cpu_ms.reserve(frames);
    block_spreads.reserve(frames);
    coherences.reserve(frames);
  }

  void time(MarkingDetector& detector, const cv::Mat& input) {
    if (const int core = sched_getcpu(); core >= 0 && core < static_cast<int>(cores.size()))
      cores.set(static_cast<std::size_t>(core));
    const double c0 = thread_cpu_ms();
    const auto t0 = std::chrono::steady_clock::now();
    detections += detector.detect(input).size();
    const auto t1 = std::chrono::steady_clock::now();
    cpu_ms.push_back(thread_cpu_ms() - c0);
    candidates += detector.candidates().size();
    const ViewSpread spread = detector.last_view_spread();
    block_spreads.push_back(spread.blocks);
    coherences.push_back(spread.pixels > 0.0f ? spread.blocks / spread.pixels : 0.0);
    ++views[static_cast<std::size_t>(detector.last_view())];
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
  }
};

// Times skip + frames frames of the file (the first `skip` untimed), or
// `frames` of the synthetic ones, cycled.
Timings time_frames(const Options& o, const CameraModel& camera, MarkingDetector& detector) {
  markloop::io::Y4mReader reader;
  std::vector<cv::Mat> synthetic;
  if (!o.y4m_path.empty()) {
    if (!reader.open(o.y4m_path, camera.width(), camera.height())) markloop::cli::fail(reader.error());
  } else {
    synthetic = synthetic_frames(camera, o.frame_source);
  }
  cv::Mat frame(camera.height(), camera.width(), CV_8UC1);
  Timings t(o.frames);
  for (unsigned i = 0; i < o.skip + o.frames; ++i) {
    const cv::Mat* input = &frame;
    if (!o.y4m_path.empty()) {
      const auto r = reader.read_frame({frame.data, frame.total()});
      if (r == markloop::io::Y4mRead::kError) markloop::cli::fail(reader.error());
      if (r == markloop::io::Y4mRead::kEnd) break;
      if (i < o.skip) continue;
    } else {
      input = &synthetic[i % synthetic.size()];
    }
    t.time(detector, *input);
  }
  if (t.ms.empty()) markloop::cli::fail("no frames timed");
  return t;
}

void print_times(const Options& o, const CameraModel& camera, const MarkingDetector& detector,
                 const Timings& t) {
  std::printf("detect() on %dx%d frames (%s), bird's-eye %dx%d, %zu frames\n", camera.width(),
              camera.height(),
              !o.y4m_path.empty()         ? o.y4m_path.c_str()
              : o.frame_source != nullptr ? o.frame_source
                                          : "synthetic",
              detector.birdseye().cols(), detector.birdseye().rows(), t.ms.size());
  std::string core_list;
  for (std::size_t core = 0; core < t.cores.size(); ++core)
    if (t.cores.test(core)) core_list += (core_list.empty() ? "" : ", ") + std::to_string(core);
  std::printf("CPU %s%s\n", core_list.c_str(),
              t.cores.count() > 1 ? " (not pinned: the cores may differ in speed; taskset -c N)" : "");
  std::printf("| time | median | p90 | p99 | max | candidates/frame | detections/frame |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|\n");
  const double frames = static_cast<double>(t.ms.size());
  std::printf("| wall | %.3f ms | %.3f ms | %.3f ms | %.3f ms | %.1f | %.2f |\n", percentile(t.ms, 0.5),
              percentile(t.ms, 0.9), percentile(t.ms, 0.99), percentile(t.ms, 1.0),
              static_cast<double>(t.candidates) / frames, static_cast<double>(t.detections) / frames);
  std::printf("| thread CPU | %.3f ms | %.3f ms | %.3f ms | %.3f ms | | |\n", percentile(t.cpu_ms, 0.5),
              percentile(t.cpu_ms, 0.9), percentile(t.cpu_ms, 0.99), percentile(t.cpu_ms, 1.0));
}

void print_views(const DetectorConfig& config, const MarkingDetector& detector, const Timings& t) {
  if (const DetectorCounters& c = detector.counters(); c.parts_dropped + c.candidates_dropped > 0)
    std::printf(
        "over the caps (a frame's %zu parts, %zu candidates), not examined: %llu parts, %llu "
        "candidates\n",
        kMaxParts, kMaxCandidates, static_cast<unsigned long long>(c.parts_dropped),
        static_cast<unsigned long long>(c.candidates_dropped));
  const auto frames_of = [&](ViewKind kind) { return t.views[static_cast<std::size_t>(kind)]; };
  std::printf(
      "views: %zu road, %zu flat, %zu noisy, %zu cluttered; blocks' grey spread min %.2f, "
      "median %.2f, max %.2f (flat below %.2f); against the pixels' min %.2f, median %.2f, "
      "max %.2f (noisy below %.2f)\n",
      frames_of(ViewKind::Road), frames_of(ViewKind::Flat), frames_of(ViewKind::Noisy),
      frames_of(ViewKind::Cluttered), percentile(t.block_spreads, 0.0), percentile(t.block_spreads, 0.5),
      percentile(t.block_spreads, 1.0), config.min_view_spread, percentile(t.coherences, 0.0),
      percentile(t.coherences, 0.5), percentile(t.coherences, 1.0), config.min_view_coherence);
  if (!config.horizon_from_lanes) return;
  const DetectorCounters& c = detector.counters();
  std::printf(
      "horizon from the lane lines: measured in %llu frames, not in %llu; view moved %llu "
      "times; now %d rows\n",
      static_cast<unsigned long long>(c.horizon_measured),
      static_cast<unsigned long long>(c.horizon_unmeasured), static_cast<unsigned long long>(c.horizon_moves),
      detector.horizon_shift());
}

}  // namespace

int main(int argc, char** argv) {
  markloop::cli::program_name() = "markloop-detector-bench";
  const Options o = parse(argc, argv);
  CameraModel camera = default_camera_model();
  DetectorConfig config;
  if (!o.camera_path.empty()) {
    const auto loaded = load_camera_model(o.camera_path);
    if (!loaded) markloop::cli::fail(loaded.message());
    camera = *loaded;
    const auto detector_config = load_detector_config(o.camera_path);
    if (!detector_config) markloop::cli::fail(detector_config.message());
    config = *detector_config;
  }
  config.horizon_from_lanes = config.horizon_from_lanes || o.horizon_from_lanes;
  MarkingDetector detector(camera, config);
  const Timings t = time_frames(o, camera, detector);
  print_times(o, camera, detector, t);
  print_views(config, detector, t);
  return markloop::cli::kExitOk;
}
