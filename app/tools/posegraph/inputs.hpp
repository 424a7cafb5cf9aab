// What markloop-posegraph reads: the car's odometry per camera frame from
// the VehicleOdometry log (integrated by the ECU's own OdometryIntegrator),
// the loops from the ECU's LoopDetection log or from markloop-replay's
// JSONL, and a truth trajectory (frames.csv, KITTI or TUM). Errors read
// "FILE:LINE: what" or "FILE: what".
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "app/common/result.hpp"
#include "app/ecu/odometry.hpp"
#include "app/engine/types.hpp"

namespace markloop::posegraph {

// The ECU's odometry timeout (config odometry_timeout_ms): three cycles.
inline constexpr double kOdometryTimeout_s = 0.060;

struct OdometryTrack {
  std::vector<Pose2> poses;             // frame k at t = k / fps, in the odometry's frame
  std::size_t frames_without_pose = 0;  // odometry missing or timed out there
  ecu::OdometryCounters counters;
  std::uint64_t other_frames = 0;  // frames of other ids in the log
};

// The VehicleOdometry frames of a candump -l log, stamped on the
// recording's clock (frame k at k / fps): the pose at every frame time from
// 0 to the last stamp, as the ECU computes it (the frames up to a frame's
// time integrated, then extrapolated to it).
Result<OdometryTrack> read_odometry_log(const std::string& path, double fps);

// One loop closure: the car at `query` seen from the car at `match`
// (inverse(pose[match]) o pose[query]), and how well it was aligned.
struct LoopMeasurement {
  FrameIndex query = 0;
  FrameIndex match = 0;
  Pose2 relative;
  double residual_m = 0.0;  // RMS residual of the landmark alignment
  bool corrupted = false;   // put in by --corrupt-loops
};

// The ECU's measure of the odometry's scale (Status page Odometry, its last
// valid value): odometry metres per true metre.
struct CameraScale {
  double scale = 1.0;
  double standard_error = 0.0;
};

struct LoopInput {
  std::vector<LoopMeasurement> loops;
  std::optional<CameraScale> camera_scale;  // none in a replay's JSONL
  std::size_t without_pose = 0;             // PoseValid clear / no relative_pose: skipped
  std::size_t incomplete = 0;               // pages missing or out of order: skipped
  std::size_t rejected_frames = 0;          // LoopDetection frames failing E2E checks
};

// The ECU's --can-out log. A loop naming a frame at or beyond frame_count
// is an error ("FILE:LINE: ..."), as is a log cut short.
Result<LoopInput> read_ecu_loops(const std::string& path, std::size_t frame_count);
// markloop-replay --jsonl: one match per line (query_frame, match_frame,
// relative_pose {dx, dy, dyaw_deg}, residual_m).
Result<LoopInput> read_replay_jsonl(const std::string& path, std::size_t frame_count);

// A truth or trajectory file: frames.csv (header frame,t,...), TUM (8
// numbers a line: times become frames, frame = round(t * fps)) or KITTI
// (line k is frame k). Frames the file does not hold are absent (nullopt
// poses are not stored: `known[k]` false).
struct Truth {
  std::vector<Pose2> poses;
  std::vector<bool> known;
};
Result<Truth> load_truth(const std::string& path, double fps);

}  // namespace markloop::posegraph
