// markloop-posegraph's optimisation time against drive length, on one core:
// a synthetic drive around a 1.2 km block at 10 m/s and 10 frames/s with a
// drifting yaw rate, a loop every 20 m from the second lap on and 10 % of
// the loops wrong. Prints a table: minutes driven, nodes, loop edges,
// median of 3 solves (s). The target: a one-hour drive under 1 s.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "app/tools/posegraph/graph.hpp"
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

double median_solve_seconds(double minutes) {
  const auto frames = static_cast<std::size_t>(minutes * 60 * kFps);
  std::vector<Pose2> truth, odometry;
  Pose2 drift{};
  for (std::size_t k = 0; k < frames; ++k) {
    const Pose2 t = block_at(kSpeed * static_cast<double>(k) / kFps);
    if (k > 0) {
      Pose2 step = compose(inverse(truth.back()), t);
      step.yaw += 0.02 * std::numbers::pi / 180 / kFps;  // yaw-rate bias
      drift = compose(drift, step);
    }
    truth.push_back(t);
    odometry.push_back(drift);
  }
  std::vector<LoopMeasurement> loops;
  const auto lap = static_cast<std::size_t>(kBlock_m / kSpeed * kFps);
  for (std::size_t q = lap; q < frames; q += static_cast<std::size_t>(20 / kSpeed * kFps))
    loops.push_back({static_cast<FrameIndex>(q), static_cast<FrameIndex>(q - lap),
                     compose(inverse(truth[q - lap]), truth[q]), 0.05});
  loops = corrupt_loops(loops, 0.1, 1, truth);
  const PoseGraph graph = build_graph(odometry, loops, GraphOptions{});
  std::vector<double> seconds;
  int iterations = 0;
  for (int run = 0; run < 3; ++run) {
    const Result<SolveReport> solved = optimise(graph);
    seconds.push_back(solved ? solved->seconds : -1.0);
    iterations = solved ? solved->iterations : 0;
  }
  std::sort(seconds.begin(), seconds.end());
  std::printf("%8.0f %8zu %8zu %10d %10.3f\n", minutes, graph.node_frame.size(), graph.loops.size(),
              iterations, seconds[1]);
  return seconds[1];
}

}  // namespace

int main() {
  std::printf("%8s %8s %8s %10s %10s\n", "minutes", "nodes", "loops", "iterations", "solve_s");
  for (const double minutes : {4.0, 15.0, 60.0}) median_solve_seconds(minutes);
  return 0;
}
