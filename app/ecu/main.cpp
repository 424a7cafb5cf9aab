// markloop: the ECU program. See --help and markloop.conf.
#include <cstdio>
#include <new>
#include <string>
#include <string_view>
#include <utility>

#include "app/common/cli.hpp"
#include "app/common/memory_check.hpp"
#include "app/ecu/config.hpp"
#include "app/ecu/runner.hpp"
#include "app/ecu/settings.hpp"
#include "platform/files.hpp"

namespace {

// The --help text around the option lines, which come from kOptions.
constexpr const char* kUsageHead = R"(usage: markloop [--config FILE] [options]

Recognises places and closes loops from road markings; reports every loop
detection (LoopDetection) and its health (Status) on CAN (dbc/markloop.dbc).

Live (car, HIL):  markloop --config /etc/markloop/markloop.conf
                  markloop --camera-device /dev/video0 --can-interface can0
File mode:        markloop --camera-file DIR/frames.y4m --can-in DIR/odometry.log
                           --can-out OUT.log [--calibration FILE] [--map FILE]
                           [--detections-out FILE] [--landmarks-out FILE] [--realtime]

Options (each overrides the same setting of the configuration file):
)";

constexpr const char* kUsageTail = R"(
Signals: SIGTERM and SIGINT save the map and stop cleanly (exit status 0),
also while waiting for a pipe's data.
Exit status: 0 clean end; 1 a failure while running (the map, the summary or
an output could not be opened or written); 2 bad configuration or input (also
an input that turns out damaged during the run: the map is then saved as it
stood after the last whole frame). See docs/inputs-and-faults.md.
)";

// The options; a help text's further lines start at the column the option
// lines align to. An option that sets a key is named in the key's row of
// settings.cpp (a flag among them sets it to true).
constexpr markloop::cli::OptionSpec kOptions[] = {
    {"--config", "FILE", "key = value configuration (see markloop.conf); read first"},
    {"--camera-device", "DEV", "V4L2 capture node (camera.device)"},
    {"--camera-file", "FILE", "frames as YUV4MPEG2 (camera.file): file mode"},
    {"--can-interface", "IF", "SocketCAN interface, e.g. can0 or vcan0 (can.interface)"},
    {"--can-in", "FILE", "candump -l log to read odometry/commands from (can.in_log)"},
    {"--can-out", "FILE",
     "candump -l log of every frame sent (can.out_log); in\n"
     "                         file mode stamped with the recording's clock plus the\n"
     "                         measured processing time"},
    {"--calibration", "FILE",
     "camera calibration, OpenCV YAML (calibration); default:\n"
     "                         the simulator's camera"},
    {"--map", "FILE",
     "place database, loaded at start, saved at exit and on\n"
     "                         command (map.file)"},
    {"--detections-out", "FILE", "CSV of every detection (detections_out)"},
    {"--landmarks-out", "FILE",
     "file mode: CSV of the landmarks the run made, written at\n"
     "                         the end (landmarks_out)"},
    {"--realtime", "", "file mode: pace frames to the recorded rate"},
    {"--first-frame", "N", "file mode: start processing at frame N (file.first_frame)"},
    {"--frames", "N", "file mode: process N frames (file.frames)"},
    {"--k", "N", "sequence length (engine.k)"},
    {"--set", "KEY=VALUE", "any configuration key"},
    {"--summary", "FILE", "write the run's figures as JSON"},
    {"--print-config", "", "print the resulting configuration and exit"},
    {"--quiet", "", "no summary on stderr"},
    {"--help", "", "this text"},
};

// The files markloop reads and those it replaces must differ: a map or an
// output named like an input would destroy it.
markloop::Status check_files_differ(const markloop::ecu::EcuConfig& config, const std::string& summary,
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
      if (*output == *input || markloop::platform::overwrites(*output, *input))
        return markloop::error(std::string(output_option) + " " + *output + " is the file given as " +
                               input_option + ": it would be overwritten");
    }
  }
  return {};
}

void fail_on(const markloop::Status& status) {
  if (!status) markloop::cli::fail(status.message());
}

// Every --config file in the order given, before any other option so that
// those override it wherever they stand. Returns the last one's name.
std::string apply_config_files(const markloop::cli::ParsedArgs& args, markloop::ecu::EcuConfig& config) {
  std::string config_file;
  for (const auto& [name, value] : args.given()) {
    if (name != "--config") continue;
    config_file = std::string(value);
    fail_on(markloop::ecu::load_config_file(config_file, config));
  }
  return config_file;
}

