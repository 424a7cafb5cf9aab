// Synthetic camera frames for the detector tests: a flat grey road with a
// fixed texture, and white paint (rectangles along the road, or lines at any
// angle) placed on the ground in the vehicle frame, drawn through the camera
// model (so distortion and perspective are the detector's own).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "app/perception/camera_model.hpp"

namespace markloop::perception::testing {

struct GroundRect {
  double x0, x1;  // along the road, metres ahead
  double y0, y1;  // across, metres left

  bool covers(const Eigen::Vector2d& g) const {
    return g.x() >= x0 && g.x() <= x1 && g.y() >= y0 && g.y() <= y1;
  }
};

// A painted line from (x0, y0) to (x1, y1), `width` metres wide.
struct GroundLine {
  double x0, y0, x1, y1;
  double width = 0.15;

  bool covers(const Eigen::Vector2d& g) const {
    const Eigen::Vector2d a(x0, y0), b(x1, y1);
    const double t = std::clamp((g - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    return (g - (a + t * (b - a))).norm() <= 0.5 * width;
  }
};

// The road with paint wherever is_paint(ground point) says, and in shadow
// (road_grey scaled by shadow_factor) wherever in_shadow says.
template <typename IsPaint, typename InShadow>
cv::Mat render_road_shaded(const CameraModel& camera, IsPaint is_paint, InShadow in_shadow,
                           int road_grey = 70, int paint_grey = 200, double shadow_factor = 1.0) {
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
      const std::uint32_t h =
          (static_cast<std::uint32_t>(u) * 73856093u) ^ (static_cast<std::uint32_t>(v) * 19349663u);
      const int road = in_shadow(g) ? static_cast<int>(road_grey * shadow_factor) : road_grey;
      const int value = is_paint(g) ? paint_grey : road + static_cast<int>(h % 13u) - 6;
      row[u] = static_cast<std::uint8_t>(value);
    }
  }
  return image;
}

// The road with paint wherever is_paint(ground point) says.
template <typename IsPaint>
cv::Mat render_road_where(const CameraModel& camera, IsPaint is_paint, int road_grey = 70,
                          int paint_grey = 200) {
  return render_road_shaded(
      camera, is_paint, [](const Eigen::Vector2d&) { return false; }, road_grey, paint_grey);
}

inline cv::Mat render_road(const CameraModel& camera, const std::vector<GroundRect>& paint,
                           int road_grey = 70, int paint_grey = 200) {
  return render_road_where(
      camera,
      [&](const Eigen::Vector2d& g) {
        return std::any_of(paint.begin(), paint.end(), [&](const GroundRect& r) { return r.covers(g); });
      },
      road_grey, paint_grey);
}

inline cv::Mat render_road_lines(const CameraModel& camera, const std::vector<GroundLine>& lines,
                                 const std::vector<GroundRect>& blocks = {}) {
  return render_road_where(camera, [&](const Eigen::Vector2d& g) {
    return std::any_of(lines.begin(), lines.end(), [&](const GroundLine& l) { return l.covers(g); }) ||
           std::any_of(blocks.begin(), blocks.end(), [&](const GroundRect& r) { return r.covers(g); });
  });
}

// Not a road: frame k of a camera gone wrong (a failing sensor,
// interference on its link): uniform noise in the even frames, checkerboards
// of 1 to 4 pixels in the odd ones. The detector takes every one for noise
// (ViewKind::Noisy) and does not search it.
inline cv::Mat garbage_frame(const CameraModel& camera, int k) {
  cv::Mat image(camera.height(), camera.width(), CV_8UC1);
  if (k % 2 == 0) {
    cv::RNG rng(static_cast<std::uint64_t>(9001 + k));  // the same frames every run
    rng.fill(image, cv::RNG::UNIFORM, 0, 256);
    return image;
  }
  const int cell = 1 + (k / 2) % 4;
  for (int r = 0; r < image.rows; ++r) {
    auto* row = image.ptr<std::uint8_t>(r);
    for (int c = 0; c < image.cols; ++c) row[c] = ((r / cell + c / cell) % 2) != 0 ? 230 : 40;
  }
  return image;
}

// A road with paint everywhere, in pieces a marking's size (tiles 0.6 to
// 0.8 m square, 0.5 to 0.8 m apart, by k): a car park's tiles, a road under
// repair, a camera taking a painted wall for the road. It passes for a road,
// and 12 of k = 0..19 have more pieces than the detector's cap on the
// candidates it classifies (the simulator's camera): its worst case.
inline cv::Mat clutter_frame(const CameraModel& camera, int k) {
  const double side = 0.6 + 0.1 * (k % 3), period = side + 0.5 + 0.1 * (k % 4);
  return render_road_where(camera, [&](const Eigen::Vector2d& g) {
    return g.x() - period * std::floor(g.x() / period) < side &&
           g.y() - period * std::floor(g.y() / period) < side;
  });
}

}  // namespace markloop::perception::testing
