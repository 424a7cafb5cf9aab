// The picture of a correction, as SVG: the truth (when known), the odometry,
// the corrected trajectory and the loop edges (green used, red rejected by
// the robust loss), all in the truth's frame (each trajectory rigidly
// aligned to it), else in the odometry's frame.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "app/common/result.hpp"
#include "app/engine/types.hpp"
#include "app/tools/posegraph/inputs.hpp"

namespace markloop::posegraph {

struct PictureContent {
  std::span<const Pose2> truth;  // empty without --truth
  std::span<const Pose2> odometry;
  std::span<const Pose2> corrected;
  std::span<const LoopMeasurement> loops;
  std::vector<bool> loop_rejected;
  std::string title;
};

// "PATH: cannot write: why" on failure.
Status write_picture_svg(const std::string& path, const PictureContent& content);

}  // namespace markloop::posegraph
