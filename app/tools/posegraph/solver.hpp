// The pose graph optimised with Ceres Solver (host only). Loop edges carry a
// robust loss whose scale shrinks in stages (graduated non-convexity): the
// first stage is nearly least squares and lets the many consistent loops
// pull the map into shape; the later ones leave a loop that still disagrees
// with the rest almost no weight, so a wrong loop cannot bend the map.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "app/common/result.hpp"
#include "app/tools/posegraph/graph.hpp"

namespace markloop::posegraph {

struct SolverOptions {
  // Cauchy scales of the stages, in standard deviations of a loop edge.
  std::vector<double> robust_scales{100.0, 20.0, 5.0, 2.0};
  int max_iterations_per_stage = 50;
  // A loop whose whitened residual exceeds this at the end is reported as
  // rejected (it had next to no weight in the last stage).
  double rejected_beyond_sigma = 10.0;
};

struct SolveReport {
  std::vector<Pose2> nodes;         // optimised, node 0 held where the odometry put it
  std::vector<bool> loop_rejected;  // per loop edge
  std::size_t loops_rejected = 0;
  std::string summary;      // Ceres's brief report of each stage
  std::string full_report;  // Ceres's full report of the last stage
  double seconds = 0.0;     // wall time of all stages
  int iterations = 0;
  bool converged = true;  // every stage ended on a convergence criterion
};

// An error when Ceres finds the problem unusable (not a number in a cost).
Result<SolveReport> optimise(const PoseGraph& graph, const SolverOptions& options = {});

}  // namespace markloop::posegraph
