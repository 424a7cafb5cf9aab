#include "app/tools/posegraph/solver.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <memory>
#include <string>
#include <utility>

#include <ceres/ceres.h>

namespace markloop::posegraph {

namespace {

template <typename T>
T wrapped(const T& angle) {
  using std::floor;
  const T two_pi(2.0 * M_PI);
  return angle - two_pi * floor((angle + T(M_PI)) / two_pi);
}

// An odometry edge's residual: the pose of `b` in the frame of `a` minus
// the measured one (its translation scaled by 1 + s), whitened.
struct OdometryCost {
  Edge edge;

  template <typename T>
  bool operator()(const T* a, const T* b, const T* s, T* residual) const {
    using std::cos;
    using std::sin;
    const T dx = b[0] - a[0], dy = b[1] - a[1];
    const T c = cos(a[2]), sn = sin(a[2]);
    const T stretch = T(1.0) + s[0];
    residual[0] = T(edge.sqrt_information[0]) * (c * dx + sn * dy - stretch * T(edge.measured.x));
    residual[1] = T(edge.sqrt_information[1]) * (-sn * dx + c * dy - stretch * T(edge.measured.y));
    residual[2] = T(edge.sqrt_information[2]) * wrapped(b[2] - a[2] - T(edge.measured.yaw));
    return true;
  }

  static ceres::CostFunction* create(const Edge& edge) {
    return new ceres::AutoDiffCostFunction<OdometryCost, 3, 3, 3, 1>(new OdometryCost{edge});
  }
};

// A loop edge's residual: each of its frames placed from its node by the
// (scaled) odometry offset, the second in the frame of the first minus the
// measured pose, whitened.
struct LoopCost {
  Edge edge;

  template <typename T>
  static void place(const T* node, const Pose2& offset, const T& stretch, T* frame) {
    using std::cos;
    using std::sin;
    const T c = cos(node[2]), sn = sin(node[2]);
    const T ox = stretch * T(offset.x), oy = stretch * T(offset.y);
    frame[0] = node[0] + c * ox - sn * oy;
    frame[1] = node[1] + sn * ox + c * oy;
    frame[2] = node[2] + T(offset.yaw);
  }

  template <typename T>
  bool operator()(const T* a, const T* b, const T* s, T* residual) const {
    using std::cos;
    using std::sin;
    const T stretch = T(1.0) + s[0];
    T fa[3], fb[3];
    place(a, edge.from_offset, stretch, fa);
    place(b, edge.to_offset, stretch, fb);
    const T dx = fb[0] - fa[0], dy = fb[1] - fa[1];
    const T c = cos(fa[2]), sn = sin(fa[2]);
    residual[0] = T(edge.sqrt_information[0]) * (c * dx + sn * dy - T(edge.measured.x));
    residual[1] = T(edge.sqrt_information[1]) * (-sn * dx + c * dy - T(edge.measured.y));
    residual[2] = T(edge.sqrt_information[2]) * wrapped(fb[2] - fa[2] - T(edge.measured.yaw));
    return true;
  }

  static ceres::CostFunction* create(const Edge& edge) {
    return new ceres::AutoDiffCostFunction<LoopCost, 3, 3, 3, 1>(new LoopCost{edge});
  }
};

// The prior on the scale error: (s - mean) / sigma.
struct ScalePrior {
  double mean;
  double sqrt_information;
  template <typename T>
  bool operator()(const T* s, T* residual) const {
    residual[0] = T(sqrt_information) * (s[0] - T(mean));
    return true;
  }
};

double whitened_norm(const Edge& e, const std::vector<std::array<double, 3>>& nodes, double scale) {
  double residual[3];
  LoopCost{e}(nodes[e.from].data(), nodes[e.to].data(), &scale, residual);
  return std::sqrt(residual[0] * residual[0] + residual[1] * residual[1] + residual[2] * residual[2]);
}

// The cost hardly changes with the scale: its solve runs to a tighter
// function tolerance than the others, or it stops before s has moved.
constexpr double kScaleTolerance = 1e-10;

// CPU time of the calling thread (Ceres runs in it with one thread).
double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// The first available of the preferred library and CXSparse, Eigen,
// SuiteSparse (measured fastest in that order on the bench's graph, one
// thread; CHOLMOD's supernodal factorisation pays for its small supernodes).
ceres::SparseLinearAlgebraLibraryType sparse_library(SparseLibrary preferred) {
  const std::pair<SparseLibrary, ceres::SparseLinearAlgebraLibraryType> order[] = {
      {SparseLibrary::kCxSparse, ceres::CX_SPARSE},
      {SparseLibrary::kEigen, ceres::EIGEN_SPARSE},
      {SparseLibrary::kSuiteSparse, ceres::SUITE_SPARSE}};
  for (const auto& [library, type] : order)
    if (library == preferred && ceres::IsSparseLinearAlgebraLibraryTypeAvailable(type)) return type;
  for (const auto& [library, type] : order)
    if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(type)) return type;
  return ceres::EIGEN_SPARSE;
}

ceres::Solver::Options solver_options(int max_iterations, double function_tolerance, SparseLibrary library) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  o.sparse_linear_algebra_library_type = sparse_library(library);
  o.num_threads = 1;  // the target: one core
  o.max_num_iterations = max_iterations;
  o.function_tolerance = function_tolerance;
  o.logging_type = ceres::SILENT;
  return o;
}

}  // namespace

