// markloop-sim: drives a car through a world of road markings and writes
// what its camera and its vehicle bus saw, in the file formats the ECU reads,
// with the ground truth next to it.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
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
  --laps N          drive a built-in scenario's lap N times (up to 1000)
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

int drive(int argc, char** argv) {
  std::string scenario_name, route_file, out_dir, camera_file;
  RecordOptions options;
  std::optional<double> speed;
  std::optional<unsigned> laps;
  WorldConfig world;
  double drift = 1.0;
  for (int i = 2; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (arg == "--no-shadows") {
      options.conditions.shadows = false;
      continue;
    }
    if (arg == "--no-render") {
      options.render = false;
      continue;
    }
    const char* value = option_value(
        argc, argv, i,
        {"--scenario", "--route", "--out", "--seed", "--speed", "--fps", "--laps", "--camera", "--max-frames",
         "--occluders", "--noise", "--wear", "--drift", "--light", "--class-weights", "--cover-lens"});
    if (arg == "--scenario")
      scenario_name = value;
    else if (arg == "--route")
      route_file = value;
    else if (arg == "--out")
      out_dir = value;
    else if (arg == "--seed")
      options.seed = parse_whole(arg, value);
    else if (arg == "--speed")
      speed = parse_number(arg, value);
    else if (arg == "--fps")
      options.drive.fps = parse_number(arg, value);
    else if (arg == "--laps")
      laps = parse_whole(arg, value);
    else if (arg == "--camera")
      camera_file = value;
    else if (arg == "--max-frames")
      options.max_frames = parse_whole(arg, value);
    else if (arg == "--occluders")
      options.conditions.occluder_probability = parse_number(arg, value);
    else if (arg == "--noise")
      options.conditions.noise_sigma = parse_number(arg, value);
    else if (arg == "--wear")
      options.conditions.paint_wear = parse_number(arg, value);
    else if (arg == "--drift")
      drift = parse_number(arg, value);
    else if (arg == "--cover-lens") {
      const std::string span = value;
      const std::size_t colon = span.find(':');
      if (colon == std::string::npos) fail("--cover-lens: expected FROM:TO (seconds), got '" + span + "'");
      options.lens_covered_from_s = parse_number(arg, span.substr(0, colon).c_str());
      options.lens_covered_until_s = parse_number(arg, span.substr(colon + 1).c_str());
      if (options.lens_covered_from_s < 0 || options.lens_covered_until_s <= options.lens_covered_from_s)
        fail("--cover-lens: expected 0 <= FROM < TO, got '" + span + "'");
    } else if (arg == "--light") {
      const auto light = illumination_from_name(value);
      if (!light) fail(std::string("--light: unknown '") + value + "' (day, dusk, night, wet-glare)");
      options.conditions.light = *light;
    } else if (arg == "--class-weights") {
      std::array<double, kClassCount> weights{};
      std::string error;
      if (!parse_class_weights(value, weights, error)) fail("--class-weights: " + error);
      world.class_weights = weights;
    }
  }
  if (out_dir.empty()) fail("--out DIR is required (see --help)");
  check_out_dir(out_dir);
  if (!scenario_name.empty() && !route_file.empty()) fail("give --scenario or --route, not both");
  if (speed && !(*speed >= 0.1 && *speed <= 100)) fail("--speed must be in 0.1..100 m/s");
  if (!(options.drive.fps >= 1 && options.drive.fps <= 1000)) fail("--fps must be in 1..1000");
  if (laps && (*laps == 0 || *laps > 1000)) fail("--laps must be in 1..1000");
  if (options.conditions.paint_wear < 0 || options.conditions.paint_wear > 1) fail("--wear must be in 0..1");
  if (options.conditions.occluder_probability < 0 || options.conditions.occluder_probability > 1)
    fail("--occluders must be in 0..1");
  if (options.conditions.noise_sigma < 0 || options.conditions.noise_sigma > 100)
    fail("--noise must be in 0..100");
  if (drift < 0 || drift > 100) fail("--drift must be in 0..100");
  // The same errors drive the CAN odometry and the legacy dead-reckoned pose.
  options.drive.speed_scale_error *= drift;
  options.drive.yaw_rate_bias_dps *= drift;
  options.drive.yaw_rate_noise_dps *= drift;
  options.odometry.speed_scale_error *= drift;
  options.odometry.speed_noise_mps *= drift;
  options.odometry.yaw_rate_bias_dps *= drift;
  options.odometry.yaw_rate_noise_dps *= drift;

  std::optional<Scenario> scenario;
  if (!route_file.empty()) {
    std::string error;
    auto route = load_route(route_file, error);
    if (!route) fail(error);
    const double route_speed = route->average_speed_mps();
    if (!speed && route_speed > 0.5 && route_speed <= 100) speed = route_speed;
    scenario = make_route_scenario(route_file, std::move(route->path), options.seed, world);
    if (laps) fail("--laps applies to built-in scenarios only");
  } else {
    if (scenario_name.empty()) scenario_name = "loop";
    scenario = make_scenario(scenario_name, options.seed, world);
    if (!scenario) fail("unknown scenario '" + scenario_name + "' (see: markloop-sim list)");
    if (laps) scenario->laps = static_cast<int>(*laps);
  }
  options.drive.speed_mps = speed.value_or(10.0);
  options.out_dir = out_dir;
  options.conditions.seed = options.seed * 0x9E3779B97F4A7C15ULL + 0xC0D1;
  const perception::CameraModel camera = camera_from(camera_file);

  RecordSummary summary;
  std::string error;
  if (!record_drive(*scenario, camera, options, summary, error)) tools::fail_run(error);
  std::printf(
      "markloop-sim: %s (%s): %zu frames, %zu markings in the world, %zu detections, "
      "%zu odometry frames",
      scenario->name.c_str(), scenario->description.c_str(), summary.frames, scenario->markings.size(),
      summary.detections, summary.odometry_messages);
  if (options.render && summary.frames > 0)
    std::printf(", %zu visible markings, %.1f ms per rendered frame", summary.visible_rows,
                1000.0 * summary.render_seconds / static_cast<double>(summary.frames));
  std::printf(" -> %s\n", out_dir.c_str());
  return 0;
}

