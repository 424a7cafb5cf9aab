// markloop: the ECU program. See --help and markloop.conf.
#include <cstdio>
#include <cstring>
#include <new>
#include <string>
#include <string_view>
#include <utility>

#include "app/common/cli.hpp"
#include "app/common/memory_check.hpp"
#include "app/ecu/config.hpp"
#include "app/ecu/runner.hpp"
#include "app/tools/common/tool_files.hpp"

namespace {

constexpr const char* kUsage = R"(usage: markloop [--config FILE] [options]

Recognises places and closes loops from road markings; reports every loop
detection (LoopDetection) and its health (Status) on CAN (dbc/markloop.dbc).

Live (car, HIL):  markloop --config /etc/markloop/markloop.conf
                  markloop --camera-device /dev/video0 --can-interface can0
File mode:        markloop --camera-file DIR/frames.y4m --can-in DIR/odometry.log
                           --can-out OUT.log [--calibration FILE] [--map FILE]
                           [--detections-out FILE] [--landmarks-out FILE] [--realtime]

Options (each overrides the same setting of the configuration file):
  --config FILE          key = value configuration (see markloop.conf); read first
  --camera-device DEV    V4L2 capture node (camera.device)
  --camera-file FILE     frames as YUV4MPEG2 (camera.file): file mode
  --can-interface IF     SocketCAN interface, e.g. can0 or vcan0 (can.interface)
  --can-in FILE          candump -l log to read odometry/commands from (can.in_log)
  --can-out FILE         candump -l log of every frame sent (can.out_log); in
                         file mode stamped with the recording's clock plus the
                         measured processing time
  --calibration FILE     camera calibration, OpenCV YAML (calibration); default:
                         the simulator's camera
  --map FILE             place database, loaded at start, saved at exit and on
                         command (map.file)
  --detections-out FILE  CSV of every detection (detections_out)
  --landmarks-out FILE   file mode: CSV of the landmarks the run made, written at
                         the end (landmarks_out)
  --realtime             file mode: pace frames to the recorded rate
  --first-frame N        file mode: start processing at frame N (file.first_frame)
  --frames N             file mode: process N frames (file.frames)
  --k N                  sequence length (engine.k)
  --set KEY=VALUE        any configuration key
  --summary FILE         write the run's figures as JSON
  --print-config         print the resulting configuration and exit
  --quiet                no summary on stderr
  --help                 this text

Signals: SIGTERM and SIGINT save the map and stop cleanly (exit status 0),
also while waiting for a pipe's data.
Exit status: 0 clean end; 1 a failure while running (the map, the summary or
an output could not be opened or written); 2 bad configuration or input (also
an input that turns out damaged during the run: the map is then saved as it
stood after the last whole frame). See docs/inputs-and-faults.md.
)";

// The files markloop reads and those it replaces must differ: a map or an
// output named like an input would destroy it. Empty when they do.
std::string overlapping_files(const markloop::ecu::EcuConfig& config, const std::string& summary,
                              const std::string& config_file) {
  using Role = std::pair<const char*, const std::string*>;
  const Role inputs[] = {{"--camera-file", &config.camera.file},
                         {"--can-in", &config.can.in_log},
                         {"--calibration", &config.calibration},
                         {"--config", &config_file},
                         {"--map", &config.map_file}};
  const Role outputs[] = {{"--map", &config.map_file},
                          {"--can-out", &config.can.out_log},
                          {"--detections-out", &config.detections_out},
                          {"--landmarks-out", &config.landmarks_out},
                          {"--summary", &summary}};
  for (const auto& [output_option, output] : outputs) {
    for (const auto& [input_option, input] : inputs) {
      if (output->empty() || input->empty() || output == input) continue;
      if (*output == *input || markloop::tools::overwrites(*output, *input))
        return std::string(output_option) + " " + *output + " is the file given as " + input_option +
               ": it would be overwritten";
    }
  }
  return {};
}

}  // namespace

