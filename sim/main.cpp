// markloop-sim: drives a car through a world of road markings and writes
// what it saw, in the file formats the ECU's tools read.
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "cli/cli.hpp"
#include "sim/drive.hpp"
#include "sim/world.hpp"

namespace {

using markloop::Pose2;
using namespace markloop::sim;
using namespace markloop::cli;

constexpr const char* kUsage = R"(usage: markloop-sim drive --scenario NAME --out DIR [options]
       markloop-sim list

drive: simulate a drive and write, into DIR,
  markings.txt   observed road markings, one record per detection, in the
                 road_marking_centroids_3Dposition.txt format (count, then
                 "frame x y z label"; camera axes: x right, y down, z ahead)
  poses.txt      the car's estimated (drifting) pose per frame, KITTI 3x4
  frames.csv     ground truth per frame: frame,t,x,y,yaw
  markings.csv   the world's markings: id,class,x,y,heading

options:
  --scenario NAME   built-in scenario (see "list"); default loop
  --out DIR         output folder (created if missing); required
  --seed N          random seed for the world and the sensors; default 1
  --speed M/S       driving speed; default 10
  --fps HZ          camera frame rate; default 10
  --help            this text
)";

// Ground frame (x ahead, y left) to the camera-style world of the paper's
// files (x right, y down, z ahead); the ground lies 1.5 m below the camera.
void write_kitti_pose(FILE* f, const Pose2& p) {
  const double c = std::cos(p.yaw), s = std::sin(p.yaw);
  std::fprintf(f, "%.6f 0 %.6f %.4f 0 1 0 0 %.6f 0 %.6f %.4f\n", c, -s, -p.y, s, c, p.x);
}

int drive(int argc, char** argv) {
  std::string scenario_name = "loop";
  std::string out_dir;
  std::uint64_t seed = 1;
  DriveConfig drive_config;
  for (int i = 2; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (i + 1 >= argc) fail(std::string(arg) + " needs a value (see --help)");
    const char* value = argv[++i];
    if (arg == "--scenario") scenario_name = value;
    else if (arg == "--out") out_dir = value;
    else if (arg == "--seed") seed = static_cast<std::uint64_t>(parse_number(arg, value));
    else if (arg == "--speed") drive_config.speed_mps = parse_number(arg, value);
    else if (arg == "--fps") drive_config.fps = parse_number(arg, value);
    else fail("unknown option " + std::string(arg) + " (see --help)");
  }
  if (out_dir.empty()) fail("--out DIR is required (see --help)");
  if (drive_config.speed_mps <= 0 || drive_config.fps <= 0)
    fail("--speed and --fps must be positive");
  const auto scenario = make_scenario(scenario_name, seed);
  if (!scenario) fail("unknown scenario '" + scenario_name + "' (see: markloop-sim list)");

  const std::filesystem::path dir(out_dir);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) fail("cannot create " + dir.string() + ": " + ec.message());

  Drive drive(*scenario, drive_config, seed * 7919 + 17);
  const auto& classes = marking_class_names();
  std::vector<std::string> records;
  FILE* poses = open_output(dir / "poses.txt");
  FILE* frames = open_output(dir / "frames.csv");
  std::fprintf(frames, "frame,t,x,y,yaw\n");
  DriveFrame frame;
  char line[160];
  while (drive.next(frame)) {
    write_kitti_pose(poses, frame.estimate.pose);
    std::fprintf(frames, "%u,%.3f,%.4f,%.4f,%.6f\n", frame.estimate.frame, frame.estimate.t,
                 frame.truth.x, frame.truth.y, frame.truth.yaw);
    for (const auto& obs : frame.observations) {
      std::snprintf(line, sizeof line, "%u %.4f 1.5 %.4f %s", frame.estimate.frame, -obs.y, obs.x,
                    classes.at(obs.label).c_str());
      records.emplace_back(line);
    }
  }
  close_output(poses, dir / "poses.txt");
  close_output(frames, dir / "frames.csv");

  FILE* markings = open_output(dir / "markings.txt");
  std::fprintf(markings, "%zu\n", records.size());
  for (const auto& r : records) std::fprintf(markings, "%s\n", r.c_str());
  close_output(markings, dir / "markings.txt");

  FILE* world = open_output(dir / "markings.csv");
  std::fprintf(world, "id,class,x,y,heading\n");
  for (const Marking& m : scenario->markings)
    std::fprintf(world, "%u,%s,%.4f,%.4f,%.6f\n", m.id, classes.at(m.label).c_str(), m.x, m.y,
                 m.heading);
  close_output(world, dir / "markings.csv");

  std::printf("markloop-sim: %s (%s): %zu frames, %zu markings in the world, %zu detections -> %s\n",
              scenario->name.c_str(), scenario->description.c_str(), drive.frame_count(),
              scenario->markings.size(), records.size(), dir.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  program_name() = "markloop-sim";
  const std::string_view command = argc > 1 ? argv[1] : "";
  if (command == "drive") return drive(argc, argv);
  if (command == "list") {
    for (const auto& name : scenario_names()) {
      const auto s = make_scenario(name, 1);
      std::printf("%-8s %s\n", name.c_str(), s->description.c_str());
    }
    return 0;
  }
  if (command == "--help" || command == "-h" || command == "help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  std::fputs(kUsage, stderr);
  return 2;
}
