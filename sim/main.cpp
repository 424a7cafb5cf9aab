// markloop-sim: drives a car through a world of road markings and writes
// what its camera and its vehicle bus saw, in the file formats the ECU reads,
// with the ground truth next to it.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "app/common/cli.hpp"
#include "app/perception/camera_model.hpp"
#include "app/tools/common/tool_files.hpp"
#include "sim/live.hpp"
#include "sim/recorder.hpp"
#include "sim/route.hpp"
#include "sim/world.hpp"

namespace {

using namespace markloop;
using namespace markloop::sim;
using namespace markloop::cli;

constexpr const char* kUsage =
    R"(usage: markloop-sim drive (--scenario NAME | --route FILE) --out DIR [options]
       markloop-sim training-set --out DIR [--seed N] [--frames N] [--camera FILE]
       markloop-sim live --from DIR --video DEVICE [--can IF] [options]
       markloop-sim list

drive: simulate a drive and write, into DIR,
  frames.y4m     the camera's frames (YUV4MPEG2, mono, camera size, --fps);
                 frame k is at time k/fps
  odometry.log   VehicleOdometry CAN frames every 20 ms (candump -l format,
                 vcan0, E2E CRC and alive counter); time stamps are seconds
                 since the first frame: the log starts at (0000000000.000000)
  frames.csv     ground truth per frame: frame,t,x,y,yaw (world frame)
  markings.csv   the world's markings: id,class,x,y,heading
  visible.csv    per frame, the markings wholly inside the image whose centre
                 is 3..25 m ahead and not behind a vehicle:
                 frame,id,class,x1,y1,...,x4,y4 (corners in pixels: near-left,
                 near-right, far-right, far-left)
  camera.yaml    the calibration used
  markings.txt   per-frame marking observations (road_marking_centroids
                 format) and poses.txt, the drifting pose estimate (KITTI
                 3x4), for markloop-replay

options:
  --scenario NAME   built-in scenario (see "list"); default loop
  --route FILE      drive a pose file instead: one pose per line, KITTI (12
                    numbers, 10 Hz) or TUM (t x y z qx qy qz qw); the world is
                    laid along it, one set of markings per road however often
                    it is driven. A route may be up to 100 km long, its
                    successive poses up to 1 km apart, each within 100000 km
                    of the origin, and its file up to 64 MiB
  --out DIR         output folder (created if missing); required
  --seed N          seed of the world, the sensors and the conditions; default 1
  --speed M/S       driving speed, 0.1..100; default 10, or a route's own
                    average speed when it lies in 0.5..100
  --fps HZ          camera frame rate, 1..1000; default 10
  --laps N          drive a built-in scenario's lap N times (up to 1000);
                    for far, N km
  --camera FILE     calibration (OpenCV YAML, as the ECU reads); default the
                    built-in 1280x512 camera (app/cameras/sim.yaml)
  --light L         day, dusk, night or wet-glare; default day
  --wear W          worst paint wear 0..1; default 0.35
  --no-shadows      no tree or building shadows
  --occluders P     share of 12 s windows with a vehicle ahead; default 0.3
  --noise SIGMA     sensor noise in grey levels; default 2
  --drift X         scale of the odometry errors (wheel-speed scale error,
                    yaw-rate bias and noise) behind the dead-reckoned pose's
                    drift; 0 = perfect odometry; default 1
  --class-weights LIST  NAME=W,... relative frequency of the marking classes
  --no-render       no frames.y4m / visible.csv (fast, for long drives)
  --max-frames N    stop after N frames
  --cover-lens FROM:TO  the camera's lens covered from FROM until TO seconds
                    into the drive: black frames with the sensor's noise, no
                    marking visible
  --help            this text

training-set: images/NNNNNN.png and annotations.csv (image,label,x1,y1,...,
  x4,y4, as the roadmarks dataset) and camera.yaml: --frames whole frames
  (default 200) of a world of its own, every class equally often, random
  light, wear, noise and vehicles; seeds are the given seed + 2^32, so never
  a drive's.

live: play a recorded drive (DIR from "drive": frames.y4m, odometry.log) in
  real time into devices, for hardware-in-the-loop tests: every frame into a
  V4L2 output node at the drive's frame rate (vivid's output, looped back to
  its capture node for the ECU) and the odometry onto a CAN interface, each
  at its absolute deadline since the start.
  --from DIR        the recorded drive; required
  --video DEVICE    V4L2 output device, e.g. /dev/video1; required
  --output N        VIDIOC_S_OUTPUT index (default: keep the current one)
  --format F        grey or yuyv (neutral chroma); default grey
  --can IF          SocketCAN interface for the odometry, e.g. vcan0
  --max-frames N    stop after N frames
  Ends at the end of the drive or on SIGINT/SIGTERM and prints its counters.
  odometry.log is read whole before the clock starts, up to 256 MiB.