int main(int argc, char** argv) {
  using markloop::cli::fail;
  markloop::cli::program_name() = "markloop";
  markloop::ecu::RunOptions options;
  markloop::ecu::EcuConfig& config = options.config;

  // The configuration file first, so that flags override it wherever they stand.
  std::string config_file;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (arg == "--config") {
      if (i + 1 >= argc || std::string_view(argv[i + 1]).starts_with("--"))
        fail("--config needs a value (see --help)");
      if (std::string error = markloop::ecu::load_config_file(argv[i + 1], config); !error.empty())
        fail(error);
      config_file = argv[++i];
    }
  }
  bool print_config = false;
  const auto set = [&](const char* key, const char* value) {
    if (std::string error = markloop::ecu::set_config_value(config, key, value); !error.empty()) fail(error);
  };
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--realtime") {
      config.realtime_replay = true;
      continue;
    }
    if (arg == "--print-config") {
      print_config = true;
      continue;
    }
    if (arg == "--quiet") {
      options.quiet = true;
      continue;
    }
    const char* value = markloop::cli::option_value(
        argc, argv, i,
        {"--config", "--camera-device", "--camera-file", "--can-interface", "--can-in", "--can-out",
         "--calibration", "--map", "--detections-out", "--landmarks-out", "--k", "--first-frame", "--frames",
         "--summary", "--set"});
    if (arg == "--config")
      continue;
    else if (arg == "--camera-device")
      set("camera.device", value);
    else if (arg == "--camera-file")
      set("camera.file", value);
    else if (arg == "--can-interface")
      set("can.interface", value);
    else if (arg == "--can-in")
      set("can.in_log", value);
    else if (arg == "--can-out")
      set("can.out_log", value);
    else if (arg == "--calibration")
      set("calibration", value);
    else if (arg == "--map")
      set("map.file", value);
    else if (arg == "--detections-out")
      set("detections_out", value);
    else if (arg == "--landmarks-out")
      set("landmarks_out", value);
    else if (arg == "--k")
      set("engine.k", value);
    else if (arg == "--first-frame")
      set("file.first_frame", value);
    else if (arg == "--frames")
      set("file.frames", value);
    else if (arg == "--summary")
      options.summary_json = value;
    else if (arg == "--set") {
      const char* equals = std::strchr(value, '=');
      if (equals == nullptr) fail("--set needs KEY=VALUE, got '" + std::string(value) + "'");
      if (std::string error = markloop::ecu::set_config_value(
              config, std::string_view(value, static_cast<std::size_t>(equals - value)), equals + 1);
          !error.empty())
        fail("--set: " + error);
    }
  }
  if (std::string error = markloop::ecu::validate_config(config); !error.empty()) fail(error);
  if (std::string error = overlapping_files(config, options.summary_json, config_file); !error.empty())
    fail(error);
  if (std::string error =
          markloop::cli::database_memory_error(config.engine.database, config.engine.chain.k,
                                               "database.landmark_capacity", "database.sequence_capacity");
      !error.empty())
    fail(error);
  if (print_config) {
    std::fputs(markloop::ecu::format_config(config).c_str(), stdout);
    return 0;
  }

  if (!config.calibration.empty()) {
    auto camera = markloop::perception::load_camera_model(config.calibration);
    if (!camera) fail(camera.message());
    options.camera = *camera;
    auto detector = markloop::perception::load_detector_config(config.calibration, options.detector);
    if (!detector) fail(detector.message());
    options.detector = *detector;
  }
  // The detector reports nothing under its own threshold, so a gate set
  // lower would let no more through: say so instead of ignoring it.
  if (config.gate.min_score < options.detector.min_score) {
    char text[320];
    std::snprintf(text, sizeof text,
                  "observation.min_score %g is below the detector's threshold %g (detector_min_score, %s): "
                  "nothing under it is detected; lower detector_min_score too",
                  double(config.gate.min_score), double(options.detector.min_score),
                  config.calibration.empty() ? "the built-in default" : config.calibration.c_str());
    fail(text);
  }
  try {
    return config.file_mode() ? markloop::ecu::run_file_mode(options) : markloop::ecu::run_live_mode(options);
  } catch (const std::bad_alloc&) {
    // The database's size is checked above; this is the last resort.
    fail("out of memory while starting (lower database.landmark_capacity or database.sequence_capacity)");
  }
}
