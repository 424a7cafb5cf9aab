#include "app/tools/posegraph/graph.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <utility>

#include "app/common/units.hpp"

namespace markloop::posegraph {

namespace {

Pose2 between(const Pose2& a, const Pose2& b) {
  return compose(inverse(a), b);
}

struct Sigmas {
  double along = 0.0, across = 0.0, yaw = 0.0;
};

// Of the odometry over d metres and dt seconds.
Sigmas odometry_sigmas(double d, double dt, const OdometryNoise& noise) {
  const double sigma_yaw = std::max(noise.yaw_rate_error_dps * kRadiansPerDegree * dt, 1e-5);
  return {noise.scale_error * d + noise.floor_m, 0.5 * d * sigma_yaw + noise.floor_m, sigma_yaw};
}

Edge odometry_edge(std::size_t from, std::size_t to, const Pose2& a, const Pose2& b, double dt,
                   const OdometryNoise& noise) {
  const Pose2 delta = between(a, b);
  const Sigmas s = odometry_sigmas(std::hypot(delta.x, delta.y), dt, noise);
  return {from, to, delta, {1.0 / s.along, 1.0 / s.across, 1.0 / s.yaw}, {}, {}};
}

// Keyframes every `spacing` metres driven and the first and last frames;
// with loop_nodes also every frame a loop names.
std::vector<FrameIndex> choose_nodes(std::span<const Pose2> odometry, std::span<const LoopMeasurement> loops,
                                     const GraphOptions& options) {
  std::vector<FrameIndex> frames;
  double since_last = 0.0;
  for (std::size_t k = 0; k < odometry.size(); ++k) {
    if (k > 0) since_last += std::hypot(odometry[k].x - odometry[k - 1].x, odometry[k].y - odometry[k - 1].y);
    if (k == 0 || k + 1 == odometry.size() || since_last >= options.keyframe_spacing_m) {
      frames.push_back(static_cast<FrameIndex>(k));
      since_last = 0.0;
    }
  }
  if (!options.loop_nodes) return frames;
  for (const LoopMeasurement& m : loops) frames.push_back(m.query), frames.push_back(m.match);
  std::sort(frames.begin(), frames.end());
  frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
  return frames;
}

// The node nearest to `frame` in frames (rising, not empty).
std::size_t nearest_node(const std::vector<FrameIndex>& frames, FrameIndex frame) {
  const auto after =
      static_cast<std::size_t>(std::lower_bound(frames.begin(), frames.end(), frame) - frames.begin());
  if (after == frames.size()) return after - 1;
  if (after == 0 || frames[after] - frame <= frame - frames[after - 1]) return after;
  return after - 1;
}

// A loop edge between the nodes nearest its frames. Its position sigma is
// the alignment residual (at least the floor) and the odometry's between
// each frame and its node, both sides added in quadrature.
Edge loop_edge(const PoseGraph& g, std::span<const Pose2> odometry, const LoopMeasurement& m,
               const GraphOptions& options) {
  Edge e;
  e.from = nearest_node(g.node_frame, m.match);
  e.to = nearest_node(g.node_frame, m.query);
  e.from_offset = between(odometry[g.node_frame[e.from]], odometry[m.match]);
  e.to_offset = between(odometry[g.node_frame[e.to]], odometry[m.query]);
  e.measured = m.relative;
  double var_xy = std::pow(std::max(m.residual_m, options.loop.floor_m), 2);
  double var_yaw = std::pow(options.loop.yaw_deg * kRadiansPerDegree, 2);
  const std::pair<std::size_t, FrameIndex> ends[] = {{e.from, m.match}, {e.to, m.query}};
  for (const auto& [node, frame] : ends) {
    const FrameIndex node_frame = g.node_frame[node];
    if (node_frame == frame) continue;
    const Pose2 offset = between(odometry[node_frame], odometry[frame]);
    const double dt = std::abs(static_cast<double>(frame) - static_cast<double>(node_frame)) / options.fps;
    const Sigmas s = odometry_sigmas(std::hypot(offset.x, offset.y), dt, options.odometry);
    var_xy += std::pow(std::max(s.along, s.across), 2);
    var_yaw += s.yaw * s.yaw;
  }
  e.sqrt_information = {1.0 / std::sqrt(var_xy), 1.0 / std::sqrt(var_xy), 1.0 / std::sqrt(var_yaw)};
  return e;
}

Pose2 scaled(Pose2 p, double scale) {
  p.x *= 1.0 + scale;
  p.y *= 1.0 + scale;
  return p;
}

}  // namespace

PoseGraph build_graph(std::span<const Pose2> odometry, std::span<const LoopMeasurement> loops,
                      const GraphOptions& options) {
  PoseGraph g;
  if (odometry.empty()) return g;
  g.node_frame = choose_nodes(odometry, loops, options);
  for (const FrameIndex f : g.node_frame) g.initial.push_back(odometry[f]);
  for (std::size_t i = 1; i < g.node_frame.size(); ++i) {
    const double dt = static_cast<double>(g.node_frame[i] - g.node_frame[i - 1]) / options.fps;
    g.odometry.push_back(odometry_edge(i - 1, i, g.initial[i - 1], g.initial[i], dt, options.odometry));
  }
  for (const LoopMeasurement& m : loops) g.loops.push_back(loop_edge(g, odometry, m, options));
  return g;
}

std::vector<Pose2> frames_from_nodes(const PoseGraph& graph, std::span<const Pose2> nodes,
                                     std::span<const Pose2> odometry, double scale) {
  std::vector<Pose2> frames(odometry.size());
  if (nodes.empty()) return frames;
  const auto placed_from = [&](std::size_t node, std::size_t k) {
    return compose(nodes[node], scaled(between(odometry[graph.node_frame[node]], odometry[k]), scale));
  };
  std::size_t node = 0;
  for (std::size_t k = 0; k < odometry.size(); ++k) {
    while (node + 1 < graph.node_frame.size() && graph.node_frame[node + 1] <= k) ++node;
    const Pose2 before = placed_from(node, k);
    if (node + 1 == graph.node_frame.size() || graph.node_frame[node] == k) {
      frames[k] = before;
      continue;
    }
    const Pose2 after = placed_from(node + 1, k);
    const Pose2& a = odometry[graph.node_frame[node]];
    const Pose2& b = odometry[graph.node_frame[node + 1]];
    const double span = std::hypot(b.x - a.x, b.y - a.y);
    const double w = span > 0.0
                         ? std::clamp(std::hypot(odometry[k].x - a.x, odometry[k].y - a.y) / span, 0.0, 1.0)
                         : static_cast<double>(k - graph.node_frame[node]) /
                               static_cast<double>(graph.node_frame[node + 1] - graph.node_frame[node]);
    frames[k] = {before.x + w * (after.x - before.x), before.y + w * (after.y - before.y),
                 wrap_angle(before.yaw + w * wrap_angle(after.yaw - before.yaw))};
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