Result<SolveReport> optimise(const PoseGraph& graph, const SolverOptions& options) {
  SolveReport report;
  std::vector<std::array<double, 3>> nodes(graph.initial.size());
  for (std::size_t i = 0; i < nodes.size(); ++i)
    nodes[i] = {graph.initial[i].x, graph.initial[i].y, graph.initial[i].yaw};
  if (nodes.empty()) return error("the graph has no node");

  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  // Without loops to refine it, the scale stays where the prior puts it.
  double scale =
      options.estimate_scale ? std::clamp(options.scale_prior_mean, -kScaleBound, kScaleBound) : 0.0;
  problem.AddParameterBlock(&scale, 1);
  for (const Edge& e : graph.odometry)
    problem.AddResidualBlock(OdometryCost::create(e), nullptr, nodes[e.from].data(), nodes[e.to].data(),
                             &scale);
  const double first_scale = options.robust_scales.empty() ? 1e6 : options.robust_scales.front();
  ceres::LossFunctionWrapper loop_loss(new ceres::CauchyLoss(first_scale), ceres::TAKE_OWNERSHIP);
  std::vector<ceres::ResidualBlockId> loop_blocks;
  for (const Edge& e : graph.loops)
    loop_blocks.push_back(problem.AddResidualBlock(LoopCost::create(e), &loop_loss, nodes[e.from].data(),
                                                   nodes[e.to].data(), &scale));
  problem.SetParameterBlockConstant(nodes[0].data());
  // The scale is held at the prior's mean through the robust stages and estimated in one
  // more solve without the loops they rejected: while loops still disagree
  // (early on, or wrong ones at any time) shrinking the whole map is the
  // cheapest way to bring each loop's two frames together.
  const bool estimate_scale = options.estimate_scale && !graph.loops.empty();
  if (estimate_scale) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<ScalePrior, 1, 1>(
                                 new ScalePrior{options.scale_prior_mean, 1.0 / options.scale_prior_sigma}),
                             nullptr, &scale);
    problem.SetParameterLowerBound(&scale, 0, -kScaleBound);
    problem.SetParameterUpperBound(&scale, 0, kScaleBound);
  }
  problem.SetParameterBlockConstant(&scale);

  const auto started = std::chrono::steady_clock::now();
  const double cpu_started = thread_cpu_seconds();
  const auto solve = [&](const char* what, double tolerance, bool last) -> Status {
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options(options.max_iterations_per_stage, tolerance, options.sparse_library),
                 &problem, &summary);
    if (!summary.IsSolutionUsable()) return error("Ceres: " + summary.message);
    char time[48];
    std::snprintf(time, sizeof time, " (%.3f s, linear solver %.3f s)", summary.total_time_in_seconds,
                  summary.linear_solver_time_in_seconds);
    report.summary += what + (": " + summary.BriefReport()) + time + "\n";
    report.iterations += static_cast<int>(summary.iterations.size());
    report.converged = report.converged && summary.termination_type == ceres::CONVERGENCE;
    if (last) report.full_report = summary.FullReport();
    return {};
  };
  const std::vector<double> scales =
      options.robust_scales.empty() ? std::vector<double>{1e6} : options.robust_scales;
  // A loop left beyond drop_beyond_scales Cauchy scales of the next stage
  // (where that stage would give it under 1 % of its weight) leaves the
  // problem: a wrong loop joins far-apart parts of the drive, and its fill-in
  // would slow every factorisation.
  std::vector<bool> dropped(graph.loops.size(), false);
  const auto drop_loops_beyond = [&](double sigmas) {
    for (std::size_t i = 0; i < graph.loops.size(); ++i)
      if (!dropped[i] && whitened_norm(graph.loops[i], nodes, scale) > sigmas) {
        problem.RemoveResidualBlock(loop_blocks[i]);
        dropped[i] = true;
      }
  };
  for (std::size_t stage = 0; stage < scales.size(); ++stage) {
    if (stage > 0 && options.drop_beyond_scales > 0)
      drop_loops_beyond(options.drop_beyond_scales * scales[stage]);
    loop_loss.Reset(new ceres::CauchyLoss(scales[stage]), ceres::TAKE_OWNERSHIP);
    const bool last = stage + 1 == scales.size() && !estimate_scale;
    char what[64];
    std::snprintf(what, sizeof what, "stage %zu (loop scale %g sigma)", stage + 1, scales[stage]);
    if (const Status done =
            solve(what, last ? options.function_tolerance : options.early_function_tolerance, last);
        !done)
      return error(done.message());
  }
  if (estimate_scale) {
    drop_loops_beyond(options.rejected_beyond_sigma);
    problem.SetParameterBlockVariable(&scale);
    if (const Status done = solve("scale (without the rejected loops)", kScaleTolerance, true); !done)
      return error(done.message());
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  report.cpu_seconds = thread_cpu_seconds() - cpu_started;

  report.scale = scale;
  report.nodes.reserve(nodes.size());
  for (const auto& n : nodes) report.nodes.push_back({n[0], n[1], n[2]});
  for (const Edge& e : graph.loops) {
    const bool rejected = whitened_norm(e, nodes, scale) > options.rejected_beyond_sigma;
    report.loop_rejected.push_back(rejected);
    report.loops_rejected += rejected ? 1 : 0;
  }
  return report;
}

}  // namespace markloop::posegraph
