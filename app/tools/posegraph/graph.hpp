// The 2-D pose graph: a node per keyframe (one every few metres driven),
// odometry edges between successive nodes and loop edges between a loop's
// two frames, each frame attached to its nearest keyframe by the odometry
// between them (or, with loop_nodes, a node of its own); each edge has a
// diagonal information in its own frame. The odometry's translations may be
// scaled by (1 + s), s one extra unknown of the graph (the wheel-speed scale
// error). Also the robustness experiment's wrong loops.
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
  double scale_error = 0.01;  // relative wheel-speed (distance) error
  // A yaw-rate sensor's bias, uncalibrated, is of this order; it turns the
  // heading steadily, which loops far apart must be free to undo.
  double yaw_rate_error_dps = 0.1;  // yaw-rate error, deg/s
  double floor_m = 0.01;
};

// A loop's position sigma is its alignment residual, at least floor_m;
// its heading sigma yaw_deg.
struct LoopNoise {
  double floor_m = 0.05;
  double yaw_deg = 1.0;
};

struct GraphOptions {
  double keyframe_spacing_m = 10.0;  // 0: a node per frame
  // Every frame a loop names gets a node of its own (the first version's
  // graph); otherwise it is attached to its nearest keyframe.
  bool loop_nodes = false;
  double fps = 10.0;
  OdometryNoise odometry;
  LoopNoise loop;
};

// Joins frame `from_offset` of node `from` (the odometry from that node's
// frame to the edge's frame, whose translation is scaled with the rest of
// the odometry) to frame `to_offset` of node `to`. An odometry edge has
// identity offsets and scales its measured translation; a loop edge's
// measured pose is not scaled.
struct Edge {
  std::size_t from = 0, to = 0;              // node indices
  Pose2 measured;                            // `to` in the frame of `from`
  std::array<double, 3> sqrt_information{};  // 1 / sigma of x, y, yaw
  Pose2 from_offset, to_offset;              // loop edges only
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

// A pose per frame from the optimised nodes: a frame between two nodes is
// placed from each by the odometry between them (its translation scaled by
// 1 + scale), and the two placements blended by the frame's share of the
// distance between the nodes, so the trajectory has no jump.
std::vector<Pose2> frames_from_nodes(const PoseGraph& graph, std::span<const Pose2> nodes,
                                     std::span<const Pose2> odometry, double scale = 0.0);

// Replaces round(fraction * loops) of the loops, chosen at random, by wrong
// ones: a random pair of frames whose `places` (truth, else odometry) lie at
// least min_separation_m apart, given a plausible relative pose (within
// 3 m and 10 degrees) and the residual of a real loop. Deterministic in seed.
std::vector<LoopMeasurement> corrupt_loops(std::span<const LoopMeasurement> loops, double fraction,
                                           std::uint64_t seed, std::span<const Pose2> places,
                                           double min_separation_m = 100.0);

}  // namespace markloop::posegraph