Exit status: 0 on success; 1 when an output cannot be written, or (live) a
frame or CAN frame could not be sent; 2 on bad options or input, or a device
that cannot be opened.
)";

// The options of each command. The help text (kUsage) is written by hand:
// its option lines wrap and group in ways one line per option cannot.
constexpr OptionSpec kDriveOptions[] = {
    {"--scenario", "NAME", "built-in scenario (see \"list\"); default loop"},
    {"--route", "FILE", "drive a pose file (KITTI or TUM) instead"},
    {"--out", "DIR", "output folder (created if missing); required"},
    {"--seed", "N", "seed of the world, the sensors and the conditions; default 1"},
    {"--speed", "M/S", "driving speed, 0.1..100; default 10"},
    {"--fps", "HZ", "camera frame rate, 1..1000; default 10"},
    {"--laps", "N", "drive a built-in scenario's lap N times (up to 1000)"},
    {"--camera", "FILE", "calibration (OpenCV YAML); default the built-in camera"},
    {"--max-frames", "N", "stop after N frames"},
    {"--occluders", "P", "share of 12 s windows with a vehicle ahead; default 0.3"},
    {"--noise", "SIGMA", "sensor noise in grey levels; default 2"},
    {"--wear", "W", "worst paint wear 0..1; default 0.35"},
    {"--drift", "X", "scale of the odometry errors; default 1"},
    {"--light", "L", "day, dusk, night or wet-glare; default day"},
    {"--class-weights", "LIST", "NAME=W,... relative frequency of the marking classes"},
    {"--cover-lens", "FROM:TO", "the camera's lens covered from FROM until TO seconds"},
    {"--no-shadows", "", "no tree or building shadows"},
    {"--no-render", "", "no frames.y4m / visible.csv (fast, for long drives)"},
};

constexpr OptionSpec kTrainingSetOptions[] = {
    {"--out", "DIR", "output folder (created if missing); required"},
    {"--seed", "N", "seed; default 1"},
    {"--frames", "N", "whole frames; default 200"},
    {"--camera", "FILE", "calibration (OpenCV YAML); default the built-in camera"},
};

constexpr OptionSpec kLiveOptions[] = {
    {"--from", "DIR", "the recorded drive; required"},
    {"--video", "DEVICE", "V4L2 output device, e.g. /dev/video1; required"},
    {"--output", "N", "VIDIOC_S_OUTPUT index (default: keep the current one)"},
    {"--can", "IF", "SocketCAN interface for the odometry, e.g. vcan0"},
    {"--max-frames", "N", "stop after N frames"},
    {"--format", "F", "grey or yuyv (neutral chroma); default grey"},
};

// A command's options: argv[1] is the command, its options follow.
ParsedArgs parse_command(int argc, char** argv, std::span<const OptionSpec> options) {
  return parse_args_or_fail(argc - 1, argv + 1, options);
}

// A value given with an option: a NUL-terminated argument of main's.
const char* text_of(std::string_view value) {
  return value.data();
}

perception::CameraModel camera_from(const std::string& path) {
  if (path.empty()) return perception::default_camera_model();
  auto model = perception::load_camera_model(path);
  if (!model) fail(model.message());
  return *model;
}