// --set KEY=VALUE.
void apply_assignment(std::string_view assignment, markloop::ecu::EcuConfig& config) {
  const std::size_t equals = assignment.find('=');
  if (equals == std::string_view::npos)
    markloop::cli::fail("--set needs KEY=VALUE, got '" + std::string(assignment) + "'");
  const markloop::Status status =
      markloop::ecu::set_config_value(config, assignment.substr(0, equals), assignment.substr(equals + 1));
  if (!status) markloop::cli::fail("--set: " + status.message());
}

// The other options in the order given: each overrides the file and the
// options before it.
void apply_options(const markloop::cli::ParsedArgs& args, markloop::ecu::RunOptions& options) {
  for (const auto& [name, value] : args.given()) {
    if (name == "--set") {
      apply_assignment(value, options.config);
    } else if (name == "--summary") {
      options.summary_json = std::string(value);
    } else if (name == "--quiet") {
      options.quiet = true;
    } else if (const markloop::ecu::Setting* setting = markloop::ecu::find_setting_by_flag(name)) {
      const std::string_view text = setting->kind == markloop::ecu::SettingKind::kBool ? "true" : value;
      fail_on(markloop::ecu::set_config_value(options.config, setting->key, text));
    }
  }
}

// What can be checked before any file but the configuration is read.
void check_configuration(const markloop::ecu::RunOptions& options, const std::string& config_file) {
  const markloop::ecu::EcuConfig& config = options.config;
  fail_on(markloop::ecu::validate_config(config));
  fail_on(check_files_differ(config, options.summary_json, config_file));
  if (std::string error =
          markloop::cli::database_memory_error(config.engine.database, config.engine.chain.k,
                                               "database.landmark_capacity", "database.sequence_capacity");
      !error.empty())
    markloop::cli::fail(error);
}

void load_calibration(markloop::ecu::RunOptions& options) {
  const std::string& path = options.config.calibration;
  if (path.empty()) return;
  auto camera = markloop::perception::load_camera_model(path);
  if (!camera) markloop::cli::fail(camera.message());
  options.camera = *camera;
  auto detector = markloop::perception::load_detector_config(path, options.detector);
  if (!detector) markloop::cli::fail(detector.message());
  options.detector = *detector;
}

// The detector reports nothing under its own threshold, so a gate set lower
// would let no more through: say so instead of ignoring it.
void check_observation_gate(const markloop::ecu::RunOptions& options) {
  const markloop::ecu::EcuConfig& config = options.config;
  if (config.gate.min_score >= options.detector.min_score) return;
  char text[320];
  std::snprintf(text, sizeof text,
                "observation.min_score %g is below the detector's threshold %g (detector_min_score, %s): "
                "nothing under it is detected; lower detector_min_score too",
                double(config.gate.min_score), double(options.detector.min_score),
                config.calibration.empty() ? "the built-in default" : config.calibration.c_str());
  markloop::cli::fail(text);
}

int run(const markloop::ecu::RunOptions& options) {
  try {
    return options.config.file_mode() ? markloop::ecu::run_file_mode(options)
                                      : markloop::ecu::run_live_mode(options);
  } catch (const std::bad_alloc&) {
    // The database's size is checked before; this is the last resort.
    markloop::cli::fail(
        "out of memory while starting (lower database.landmark_capacity or database.sequence_capacity)");
  }
}

}  // namespace

int main(int argc, char** argv) {
  markloop::cli::program_name() = "markloop";
  const markloop::cli::ParsedArgs args = markloop::cli::parse_args_or_fail(argc, argv, kOptions);
  if (args.help()) {
    std::fputs(kUsageHead, stdout);
    std::fputs(markloop::cli::options_help(kOptions).c_str(), stdout);
    std::fputs(kUsageTail, stdout);
    return markloop::cli::kExitOk;
  }
  markloop::ecu::RunOptions options;
  const std::string config_file = apply_config_files(args, options.config);
  apply_options(args, options);
  check_configuration(options, config_file);
  if (args.has("--print-config")) {
    std::fputs(markloop::ecu::format_config(options.config).c_str(), stdout);
    return markloop::cli::kExitOk;
  }
  load_calibration(options);
  check_observation_gate(options);
  return run(options);
}
