// Synthetic camera frames for the detector tests: a flat grey road with a
// fixed texture, and white paint rectangles placed on the ground in the
// vehicle frame, drawn through the camera model (so distortion and
// perspective are the detector's own).
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "perception/camera_model.hpp"

namespace markloop::perception::testing {

struct GroundRect {
  double x0, x1;  // along the road, metres ahead
  double y0, y1;  // across, metres left
};

inline cv::Mat render_road(const CameraModel& camera, const std::vector<GroundRect>& paint,
                           int road_grey = 70, int paint_grey = 200) {
  cv::Mat image(camera.height(), camera.width(), CV_8UC1);
  for (int v = 0; v < image.rows; ++v) {
    auto* row = image.ptr<std::uint8_t>(v);
    for (int u = 0; u < image.cols; ++u) {
      Eigen::Vector2d g;
      if (!camera.image_to_ground({u, v}, g)) {
        row[u] = 150;  // sky
        continue;
      }
      // Deterministic asphalt texture of +-6 grey levels.
      const std::uint32_t h = (static_cast<std::uint32_t>(u) * 73856093u) ^
                              (static_cast<std::uint32_t>(v) * 19349663u);
      int value = road_grey + static_cast<int>(h % 13u) - 6;
      for (const GroundRect& r : paint)
        if (g.x() >= r.x0 && g.x() <= r.x1 && g.y() >= r.y0 && g.y() <= r.y1) value = paint_grey;
      row[u] = static_cast<std::uint8_t>(value);
    }
  }
  return image;
}

}  // namespace markloop::perception::testing
