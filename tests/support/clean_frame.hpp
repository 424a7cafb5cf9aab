// A frame the simulator renders at a pose without sensor noise, vehicles
// ahead or shadows: what the detector sees of the markings alone.
#pragma once

#include <opencv2/core.hpp>

#include "sim/render.hpp"

namespace markloop::sim {

inline cv::Mat clean_frame(Renderer& renderer, const Pose2& pose) {
  Conditions c;
  c.noise_sigma = 0.0;
  c.occluder_probability = 0.0;
  c.shadows = false;
  cv::Mat image;
  renderer.render(pose, 10.0, c, 0, {}, image);
  return image;
}

}  // namespace markloop::sim
