#include "app/tools/posegraph/graph.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "app/common/units.hpp"

namespace markloop::posegraph {

namespace {

Pose2 between(const Pose2& a, const Pose2& b) {
  return compose(inverse(a), b);
}

Edge odometry_edge(std::size_t from, std::size_t to, const Pose2& a, const Pose2& b, double dt,
                   const OdometryNoise& noise) {
  const Pose2 delta = between(a, b);
  const double d = std::hypot(delta.x, delta.y);
  const double sigma_yaw = std::max(noise.yaw_rate_error_dps * kRadiansPerDegree * dt, 1e-5);
  const double sigma_along = noise.scale_error * d + noise.floor_m;
  const double sigma_across = 0.5 * d * sigma_yaw + noise.floor_m;
  return {from, to, delta, {1.0 / sigma_along, 1.0 / sigma_across, 1.0 / sigma_yaw}};
}

Edge loop_edge(std::size_t match_node, std::size_t query_node, const LoopMeasurement& m,
               const LoopNoise& noise) {
  const double sigma_xy = std::max(m.residual_m, noise.floor_m);
  const double sigma_yaw = noise.yaw_deg * kRadiansPerDegree;
  return {match_node, query_node, m.relative, {1.0 / sigma_xy, 1.0 / sigma_xy, 1.0 / sigma_yaw}};
}

// Keyframes every `spacing` metres driven, the first and last frames, and
// every frame a loop names.
std::vector<FrameIndex> choose_nodes(std::span<const Pose2> odometry, std::span<const LoopMeasurement> loops,
                                     double spacing) {
  std::vector<FrameIndex> frames;
  double since_last = 0.0;
  for (std::size_t k = 0; k < odometry.size(); ++k) {
    if (k > 0) since_last += std::hypot(odometry[k].x - odometry[k - 1].x, odometry[k].y - odometry[k - 1].y);
    if (k == 0 || k + 1 == odometry.size() || since_last >= spacing) {
      frames.push_back(static_cast<FrameIndex>(k));
      since_last = 0.0;
    }
  }
  for (const LoopMeasurement& m : loops) frames.push_back(m.query), frames.push_back(m.match);
  std::sort(frames.begin(), frames.end());
  frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
  return frames;
}

std::size_t node_of(const std::vector<FrameIndex>& frames, FrameIndex frame) {
  return static_cast<std::size_t>(std::lower_bound(frames.begin(), frames.end(), frame) - frames.begin());
}

}  // namespace

PoseGraph build_graph(std::span<const Pose2> odometry, std::span<const LoopMeasurement> loops,
                      const GraphOptions& options) {
  PoseGraph g;
  if (odometry.empty()) return g;
  g.node_frame = choose_nodes(odometry, loops, options.keyframe_spacing_m);
  for (const FrameIndex f : g.node_frame) g.initial.push_back(odometry[f]);
  for (std::size_t i = 1; i < g.node_frame.size(); ++i) {
    const double dt = static_cast<double>(g.node_frame[i] - g.node_frame[i - 1]) / options.fps;
    g.odometry.push_back(odometry_edge(i - 1, i, g.initial[i - 1], g.initial[i], dt, options.odometry));
  }
  for (const LoopMeasurement& m : loops)
    g.loops.push_back(
        loop_edge(node_of(g.node_frame, m.match), node_of(g.node_frame, m.query), m, options.loop));
  return g;
}

std::vector<Pose2> frames_from_nodes(const PoseGraph& graph, std::span<const Pose2> nodes,
                                     std::span<const Pose2> odometry) {
  std::vector<Pose2> frames(odometry.size());
  std::size_t node = 0;
  for (std::size_t k = 0; k < odometry.size(); ++k) {
    while (node + 1 < graph.node_frame.size() && graph.node_frame[node + 1] <= k) ++node;
    frames[k] = compose(nodes[node], between(odometry[graph.node_frame[node]], odometry[k]));
  }
  return frames;
}

std::vector<LoopMeasurement> corrupt_loops(std::span<const LoopMeasurement> loops, double fraction,
                                           std::uint64_t seed, std::span<const Pose2> places,
                                           double min_separation_m) {
  std::vector<LoopMeasurement> out(loops.begin(), loops.end());
  const auto count = static_cast<std::size_t>(std::lround(fraction * static_cast<double>(loops.size())));
  if (count == 0 || places.size() < 2) return out;
  std::mt19937_64 random(seed);
  std::vector<std::size_t> order(loops.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), random);
  std::uniform_int_distribution<std::size_t> any_frame(0, places.size() - 1);
  std::uniform_real_distribution<double> offset(-3.0, 3.0), turn(-10.0, 10.0);
  for (std::size_t n = 0; n < count; ++n) {
    LoopMeasurement& m = out[order[n]];
    // Rejection sampling; a route shorter than the separation keeps its loop.
    for (int attempt = 0; attempt < 10000; ++attempt) {
      std::size_t a = any_frame(random), b = any_frame(random);
      if (a == b) continue;
      if (a < b) std::swap(a, b);
      if (std::hypot(places[a].x - places[b].x, places[a].y - places[b].y) < min_separation_m) continue;
      m.query = static_cast<FrameIndex>(a);
      m.match = static_cast<FrameIndex>(b);
      m.relative = {offset(random), offset(random), turn(random) * kRadiansPerDegree};
      m.residual_m = loops[order[any_frame(random) % loops.size()]].residual_m;
      m.corrupted = true;
      break;
    }
  }
  return out;
}

}  // namespace markloop::posegraph
