// The pose graph optimised with Ceres Solver (host only). Loop edges carry a
// robust loss whose scale shrinks in stages (graduated non-convexity): the
// first stage is nearly least squares and lets the many consistent loops
// pull the map into shape; the last leaves a loop that still disagrees with
// the rest almost no weight, so a wrong loop cannot bend the map. Optionally
// the odometry's scale error s is estimated with the poses (its translations
// scaled by 1 + s, a prior holding s near 0 or near what the camera
// measured): the loops' relative poses tell the scale only weakly, the
// closures themselves not at all.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "app/common/result.hpp"
#include "app/tools/posegraph/graph.hpp"

namespace markloop::posegraph {

// The sparse Cholesky factorisation's library: this one if Ceres has it,
// else the first it has of CXSparse, Eigen, SuiteSparse.
enum class SparseLibrary { kCxSparse, kEigen, kSuiteSparse };

// The scale error is kept within this (a wheel circumference 5 % off).
inline constexpr double kScaleBound = 0.05;

struct SolverOptions {
  // Cauchy scales of the stages, in standard deviations of a loop edge.
  std::vector<double> robust_scales{100.0, 2.0};
  int max_iterations_per_stage = 50;
  SparseLibrary sparse_library = SparseLibrary::kCxSparse;
  // Ceres's function tolerance in every stage but the last, and in the last.
  double early_function_tolerance = 1e-3;
  double function_tolerance = 1e-6;
  // Estimate the odometry's scale error, with a prior of this mean and
  // standard deviation on it.
  bool estimate_scale = true;
  double scale_prior_mean = 0.0;
  double scale_prior_sigma = 0.02;
  // Before a stage, a loop whose whitened residual exceeds this many of the
  // stage's Cauchy scales is removed from the problem (0: never).
  double drop_beyond_scales = 10.0;
  // A loop whose whitened residual exceeds this at the end is reported as
  // rejected (it had next to no weight in the last stage). Before the
  // scale's solve such loops are removed.
  double rejected_beyond_sigma = 10.0;
};

struct SolveReport {
  std::vector<Pose2> nodes;         // optimised, node 0 held where the odometry put it
  double scale = 0.0;               // the odometry's scale error s (0 unless estimated)
  std::vector<bool> loop_rejected;  // per loop edge
  std::size_t loops_rejected = 0;
  std::string summary;       // Ceres's brief report of each stage
  std::string full_report;   // Ceres's full report of the last stage
  double seconds = 0.0;      // wall time of all stages
  double cpu_seconds = 0.0;  // CPU time of all stages (one thread)
  int iterations = 0;
  bool converged = true;  // every stage ended on a convergence criterion
};

// An error when Ceres finds the problem unusable (not a number in a cost).
Result<SolveReport> optimise(const PoseGraph& graph, const SolverOptions& options = {});

}  // namespace markloop::posegraph