// --out names a folder (made when missing); anything else there is a
// mistake on the command line, refused before the drive.
void check_out_dir(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (std::filesystem::exists(status) && !std::filesystem::is_directory(status))
    fail(path + ": not a directory (--out DIR: a folder, made when missing)");
}

// What `drive` was asked for.
struct DriveRequest {
  std::string scenario_name, route_file, out_dir, camera_file;
  RecordOptions options;
  std::optional<double> speed;
  std::optional<unsigned> laps;
  WorldConfig world;
  double drift = 1.0;
};

void apply_cover_lens(std::string_view option, const char* value, RecordOptions& options) {
  const std::string span = value;
  const std::size_t colon = span.find(':');
  if (colon == std::string::npos) fail("--cover-lens: expected FROM:TO (seconds), got '" + span + "'");
  options.lens_covered_from_s = parse_number(option, span.substr(0, colon).c_str());
  options.lens_covered_until_s = parse_number(option, span.substr(colon + 1).c_str());
  if (options.lens_covered_from_s < 0 || options.lens_covered_until_s <= options.lens_covered_from_s)
    fail("--cover-lens: expected 0 <= FROM < TO, got '" + span + "'");
}

void apply_light(const char* value, Conditions& conditions) {
  const auto light = illumination_from_name(value);
  if (!light) fail(std::string("--light: unknown '") + value + "' (day, dusk, night, wet-glare)");
  conditions.light = *light;
}

void apply_class_weights(const char* value, WorldConfig& world) {
  const Result<std::array<double, kClassCount>> weights = parse_class_weights(value);
  if (!weights) fail("--class-weights: " + weights.message());
  world.class_weights = *weights;
}

// One option of `drive`, as given; bad values fail.
void apply_drive_option(std::string_view arg, const char* value, DriveRequest& r) {
  RecordOptions& o = r.options;
  if (arg == "--no-shadows")
    o.conditions.shadows = false;
  else if (arg == "--no-render")
    o.render = false;
  else if (arg == "--scenario")
    r.scenario_name = value;
  else if (arg == "--route")
    r.route_file = value;
  else if (arg == "--out")
    r.out_dir = value;
  else if (arg == "--seed")
    o.seed = parse_whole(arg, value);
  else if (arg == "--speed")
    r.speed = parse_number(arg, value);
  else if (arg == "--fps")
    o.drive.fps = parse_number(arg, value);
  else if (arg == "--laps")
    r.laps = parse_whole(arg, value);
  else if (arg == "--camera")
    r.camera_file = value;
  else if (arg == "--max-frames")
    o.max_frames = parse_whole(arg, value);
  else if (arg == "--occluders")
    o.conditions.occluder_probability = parse_number(arg, value);
  else if (arg == "--noise")
    o.conditions.noise_sigma = parse_number(arg, value);
  else if (arg == "--wear")
    o.conditions.paint_wear = parse_number(arg, value);
  else if (arg == "--drift")
    r.drift = parse_number(arg, value);
  else if (arg == "--cover-lens")
    apply_cover_lens(arg, value, o);
  else if (arg == "--light")
    apply_light(value, o.conditions);
  else if (arg == "--class-weights")
    apply_class_weights(value, r.world);
}

// Refuses a drive request whose values are out of range, before the drive.
void check_drive_request(const DriveRequest& r) {
  const RecordOptions& o = r.options;
  if (r.out_dir.empty()) fail("--out DIR is required (see --help)");
  check_out_dir(r.out_dir);
  if (!r.scenario_name.empty() && !r.route_file.empty()) fail("give --scenario or --route, not both");
  if (r.speed && !(*r.speed >= 0.1 && *r.speed <= 100)) fail("--speed must be in 0.1..100 m/s");
  if (!(o.drive.fps >= 1 && o.drive.fps <= 1000)) fail("--fps must be in 1..1000");
  if (r.laps && (*r.laps == 0 || *r.laps > 1000)) fail("--laps must be in 1..1000");
  if (o.conditions.paint_wear < 0 || o.conditions.paint_wear > 1) fail("--wear must be in 0..1");
  if (o.conditions.occluder_probability < 0 || o.conditions.occluder_probability > 1)
    fail("--occluders must be in 0..1");
  if (o.conditions.noise_sigma < 0 || o.conditions.noise_sigma > 100) fail("--noise must be in 0..100");
  if (r.drift < 0 || r.drift > 100) fail("--drift must be in 0..100");
}

