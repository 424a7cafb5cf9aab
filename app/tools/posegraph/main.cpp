// markloop-posegraph: a 2-D pose graph of the car's odometry and markloop's
// loop closures, optimised with Ceres; writes the trajectory before and
// after, and with a truth prints how much the loops corrected it.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "app/common/cli.hpp"
#include "app/tools/common/tool_files.hpp"
#include "app/tools/common/trajectory.hpp"
#include "app/tools/posegraph/graph.hpp"
#include "app/tools/posegraph/inputs.hpp"
#include "app/tools/posegraph/metrics.hpp"
#include "app/tools/posegraph/picture.hpp"
#include "app/tools/posegraph/solver.hpp"
#include "app/tools/replay/paper_format.hpp"
#include "platform/files.hpp"

namespace {

using namespace markloop;
using namespace markloop::posegraph;
using namespace markloop::cli;

constexpr const char* kUsage = R"(usage: markloop-posegraph --can-in FILE --can-out FILE --out DIR [options]
       markloop-posegraph --replay-jsonl FILE --poses FILE --out DIR [options]

Builds a 2-D pose graph from the car's odometry and markloop's loop
closures, optimises it with Ceres Solver (robust loss on the loops, the
odometry's scale error estimated too, from the camera's measure of it
that the ECU sends and from the loops) and writes the trajectory before
and after. With --truth it prints the
absolute and relative trajectory errors before and after.

input (the bus as recorded, candump -l logs on the recording's clock:
frame k at k / fps):
  --can-in FILE            VehicleOdometry frames (markloop-sim's odometry.log);
                           integrated as the ECU does, a graph node every few
                           metres
  --can-out FILE           the ECU's LoopDetection frames (its --can-out)
input (markloop-replay's output instead):
  --replay-jsonl FILE      markloop-replay --jsonl: one match per line
  --poses FILE             the drifting trajectory it ran on, KITTI 3x4 per
                           frame (markloop-sim's poses.txt)
  --truth FILE             frames.csv (markloop-sim), KITTI or TUM poses
  --fps HZ                 frame rate, 1 to 1000; default 10

graph and noise model (each standard deviation of an odometry edge of
length d over dt seconds: along d * R + 0.01 m, heading DPS * dt, across
d * heading / 2 + 0.01 m; of a loop edge: position its PoseResidual, at
least the floor, heading the loop sigma):
  --keyframe-spacing M     a node every M metres driven (0: every frame),
                           0 to 100; default 10. A loop's frames are attached
                           to their nearest nodes by the odometry between
  --loop-nodes             every frame a loop names gets a node instead
  --odometry-scale-error R relative distance error, 0.0001 to 1; default 0.01
  --yaw-rate-error DPS     yaw-rate error in deg/s, 0.0001 to 10; default 0.1
  --loop-sigma-floor M     least position sigma of a loop, 0.001 to 10; default 0.05
  --loop-yaw-sigma DEG     heading sigma of a loop, 0.01 to 90; default 1
  --robust-scales LIST     Cauchy scales of the robust stages on the loops, in
                           loop sigmas, comma-separated, each 0.1 to 1e6;
                           default 100,2
  --no-robust              plain least squares on the loops (for comparison)
  --no-scale               do not estimate the odometry's scale error s (its
                           translations scaled by 1 + s; estimated after the
                           robust stages, without the loops they rejected)
  --scale-prior SIGMA      standard deviation of the prior on s without the
                           camera's measure, 0.0001 to 1; default 0.02
  --camera-scale-floor SIGMA
                           the prior on s is the ECU's OdometryScale (Status
                           page Odometry) when it sent one, its standard
                           deviation OdometryScaleError but at least this
                           (the camera's own range errors), 0.0001 to 1;
                           default 0.002
  --camera-scale SCALE     the camera's measure of the odometry's scale, 0.9
                           to 1.1, in place of the ECU's (for a replay's JSONL:
                           markloop-replay prints it); standard deviation the
                           floor
  --no-camera-scale        ignore the ECU's OdometryScale

robustness experiment:
  --corrupt-loops F        replace the share F (0 to 1) of the loops, chosen at
                           random, by wrong ones: random frame pairs at least
                           100 m apart (by the truth, else the odometry) with a
                           plausible relative pose (within 3 m and 10 deg)
  --seed N                 seed of that choice; default 1

output:
  --out DIR                created if missing; writes before.tum, after.tum
                           (t x y z qx qy qz qw, t = frame / fps), before.kitti,
                           after.kitti (3x4 per frame), solver.txt (Ceres's
                           full report) and, with --truth, posegraph.svg (truth,
                           odometry, corrected and the loop edges)
  --help                   this text

Loops whose pages arrived incomplete or out of order, or without a relative
pose, are skipped and counted. A loop naming a frame outside the recording,
a log line that is not a candump frame or a log cut short is an error.

Exit status: 0 on success; 1 when an output cannot be written (PATH: why);
2 on bad input or options (FILE:LINE: what).
)";

constexpr OptionSpec kOptions[] = {
    {"--can-in", "FILE", "VehicleOdometry candump log"},
    {"--can-out", "FILE", "the ECU's LoopDetection candump log"},
    {"--replay-jsonl", "FILE", "markloop-replay --jsonl matches"},
    {"--poses", "FILE", "the trajectory markloop-replay ran on (KITTI)"},
    {"--truth", "FILE", "frames.csv, KITTI or TUM truth"},
    {"--fps", "HZ", "frame rate"},
    {"--keyframe-spacing", "M", "a node every M metres"},
    {"--odometry-scale-error", "R", "relative distance error"},
    {"--yaw-rate-error", "DPS", "yaw-rate error"},
    {"--loop-sigma-floor", "M", "least position sigma of a loop"},
    {"--loop-yaw-sigma", "DEG", "heading sigma of a loop"},
    {"--loop-nodes", "", "a node at every frame a loop names"},
    {"--robust-scales", "LIST", "Cauchy scales of the robust stages"},
    {"--no-robust", "", "plain least squares on the loops"},
    {"--no-scale", "", "do not estimate the odometry's scale error"},
    {"--scale-prior", "SIGMA", "prior on the odometry's scale error"},
    {"--camera-scale-floor", "SIGMA", "least sigma of the camera's scale"},
    {"--camera-scale", "SCALE", "the odometry's scale, measured elsewhere"},
    {"--no-camera-scale", "", "ignore the ECU's OdometryScale"},
    {"--corrupt-loops", "F", "replace this share of loops by wrong ones"},
    {"--seed", "N", "seed of --corrupt-loops"},
    {"--out", "DIR", "output folder"},
};

struct Options {
  std::string can_in, can_out, replay_jsonl, poses, truth, out;
  GraphOptions graph;
  SolverOptions solver;
  double corrupt = 0.0;
  unsigned seed = 1;
  bool camera_scale = true;
  double camera_scale_floor = 0.002;
  std::optional<double> camera_scale_given;
};

double number_in(std::string_view name, std::string_view value, double low, double high) {
  const double v = parse_number(name, std::string(value).c_str());
  if (!(v >= low && v <= high))
    fail(std::string(name) + " must lie in " + std::to_string(low) + " to " + std::to_string(high));
  return v;
}

std::vector<double> scales_in(std::string_view name, std::string_view list) {
  std::vector<double> scales;
  while (true) {
    const std::size_t comma = list.find(',');
    scales.push_back(number_in(name, list.substr(0, comma), 0.1, 1e6));
    if (comma == std::string_view::npos) return scales;
    list.remove_prefix(comma + 1);
  }
}

void apply_option(std::string_view name, std::string_view value, Options& o) {
  for (auto [option, field] : {std::pair{"--can-in", &o.can_in},
                               {"--can-out", &o.can_out},
                               {"--replay-jsonl", &o.replay_jsonl},
                               {"--poses", &o.poses},
                               {"--truth", &o.truth},
                               {"--out", &o.out}})
    if (name == option) *field = value;
  if (name == "--fps") o.graph.fps = number_in(name, value, 1, 1000);
  if (name == "--keyframe-spacing") o.graph.keyframe_spacing_m = number_in(name, value, 0, 100);
  if (name == "--odometry-scale-error") o.graph.odometry.scale_error = number_in(name, value, 1e-4, 1);
  if (name == "--yaw-rate-error") o.graph.odometry.yaw_rate_error_dps = number_in(name, value, 1e-4, 10);
  if (name == "--loop-sigma-floor") o.graph.loop.floor_m = number_in(name, value, 1e-3, 10);
  if (name == "--loop-yaw-sigma") o.graph.loop.yaw_deg = number_in(name, value, 0.01, 90);
  if (name == "--loop-nodes") o.graph.loop_nodes = true;
  if (name == "--robust-scales") o.solver.robust_scales = scales_in(name, value);
  if (name == "--no-robust") o.solver.robust_scales = {};
  if (name == "--no-scale") o.solver.estimate_scale = false;
  if (name == "--scale-prior") o.solver.scale_prior_sigma = number_in(name, value, 1e-4, 1);
  if (name == "--camera-scale-floor") o.camera_scale_floor = number_in(name, value, 1e-4, 1);
  if (name == "--no-camera-scale") o.camera_scale = false;
  if (name == "--camera-scale") o.camera_scale_given = number_in(name, value, 0.9, 1.1);
  if (name == "--corrupt-loops") o.corrupt = number_in(name, value, 0, 1);
  if (name == "--seed") o.seed = parse_whole(name, std::string(value).c_str());
}

Options parse(int argc, char** argv) {
  const ParsedArgs args = parse_args_or_fail(argc, argv, kOptions);
  Options o;
  for (const ParsedArgs::Given& given : args.given()) apply_option(given.name, given.value, o);
  if (args.help()) {
    std::fputs(kUsage, stdout);
    std::exit(kExitOk);
  }
  const bool from_ecu = !o.can_in.empty() || !o.can_out.empty();
  const bool from_replay = !o.replay_jsonl.empty() || !o.poses.empty();
  if (from_ecu == from_replay)
    fail("give either --can-in and --can-out, or --replay-jsonl and --poses (see --help)");
  if (from_ecu && (o.can_in.empty() || o.can_out.empty())) fail("--can-in and --can-out go together");
  if (from_replay && (o.replay_jsonl.empty() || o.poses.empty()))
    fail("--replay-jsonl and --poses go together");
  if (o.camera_scale_given && !o.camera_scale)
    fail("--camera-scale and --no-camera-scale contradict each other");
  if (o.out.empty()) fail("--out DIR is required (see --help)");
  return o;
}

const char* const kOutputs[] = {"before.tum",  "after.tum",  "before.kitti",
                                "after.kitti", "solver.txt", "posegraph.svg"};

std::string output(const Options& o, const char* name) {
  return (std::filesystem::path(o.out) / name).string();
}

// An output that is one of the inputs would destroy it: refused before the run.
void check_outputs(const Options& o) {
  for (const char* name : kOutputs)
    for (const std::string* input : {&o.can_in, &o.can_out, &o.replay_jsonl, &o.poses, &o.truth})
      if (!input->empty() && platform::overwrites(output(o, name), *input))
        fail(output(o, name) + ": is the input " + *input + ": an output may not overwrite it");
}

template <typename T>
T or_fail(Result<T> result) {
  if (!result) fail(result.message());
  return std::move(result).value();
}

struct Run {
  Options o;
  std::vector<Pose2> odometry;  // a pose per frame
  LoopInput loops;
  std::optional<Truth> truth;
};

void load_inputs(Run& r) {
  if (!r.o.can_in.empty()) {
    const OdometryTrack track = or_fail(read_odometry_log(r.o.can_in, r.o.graph.fps));
    const ecu::OdometryCounters& c = track.counters;
    std::printf(
        "odometry: %zu frames at %g Hz (%.1f s), %zu without a known pose; VehicleOdometry %llu "
        "accepted, %llu rejected\n",
        track.poses.size(), r.o.graph.fps, static_cast<double>(track.poses.size()) / r.o.graph.fps,
        track.frames_without_pose, (unsigned long long)c.accepted,
        (unsigned long long)(c.wrong_length + c.bad_crc + c.bad_counter + c.out_of_range + c.out_of_order));
    r.odometry = track.poses;
    r.loops = or_fail(read_ecu_loops(r.o.can_out, r.odometry.size()));
  } else {
    r.odometry = or_fail(replay::load_kitti_poses(r.o.poses));
    if (r.odometry.empty()) fail(r.o.poses + ": no pose in it");
    std::printf("trajectory: %zu frames from %s\n", r.odometry.size(), r.o.poses.c_str());
    r.loops = or_fail(read_replay_jsonl(r.o.replay_jsonl, r.odometry.size()));
  }
  std::printf(
      "loops: %zu with a relative pose; skipped %zu without one, %zu incomplete (pages missing or out of "
      "order), %zu LoopDetection frames rejected\n",
      r.loops.loops.size(), r.loops.without_pose, r.loops.incomplete, r.loops.rejected_frames);
  if (!r.o.truth.empty()) r.truth = or_fail(load_truth(r.o.truth, r.o.graph.fps));
}

// The camera's measure of the odometry's scale becomes the prior on s
// (corrected distance = odometry distance * (1 + s)).
void use_camera_scale(Run& r) {
  if (r.o.camera_scale_given) r.loops.camera_scale = CameraScale{*r.o.camera_scale_given, 0.0};
  const std::optional<CameraScale>& camera = r.loops.camera_scale;
  if (!camera) {
    if (!r.o.can_out.empty()) std::printf("odometry scale by the camera: none in the ECU's log\n");
    return;
  }
  std::printf("odometry scale by the camera: %.5f +- %.5f", camera->scale, camera->standard_error);
  const double mean = 1.0 / camera->scale - 1.0;
  if (!r.o.camera_scale || !r.o.solver.estimate_scale) {
    std::printf(" (not used)\n");
  } else if (!(std::abs(mean) <= kScaleBound)) {
    std::printf(" (not used: beyond the %.0f %% the solver allows)\n", 100.0 * kScaleBound);
  } else {
    r.o.solver.scale_prior_mean = mean;
    r.o.solver.scale_prior_sigma =
        std::hypot(camera->standard_error / (camera->scale * camera->scale), r.o.camera_scale_floor);
    std::printf("; prior on s %+.4f +- %.4f\n", mean, r.o.solver.scale_prior_sigma);
  }
}

void corrupt(Run& r) {
  if (r.o.corrupt <= 0.0) return;
  const std::vector<Pose2>& places = r.truth ? r.truth->poses : r.odometry;
  const std::size_t frames = std::min(places.size(), r.odometry.size());
  r.loops.loops = corrupt_loops(r.loops.loops, r.o.corrupt, r.o.seed, std::span(places).first(frames));
  std::size_t wrong = 0;
  for (const LoopMeasurement& m : r.loops.loops) wrong += m.corrupted ? 1 : 0;
  std::printf("corrupt-loops: %zu of %zu loops replaced by wrong ones (seed %u)\n", wrong,
              r.loops.loops.size(), r.o.seed);
}

void print_solve(const PoseGraph& g, const SolveReport& s, std::span<const LoopMeasurement> loops) {
  std::printf("graph: %zu nodes, %zu odometry edges, %zu loop edges\n", g.node_frame.size(),
              g.odometry.size(), g.loops.size());
  std::fputs(s.summary.c_str(), stdout);
  std::size_t wrong_rejected = 0, wrong = 0;
  for (std::size_t i = 0; i < loops.size(); ++i) {
    wrong += loops[i].corrupted ? 1 : 0;
    wrong_rejected += loops[i].corrupted && s.loop_rejected[i] ? 1 : 0;
  }
  std::printf(
      "solver: %.3f s, %d iterations%s; odometry scale error %+.4f; %zu loop edges rejected by the "
      "robust loss",
      s.seconds, s.iterations, s.converged ? "" : " (a stage stopped before converging)", s.scale,
      s.loops_rejected);
  if (wrong > 0) std::printf(" (%zu of the %zu wrong ones)", wrong_rejected, wrong);
  std::printf("\n");
}

void print_errors(const TrajectoryError& before, const TrajectoryError& after) {
  std::printf(
      "ATE (RMSE after SE(2) alignment, %zu frames): before %.3f m, after %.3f m (max %.3f m, %.3f m); "
      "after / before %.3f\n",
      before.frames, before.ate_rmse_m, after.ate_rmse_m, before.ate_max_m, after.ate_max_m,
      before.ate_rmse_m > 0 ? after.ate_rmse_m / before.ate_rmse_m : 0.0);
  std::printf("ATE after Sim(2) alignment (scale %.4f and %.4f): before %.3f m, after %.3f m\n",
              before.sim2_scale, after.sim2_scale, before.ate_sim2_rmse_m, after.ate_sim2_rmse_m);
  std::printf("RPE per %.0f m (%zu pairs): before %.3f m / %.3f deg, after %.3f m / %.3f deg\n",
              kRpeStretch_m, before.rpe_pairs, before.rpe_translation_rmse_m, before.rpe_rotation_mean_deg,
              after.rpe_translation_rmse_m, after.rpe_rotation_mean_deg);
}

void write_or_fail(const Status& written) {
  if (!written) tools::fail_run(written.message());
}

void write_outputs(const Run& r, const std::vector<Pose2>& after, const SolveReport& s) {
  std::error_code ec;
  std::filesystem::create_directories(r.o.out, ec);
  if (ec) tools::fail_run(r.o.out + ": cannot create: " + ec.message());
  write_or_fail(tools::write_tum(output(r.o, "before.tum"), r.odometry, r.o.graph.fps));
  write_or_fail(tools::write_tum(output(r.o, "after.tum"), after, r.o.graph.fps));
  write_or_fail(tools::write_kitti(output(r.o, "before.kitti"), r.odometry));
  write_or_fail(tools::write_kitti(output(r.o, "after.kitti"), after));
  write_or_fail(
      tools::write_whole_file(output(r.o, "solver.txt"), s.full_report.data(), s.full_report.size()));
}

void draw(const Run& r, const std::vector<Pose2>& after, const SolveReport& s,
          const TrajectoryError& before_error, const TrajectoryError& after_error) {
  const std::vector<Pose2> odometry = tools::transformed(r.odometry, before_error.alignment);
  const std::vector<Pose2> corrected = tools::transformed(after, after_error.alignment);
  PictureContent picture{r.truth->poses, odometry, corrected, r.loops.loops, s.loop_rejected, {}};
  char title[200];
  std::snprintf(title, sizeof title,
                "markloop-posegraph: ATE %.2f m before, %.2f m after (%zu loops, %zu rejected)",
                before_error.ate_rmse_m, after_error.ate_rmse_m, r.loops.loops.size(), s.loops_rejected);
  picture.title = title;
  write_or_fail(write_picture_svg(output(r.o, "posegraph.svg"), picture));
}

}  // namespace

