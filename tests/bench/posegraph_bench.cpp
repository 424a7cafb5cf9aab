// markloop-posegraph's optimisation time against drive length, on one core:
// a synthetic drive around a 1.2 km block at 10 m/s and 10 frames/s with a
// drifting yaw rate, a loop every 20 m from the second lap on and 10 % of
// the loops wrong. Prints a table: minutes driven, nodes, loop edges,
// iterations, median of 3 solves (s), ATE before and after against the
// block, and how many wrong loops were rejected. The target: a
// one-hour drive under 1 s.
//
//   markloop-posegraph-bench [--first] [options]
//
// By default the tool's defaults. --first solves the first version's graph
// for comparison: a node every 2 m and at every loop frame, four robust
// stages (100, 20, 5, 2) each to the final tolerance, SuiteSparse, no scale
// estimate (loops
// are still dropped between stages: --drop 0 turns that off too). The other
// options change one setting each (see the usage line).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <numbers>
#include <vector>

#include "app/tools/posegraph/graph.hpp"
#include "app/tools/posegraph/metrics.hpp"
#include "app/tools/posegraph/solver.hpp"

namespace {

using namespace markloop;
using namespace markloop::posegraph;

constexpr double kSpeed = 10.0, kFps = 10.0, kBlock_m = 1200.0;

// A rounded square of perimeter kBlock_m: truth at distance s.
Pose2 block_at(double s) {
  const double r = kBlock_m / (2 * std::numbers::pi);
  const double a = s / r;
  return {r * std::sin(a), r * (1 - std::cos(a)), a};
}

struct Config {
  GraphOptions graph;
  SolverOptions solver;
  bool report = false;  // print Ceres's reports of the longest drive
};

void solve_drive(double minutes, const Config& config) {
  const auto frames = static_cast<std::size_t>(minutes * 60 * kFps);
  Truth truth;
  std::vector<Pose2> odometry;
  Pose2 drift{};
  for (std::size_t k = 0; k < frames; ++k) {
    const Pose2 t = block_at(kSpeed * static_cast<double>(k) / kFps);
    if (k > 0) {
      Pose2 step = compose(inverse(truth.poses.back()), t);
      step.yaw += 0.02 * std::numbers::pi / 180 / kFps;  // yaw-rate bias
      drift = compose(drift, step);
    }
    truth.poses.push_back(t);
    odometry.push_back(drift);
  }
  truth.known.assign(frames, true);
  std::vector<LoopMeasurement> loops;
  const auto lap = static_cast<std::size_t>(kBlock_m / kSpeed * kFps);
  for (std::size_t q = lap; q < frames; q += static_cast<std::size_t>(20 / kSpeed * kFps))
    loops.push_back({static_cast<FrameIndex>(q), static_cast<FrameIndex>(q - lap),
                     compose(inverse(truth.poses[q - lap]), truth.poses[q]), 0.05});
  loops = corrupt_loops(loops, 0.1, 1, truth.poses);
  std::size_t wrong = 0;
  for (const LoopMeasurement& m : loops) wrong += m.corrupted ? 1 : 0;
  const PoseGraph graph = build_graph(odometry, loops, config.graph);
  std::vector<double> seconds, cpu;
  Result<SolveReport> solved = error("not solved");
  for (int run = 0; run < 3; ++run) {
    solved = optimise(graph, config.solver);
    seconds.push_back(solved ? solved->seconds : -1.0);
    cpu.push_back(solved ? solved->cpu_seconds : -1.0);
  }
  std::sort(seconds.begin(), seconds.end());
  std::sort(cpu.begin(), cpu.end());
  double before = -1, after = -1;
  std::size_t wrong_rejected = 0;
  if (solved) {
    before = trajectory_error(odometry, truth)->ate_rmse_m;
    after =
        trajectory_error(frames_from_nodes(graph, solved->nodes, odometry, solved->scale), truth)->ate_rmse_m;
    for (std::size_t i = 0; i < loops.size(); ++i)
      wrong_rejected += loops[i].corrupted && solved->loop_rejected[i] ? 1 : 0;
  }
  std::printf("%8.0f %8zu %8zu %10d %10.3f %10.3f %10.3f %10.3f %6zu/%-4zu %+8.4f\n", minutes,
              graph.node_frame.size(), graph.loops.size(), solved ? solved->iterations : 0, seconds[1],
              cpu[1], before, after, wrong_rejected, wrong, solved ? solved->scale : 0.0);
  if (config.report && solved) std::printf("%s%s", solved->summary.c_str(), solved->full_report.c_str());
}

std::vector<double> scales_in(const char* list) {
  std::vector<double> scales;
  for (const char* p = list; *p != '\0';) {
    char* end = nullptr;
    scales.push_back(std::strtod(p, &end));
    p = *end == ',' ? end + 1 : end;
    if (end == p && *p != '\0') break;
  }
  return scales;
}

}  // namespace

int main(int argc, char** argv) {
  Config config;
  for (int i = 1; i < argc; ++i) {
    const char* a = argv[i];
    const bool has_value = i + 1 < argc;
    if (std::strcmp(a, "--first") == 0) {
      config.graph.keyframe_spacing_m = 2.0;
      config.graph.loop_nodes = true;
      config.solver.robust_scales = {100.0, 20.0, 5.0, 2.0};
      config.solver.early_function_tolerance = config.solver.function_tolerance;
      config.solver.sparse_library = SparseLibrary::kSuiteSparse;
      config.solver.estimate_scale = false;
    } else if (std::strcmp(a, "--report") == 0) {
      config.report = true;
    } else if (std::strcmp(a, "--no-scale") == 0) {
      config.solver.estimate_scale = false;
    } else if (std::strcmp(a, "--library") == 0 && has_value) {
      const char* l = argv[++i];
      config.solver.sparse_library = std::strcmp(l, "eigen") == 0         ? SparseLibrary::kEigen
                                     : std::strcmp(l, "suitesparse") == 0 ? SparseLibrary::kSuiteSparse
                                                                          : SparseLibrary::kCxSparse;
    } else if (std::strcmp(a, "--loop-nodes") == 0) {
      config.graph.loop_nodes = true;
    } else if (std::strcmp(a, "--keyframe-spacing") == 0 && has_value) {
      config.graph.keyframe_spacing_m = std::atof(argv[++i]);
    } else if (std::strcmp(a, "--robust-scales") == 0 && has_value) {
      config.solver.robust_scales = scales_in(argv[++i]);
    } else if (std::strcmp(a, "--drop") == 0 && has_value) {
      config.solver.drop_beyond_scales = std::atof(argv[++i]);
    } else if (std::strcmp(a, "--early-tolerance") == 0 && has_value) {
      config.solver.early_function_tolerance = std::atof(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: markloop-posegraph-bench [--first] [--no-scale] [--library "
                   "cx|eigen|suitesparse] [--loop-nodes] [--keyframe-spacing M] "
                   "[--robust-scales LIST] [--early-tolerance T] [--drop K] [--report]\n");
      return 2;
    }
  }
  std::printf("%8s %8s %8s %10s %10s %10s %10s %10s %11s %8s\n", "minutes", "nodes", "loops", "iterations",
              "solve_s", "cpu_s", "ate_bef_m", "ate_aft_m", "wrong_rej", "scale");
  for (const double minutes : {4.0, 15.0, 60.0}) {
    Config c = config;
    c.report = config.report && minutes == 60.0;
    solve_drive(minutes, c);
  }
  return 0;
}
