// Trajectories as files and as curves to compare: TUM ("t x y z qx qy qz
// qw") and KITTI (3x4 [R|t], camera axes as the paper's files) writers, a
// strict TUM reader, and the rigid 2-D alignment of one trajectory onto
// another that ATE is measured after. Shared by markloop-posegraph (writes
// and scores them) and markloop-eval (draws a corrected one).
#pragma once

#include <span>
#include <string>
#include <vector>

#include "app/common/result.hpp"
#include "app/engine/types.hpp"

namespace markloop::tools {

struct TimedPose {
  double t = 0.0;  // seconds
  Pose2 pose;
};

// One line per pose, pose k at t = k / fps, z = 0, yaw as a quaternion about z.
// An error "PATH: cannot write: why".
Status write_tum(const std::string& path, std::span<const Pose2> poses, double fps);
// One 3x4 row-major camera pose per line (x right, y down, z ahead), as
// markloop-sim's poses.txt and replay::load_kitti_poses read.
Status write_kitti(const std::string& path, std::span<const Pose2> poses);

// A TUM file: "#" comments and blank lines skipped, 8 numbers per line, a
// unit quaternion; times rising. "FILE:LINE: what" on a bad line.
Result<std::vector<TimedPose>> load_tum(const std::string& path);

// The rigid transform T (rotation and translation in the plane, no scale)
// minimising sum |T(from[i]) - to[i]|^2 over the positions (Umeyama / Horn
// in 2-D). Both spans the same size; identity when it is below 2.
Pose2 align_se2(std::span<const Pose2> from, std::span<const Pose2> to);
// Every pose of `poses` moved by `transform` (compose(transform, p)).
std::vector<Pose2> transformed(std::span<const Pose2> poses, const Pose2& transform);

}  // namespace markloop::tools