int main(int argc, char** argv) {
  program_name() = "markloop-posegraph";
  Run r;
  r.o = parse(argc, argv);
  check_outputs(r.o);
  load_inputs(r);
  use_camera_scale(r);
  corrupt(r);
  const PoseGraph graph = build_graph(r.odometry, r.loops.loops, r.o.graph);
  const SolveReport solved = or_fail(optimise(graph, r.o.solver));
  print_solve(graph, solved, r.loops.loops);
  const std::vector<Pose2> after = frames_from_nodes(graph, solved.nodes, r.odometry, solved.scale);
  write_outputs(r, after, solved);
  if (r.truth) {
    const auto before_error = trajectory_error(r.odometry, *r.truth);
    const auto after_error = trajectory_error(after, *r.truth);
    if (!before_error || !after_error) fail(r.o.truth + ": fewer than 2 frames in common with the recording");
    print_errors(*before_error, *after_error);
    draw(r, after, solved, *before_error, *after_error);
  }
  std::printf("outputs: %s/{before,after}.{tum,kitti}, solver.txt%s\n", r.o.out.c_str(),
              r.truth ? ", posegraph.svg" : "");
  if (const Status flushed = tools::flush_stdout(); !flushed) tools::fail_run(flushed.message());
  return kExitOk;
}
