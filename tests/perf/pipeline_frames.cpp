// Runs N frames of one per-frame pipeline stage and nothing else worth
// counting, for instruction counts under emulation
// (tests/perf/instruction-counts.sh). Everything a stage needs is prepared
// before the first frame and does not depend on N, so the difference between
// two runs with different N is the cost of the extra frames alone.
//
//   markloop-pipeline-frames --stage engine|perception --frames N
#include <cstdio>
#include <cstring>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "app/common/cli.hpp"
#include "app/engine/sequence_engine.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/marking_detector.hpp"
#include "sim/drive.hpp"
#include "sim/world.hpp"

namespace {

using namespace markloop;

constexpr const char* kUsage =
    "usage: markloop-pipeline-frames --stage STAGE --frames N\n"
    "Runs N frames of one pipeline stage (prepared beforehand, independent of N).\n"
    "  --stage engine      the sequence engine on the simulated ring drive (seed 1);\n"
    "                      frames past the end of the drive repeat it, later in time\n"
    "  --stage perception  the marking detector on synthetic grey frames of the\n"
    "                      default camera (1280x512): road, painted blocks, a lane line\n"
    "  --frames N       number of frames to process (0 allowed)\n"
    "Prints the number of frames and a checksum of the stage's output.\n";

struct CountingSink final : MatchSink {
  std::size_t matches = 0;
  void on_match(const MatchEvent&) override { ++matches; }
};

int run_engine(unsigned frames) {
  const auto scenario = sim::make_scenario("ring", 1);
  if (!scenario) cli::fail("the simulator has no 'ring' scenario");
  sim::Drive drive(*scenario, sim::DriveConfig{}, 2);
  std::vector<sim::DriveFrame> drive_frames;
  sim::DriveFrame frame;
  while (drive.next(frame)) drive_frames.push_back(frame);
  if (drive_frames.empty()) cli::fail("the ring drive has no frames");

  EngineConfig config;
  config.database.sequence_capacity = 1 << 16;
  config.database.landmark_capacity = 1 << 14;
  auto engine = std::make_unique<SequenceEngine>(config);
  CountingSink sink;
  double lap_offset = 0.0;
  std::size_t i = 0;
  for (unsigned n = 0; n < frames; ++n) {
    const sim::DriveFrame& f = drive_frames[i];
    FrameInput input = f.estimate;
    input.frame = n;
    input.t += lap_offset;
    engine->process_frame(input, f.observations, sink);
    if (++i == drive_frames.size()) {  // drive the ring again, later
      i = 0;
      lap_offset = input.t + 1.0;
    }
  }
  std::printf("stage engine: %u frames, %zu matches\n", frames, sink.matches);
  return 0;
}

int run_perception(unsigned frames) {
  const perception::CameraModel camera = perception::default_camera_model();
  perception::MarkingDetector detector(camera);
  // Eight different frames, cycled (the same synthetic road as the ECU's
  // allocation test): road grey, painted bars and blocks, a lane line.
  std::vector<cv::Mat> images;
  for (int i = 0; i < 8; ++i) {
    cv::Mat grey(camera.height(), camera.width(), CV_8UC1, cv::Scalar(70));
    for (int j = 0; j < 6; ++j) {
      const int x = 100 + ((i * 7 + j * 13) % 10) * 100, y = 300 + ((i + j) % 4) * 45;
      cv::rectangle(grey, cv::Rect(x, y, 40 + 10 * j, 15 + 5 * (i % 3)), cv::Scalar(220), cv::FILLED);
    }
    cv::line(grey, {640, camera.height() - 1}, {600, 260}, cv::Scalar(230), 6);
    images.push_back(grey);
  }
  std::size_t detections = 0;
  for (unsigned n = 0; n < frames; ++n) detections += detector.detect(images[n % images.size()]).size();
  std::printf("stage perception: %u frames of %dx%d, %zu detections\n", frames, camera.width(),
              camera.height(), detections);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  cli::program_name() = "markloop-pipeline-frames";
  static constexpr cli::OptionSpec kOptions[] = {
      {"--stage", "STAGE", "engine or perception"},
      {"--frames", "N", "number of frames to process (0 allowed)"},
  };
  const cli::ParsedArgs args = cli::parse_args_or_fail(argc, argv, kOptions);
  std::string stage;
  long frames = -1;
  for (const cli::ParsedArgs::Given& given : args.given()) {
    if (given.name == "--stage") stage = given.value;
    if (given.name == "--frames") frames = cli::parse_whole("--frames", std::string(given.value).c_str());
  }
  if (args.help()) {
    std::fputs(kUsage, stdout);
    return cli::kExitOk;
  }
  if (stage.empty()) cli::fail("--stage is required (see --help)");
  if (frames < 0) cli::fail("--frames is required (see --help)");
  if (stage == "engine") return run_engine(static_cast<unsigned>(frames));
  if (stage == "perception") return run_perception(static_cast<unsigned>(frames));
  cli::fail("unknown stage '" + stage + "' (see --help)");
}