// The same errors drive the CAN odometry and the legacy dead-reckoned pose.
void scale_odometry_errors(double drift, RecordOptions& options) {
  options.drive.speed_scale_error *= drift;
  options.drive.yaw_rate_bias_dps *= drift;
  options.drive.yaw_rate_noise_dps *= drift;
  options.odometry.speed_scale_error *= drift;
  options.odometry.speed_noise_mps *= drift;
  options.odometry.yaw_rate_bias_dps *= drift;
  options.odometry.yaw_rate_noise_dps *= drift;
}

// The scenario a drive request names: a route file's, or a built-in one.
// A route sets the speed when none was given and its own is plausible.
Scenario scenario_for(DriveRequest& r) {
  if (!r.route_file.empty()) {
    Result<Route> route = load_route(r.route_file);
    if (!route) fail(route.message());
    const double route_speed = route->average_speed_mps();
    if (!r.speed && route_speed > 0.5 && route_speed <= 100) r.speed = route_speed;
    Scenario scenario = make_route_scenario(r.route_file, std::move(route->path), r.options.seed, r.world);
    if (r.laps) fail("--laps applies to built-in scenarios only");
    return scenario;
  }
  if (r.scenario_name.empty()) r.scenario_name = "loop";
  // "far" never comes back: its --laps is its length in km.
  const bool laps_are_km = r.scenario_name == "far";
  if (laps_are_km && r.laps) r.world.route_km = *r.laps;
  std::optional<Scenario> scenario = make_scenario(r.scenario_name, r.options.seed, r.world);
  if (!scenario) fail("unknown scenario '" + r.scenario_name + "' (see: markloop-sim list)");
  if (r.laps && !laps_are_km) scenario->laps = static_cast<int>(*r.laps);
  return std::move(*scenario);
}

void print_drive_summary(const Scenario& scenario, const RecordOptions& options,
                         const RecordSummary& summary) {
  std::printf(
      "markloop-sim: %s (%s): %zu frames, %zu markings in the world, %zu detections, "
      "%zu odometry frames",
      scenario.name.c_str(), scenario.description.c_str(), summary.frames, scenario.markings.size(),
      summary.detections, summary.odometry_messages);
  if (options.render && summary.frames > 0)
    std::printf(", %zu visible markings, %.1f ms per rendered frame", summary.visible_rows,
                1000.0 * summary.render_seconds / static_cast<double>(summary.frames));
  std::printf(" -> %s\n", options.out_dir.c_str());
}

int drive(int argc, char** argv) {
  const ParsedArgs args = parse_command(argc, argv, kDriveOptions);
  if (args.help()) {
    std::fputs(kUsage, stdout);
    return kExitOk;
  }
  DriveRequest request;
  for (const ParsedArgs::Given& given : args.given())
    apply_drive_option(given.name, text_of(given.value), request);
  check_drive_request(request);
  RecordOptions& options = request.options;
  scale_odometry_errors(request.drift, options);
  const Scenario scenario = scenario_for(request);
  options.drive.speed_mps = request.speed.value_or(10.0);
  options.out_dir = request.out_dir;
  options.conditions.seed = options.seed * 0x9E3779B97F4A7C15ULL + 0xC0D1;
  const perception::CameraModel camera = camera_from(request.camera_file);

  const Result<RecordSummary> summary = record_drive(scenario, camera, options);
  if (!summary) tools::fail_run(summary.message());
  print_drive_summary(scenario, options, *summary);
  return kExitOk;
}

