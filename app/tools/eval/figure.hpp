// The picture of a run, after the paper's Fig. 3: the route driven, the
// world's markings coloured by class, and every loop detection as a line
// joining the true positions of its two frames (green correct, red wrong).
// Written as SVG (text, by hand) and PNG (OpenCV).
#pragma once

#include <string>
#include <vector>

#include "app/common/result.hpp"
#include "app/engine/types.hpp"
#include "app/tools/eval/inputs.hpp"
#include "app/tools/eval/scoring.hpp"

namespace markloop::eval {

struct FigureContent {
  const std::vector<Pose2>* route = nullptr;  // true pose per frame
  const std::vector<WorldMarking>* markings = nullptr;
  const std::vector<LoopOutcome>* loops = nullptr;
  std::string title;
  std::string subtitle;
  // A corrected trajectory (markloop-posegraph's after.tum) already aligned
  // to the truth; drawn when set.
  const std::vector<Pose2>* corrected = nullptr;
};

// A TUM trajectory (time in the drive's clock) as a pose per frame of the
// route, each at the frame's time in `times` (nearest within half a frame),
// rigidly aligned to the route. "FILE:LINE: what" on a bad file; an error
// when it shares fewer than 2 frames with the route.
Result<std::vector<Pose2>> corrected_on_route(const std::string& path, const std::vector<Pose2>& route,
                                              const std::vector<double>& times);

// Each returns an error ("PATH: why") when the file cannot be written.
Status write_svg(const std::string& path, const FigureContent& content);
Status write_png(const std::string& path, const FigureContent& content);

}  // namespace markloop::eval