int training_set(int argc, char** argv) {
  TrainingSetOptions options;
  std::string camera_file;
  for (int i = 2; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    const char* value = option_value(argc, argv, i, {"--out", "--seed", "--frames", "--camera"});
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
  std::size_t annotations = 0;
  std::string error;
  if (!record_training_set(camera, options, annotations, error)) tools::fail_run(error);
  std::printf("markloop-sim: training set: %zu images, %zu annotated markings -> %s\n", options.frames,
              annotations, options.out_dir.c_str());
  return 0;
}

int live(int argc, char** argv) {
  LiveOptions options;
  for (int i = 2; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    const char* value =
        option_value(argc, argv, i, {"--from", "--video", "--output", "--can", "--max-frames", "--format"});
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
    else if (arg == "--format") {
      const std::string_view f = value;
      if (f == "grey")
        options.format = v4l2::PixelFormat::Grey;
      else if (f == "yuyv")
        options.format = v4l2::PixelFormat::Yuyv;
      else
        fail(std::string("--format: unknown '") + value + "' (grey, yuyv)");
    }
  }
  if (options.drive_dir.empty()) fail("--from DIR is required (see --help)");
  if (options.video_device.empty()) fail("--video DEVICE is required (see --help)");
  LiveCounters counters;
  std::string error;
  if (!run_live(options, counters, error)) fail(error);
  std::printf(
      "markloop-sim: live: %llu frames sent (%llu failed), %llu CAN frames sent (%llu failed), "
      "%llu events late by more than 5 ms, worst %.2f ms%s\n",
      static_cast<unsigned long long>(counters.frames_sent),
      static_cast<unsigned long long>(counters.frame_errors),
      static_cast<unsigned long long>(counters.can_sent),
      static_cast<unsigned long long>(counters.can_errors),
      static_cast<unsigned long long>(counters.late_events), counters.max_lateness_ms,
      counters.interrupted ? " (interrupted)" : "");
  return counters.frame_errors == 0 && counters.can_errors == 0 ? 0 : 1;
}

int run(int argc, char** argv) {
  const std::string_view command = argc > 1 ? argv[1] : "";
  if (command == "drive") return drive(argc, argv);
  if (command == "training-set") return training_set(argc, argv);
  if (command == "live") return live(argc, argv);
  if (command == "list") {
    for (const auto& name : scenario_names()) {
      const auto s = make_scenario(name, 1);
      std::printf("%-9s %s\n", name.c_str(), s->description.c_str());
    }
    return 0;
  }
  if (command == "--help" || command == "-h" || command == "help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  if (command.empty()) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  fail("unknown command '" + std::string(command) + "' (drive, training-set, live or list; see --help)");
}

}  // namespace

int main(int argc, char** argv) {
  program_name() = "markloop-sim";
  const int status = run(argc, argv);
  std::string error;
  if (!tools::flush_stdout(error)) tools::fail_run(error);
  return status;
}