int training_set(int argc, char** argv) {
  const ParsedArgs args = parse_command(argc, argv, kTrainingSetOptions);
  if (args.help()) {
    std::fputs(kUsage, stdout);
    return kExitOk;
  }
  TrainingSetOptions options;
  std::string camera_file;
  for (const auto& [arg, given] : args.given()) {
    const char* value = text_of(given);
    if (arg == "--out")
      options.out_dir = value;
    else if (arg == "--seed")
      options.seed = parse_whole(arg, value);
    else if (arg == "--frames")
      options.frames = parse_whole(arg, value);
    else if (arg == "--camera")
      camera_file = value;
  }
  if (options.out_dir.empty()) fail("--out DIR is required (see --help)");
  check_out_dir(options.out_dir);
  if (options.frames == 0) fail("--frames must be at least 1");
  const perception::CameraModel camera = camera_from(camera_file);
  const Result<std::size_t> annotations = record_training_set(camera, options);
  if (!annotations) tools::fail_run(annotations.message());
  std::printf("markloop-sim: training set: %zu images, %zu annotated markings -> %s\n", options.frames,
              *annotations, options.out_dir.c_str());
  return kExitOk;
}

v4l2::PixelFormat pixel_format_from(const char* value) {
  const std::string_view f = value;
  if (f == "grey") return v4l2::PixelFormat::Grey;
  if (f == "yuyv") return v4l2::PixelFormat::Yuyv;
  fail(std::string("--format: unknown '") + value + "' (grey, yuyv)");
}

LiveOptions live_options_from(const ParsedArgs& args) {
  LiveOptions options;
  for (const auto& [arg, given] : args.given()) {
    const char* value = text_of(given);
    if (arg == "--from")
      options.drive_dir = value;
    else if (arg == "--video")
      options.video_device = value;
    else if (arg == "--output")
      options.video_output = static_cast<int>(parse_whole(arg, value));
    else if (arg == "--can")
      options.can_interface = value;
    else if (arg == "--max-frames")
      options.max_frames = parse_whole(arg, value);
    else if (arg == "--format")
      options.format = pixel_format_from(value);
  }
  if (options.drive_dir.empty()) fail("--from DIR is required (see --help)");
  if (options.video_device.empty()) fail("--video DEVICE is required (see --help)");
  return options;
}

int live(int argc, char** argv) {
  const ParsedArgs args = parse_command(argc, argv, kLiveOptions);
  if (args.help()) {
    std::fputs(kUsage, stdout);
    return kExitOk;
  }
  const Result<LiveCounters> played = run_live(live_options_from(args));
  if (!played) fail(played.message());
  const LiveCounters& counters = *played;
  std::printf(
      "markloop-sim: live: %llu frames sent (%llu failed), %llu CAN frames sent (%llu failed), "
      "%llu events late by more than 5 ms, worst %.2f ms%s\n",
      static_cast<unsigned long long>(counters.frames_sent),
      static_cast<unsigned long long>(counters.frame_errors),
      static_cast<unsigned long long>(counters.can_sent),
      static_cast<unsigned long long>(counters.can_errors),
      static_cast<unsigned long long>(counters.late_events), counters.max_lateness_ms,
      counters.interrupted ? " (interrupted)" : "");
  return counters.frame_errors == 0 && counters.can_errors == 0 ? kExitOk : kExitOutputFailed;
}

int list_scenarios() {
  for (const auto& name : scenario_names()) {
    const auto s = make_scenario(name, 1);
    std::printf("%-9s %s\n", name.c_str(), s->description.c_str());
  }
  return kExitOk;
}

int run(int argc, char** argv) {
  const std::string_view command = argc > 1 ? argv[1] : "";
  if (command == "drive") return drive(argc, argv);
  if (command == "training-set") return training_set(argc, argv);
  if (command == "live") return live(argc, argv);
  if (command == "list") return list_scenarios();
  if (command == "--help" || command == "-h" || command == "help") {
    std::fputs(kUsage, stdout);
    return kExitOk;
  }
  if (command.empty()) {
    std::fputs(kUsage, stderr);
    return kExitBadInput;
  }
  fail("unknown command '" + std::string(command) + "' (drive, training-set, live or list; see --help)");
}

}  // namespace

int main(int argc, char** argv) {
  program_name() = "markloop-sim";
  const int status = run(argc, argv);
  if (const Status flushed = tools::flush_stdout(); !flushed) tools::fail_run(flushed.message());
  return status;
}
