#include "app/perception/detector/marking_locator.hpp"

#include <array>

namespace markloop::perception {

MarkingLocator::MarkingLocator(const CameraModel& camera, const BirdsEyeView& view,
                               const BirdsEyeRegion& region)
    : camera_(camera), view_(view), region_(region) {}

MarkingLocator::GroundBox MarkingLocator::ground_box(const Candidate& candidate) const {
  return {view_.ground_x(static_cast<float>(candidate.row0) - 0.5f),
          view_.ground_x(static_cast<float>(candidate.row1) + 0.5f),
          view_.ground_y(static_cast<float>(candidate.col0) - 0.5f),
          view_.ground_y(static_cast<float>(candidate.col1) + 0.5f)};
}

void MarkingLocator::locate(const Candidate& candidate, Detection& out) const {
  const auto [far, near, left, right] = ground_box(candidate);
  // The dataset's corner order: near left, near right, far right, far left.
  const std::array<std::array<float, 2>, 4> corners = {
      {{near, left}, {near, right}, {far, right}, {far, left}}};
  for (std::size_t i = 0; i < 4; ++i) {
    Eigen::Vector2d pixel(-1.0, -1.0);
    camera_.ground_to_image({corners[i][0], corners[i][1]}, pixel);
    out.quad[i] = {static_cast<float>(pixel.x()),
                   static_cast<float>(pixel.y()) + static_cast<float>(view_.row_shift())};
  }
  out.ground_x = 0.5f * (near + far);
  out.ground_y = 0.5f * (left + right);
}

bool MarkingLocator::beyond_region(const Candidate& candidate) const {
  // The centre as locate() gives it.
  const auto [far, near, left, right] = ground_box(candidate);
  const float x = 0.5f * (near + far), y = 0.5f * (left + right);
  return x > region_.x_far_m || y > region_.y_left_m || y < region_.y_right_m;
}

}  // namespace markloop::perception
