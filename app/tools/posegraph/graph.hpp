// The 2-D pose graph: a node per keyframe (one every few metres, and every
// frame a loop names), odometry edges between successive nodes and loop
// edges between a loop's two frames, each with a diagonal information in
// the edge's own frame. Also the robustness experiment's wrong loops.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "app/engine/types.hpp"
#include "app/tools/posegraph/inputs.hpp"

namespace markloop::posegraph {

// Standard deviations of an odometry edge of length d metres over dt
// seconds: along the car, scale_error * d + floor; heading,
// yaw_rate_error * dt; across the car, the heading error's sway over d
// (d * sigma_yaw / 2) + floor.
struct OdometryNoise {
  double scale_error = 0.01;         // relative wheel-speed (distance) error
  double yaw_rate_error_dps = 0.05;  // yaw-rate error, deg/s
  double floor_m = 0.01;
};

// A loop's position sigma is its alignment residual, at least floor_m;
// its heading sigma yaw_deg.
struct LoopNoise {
  double floor_m = 0.05;
  double yaw_deg = 1.0;
};

struct GraphOptions {
  double keyframe_spacing_m = 2.0;  // 0: a node per frame
  double fps = 10.0;
  OdometryNoise odometry;
  LoopNoise loop;
};

struct Edge {
  std::size_t from = 0, to = 0;              // node indices
  Pose2 measured;                            // `to` in the frame of `from`
  std::array<double, 3> sqrt_information{};  // 1 / sigma of x, y, yaw
};

struct PoseGraph {
  std::vector<FrameIndex> node_frame;  // rising
  std::vector<Pose2> initial;          // the odometry's pose of each node
  std::vector<Edge> odometry;
  std::vector<Edge> loops;  // in the order of the measurements
};

// Builds the graph over `odometry` (a pose per frame). Every loop's frames
// must lie within it.
PoseGraph build_graph(std::span<const Pose2> odometry, std::span<const LoopMeasurement> loops,
                      const GraphOptions& options);

// A pose per frame from the optimised nodes: each frame keeps its odometry
// offset from the node at or before it.
std::vector<Pose2> frames_from_nodes(const PoseGraph& graph, std::span<const Pose2> nodes,
                                     std::span<const Pose2> odometry);

// Replaces round(fraction * loops) of the loops, chosen at random, by wrong
// ones: a random pair of frames whose `places` (truth, else odometry) lie at
// least min_separation_m apart, given a plausible relative pose (within
// 3 m and 10 degrees) and the residual of a real loop. Deterministic in seed.
std::vector<LoopMeasurement> corrupt_loops(std::span<const LoopMeasurement> loops, double fraction,
                                           std::uint64_t seed, std::span<const Pose2> places,
                                           double min_separation_m = 100.0);

}  // namespace markloop::posegraph
