#include "app/tools/posegraph/solver.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

#include <ceres/ceres.h>

namespace markloop::posegraph {

namespace {

template <typename T>
T wrapped(const T& angle) {
  using std::floor;
  const T two_pi(2.0 * M_PI);
  return angle - two_pi * floor((angle + T(M_PI)) / two_pi);
}

// Residual of one edge: the pose of `to` in the frame of `from` minus the
// measured one, whitened by the edge's diagonal information.
struct EdgeCost {
  Edge edge;

  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    using std::cos;
    using std::sin;
    const T dx = b[0] - a[0], dy = b[1] - a[1];
    const T c = cos(a[2]), s = sin(a[2]);
    residual[0] = T(edge.sqrt_information[0]) * (c * dx + s * dy - T(edge.measured.x));
    residual[1] = T(edge.sqrt_information[1]) * (-s * dx + c * dy - T(edge.measured.y));
    residual[2] = T(edge.sqrt_information[2]) * wrapped(b[2] - a[2] - T(edge.measured.yaw));
    return true;
  }

  static ceres::CostFunction* create(const Edge& edge) {
    return new ceres::AutoDiffCostFunction<EdgeCost, 3, 3, 3>(new EdgeCost{edge});
  }
};

double whitened_norm(const Edge& e, const std::vector<std::array<double, 3>>& nodes) {
  double residual[3];
  EdgeCost{e}(nodes[e.from].data(), nodes[e.to].data(), residual);
  return std::sqrt(residual[0] * residual[0] + residual[1] * residual[1] + residual[2] * residual[2]);
}

ceres::Solver::Options solver_options(int max_iterations) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  if (!ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE))
    o.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
  o.num_threads = 1;  // the target: one core
  o.max_num_iterations = max_iterations;
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
  for (const Edge& e : graph.odometry)
    problem.AddResidualBlock(EdgeCost::create(e), nullptr, nodes[e.from].data(), nodes[e.to].data());
  const double first_scale = options.robust_scales.empty() ? 1e6 : options.robust_scales.front();
  ceres::LossFunctionWrapper loop_loss(new ceres::CauchyLoss(first_scale), ceres::TAKE_OWNERSHIP);
  for (const Edge& e : graph.loops)
    problem.AddResidualBlock(EdgeCost::create(e), &loop_loss, nodes[e.from].data(), nodes[e.to].data());
  problem.SetParameterBlockConstant(nodes[0].data());

  const auto started = std::chrono::steady_clock::now();
  const std::vector<double> scales =
      options.robust_scales.empty() ? std::vector<double>{1e6} : options.robust_scales;
  for (std::size_t stage = 0; stage < scales.size(); ++stage) {
    loop_loss.Reset(new ceres::CauchyLoss(scales[stage]), ceres::TAKE_OWNERSHIP);
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options(options.max_iterations_per_stage), &problem, &summary);
    if (!summary.IsSolutionUsable()) return error("Ceres: " + summary.message);
    char line[96];
    std::snprintf(line, sizeof line, "stage %zu (loop scale %g sigma): ", stage + 1, scales[stage]);
    report.summary += line + summary.BriefReport() + "\n";
    report.iterations += static_cast<int>(summary.iterations.size());
    report.converged = report.converged && summary.termination_type == ceres::CONVERGENCE;
    if (stage + 1 == scales.size()) report.full_report = summary.FullReport();
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();

  report.nodes.reserve(nodes.size());
  for (const auto& n : nodes) report.nodes.push_back({n[0], n[1], n[2]});
  for (const Edge& e : graph.loops) {
    const bool rejected = whitened_norm(e, nodes) > options.rejected_beyond_sigma;
    report.loop_rejected.push_back(rejected);
    report.loops_rejected += rejected ? 1 : 0;
  }
  return report;
}

}  // namespace markloop::posegraph
