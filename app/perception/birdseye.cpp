#include "app/perception/birdseye.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace markloop::perception {

float ImageOutline::row_at(float col) const {
  if (count == 0) return std::numeric_limits<float>::infinity();
  if (col <= points[0][0]) return points[0][1];
  for (std::size_t i = 1; i < count; ++i) {
    const auto& [c0, r0] = points[i - 1];
    const auto& [c1, r1] = points[i];
    if (col <= c1) return c1 > c0 ? r0 + (r1 - r0) * (col - c0) / (c1 - c0) : r1;
  }
  return points[count - 1][1];
}

BirdsEyeView::BirdsEyeView(const CameraModel& camera, const BirdsEyeRegion& region,
                           const ImageOutline& hidden_below)
    : region_(region), source_cols_(camera.width()), source_rows_(camera.height()) {
  rows_ = std::max(1, static_cast<int>(std::lround((region.x_far_m - region.x_near_m) / region.x_step_m)));
  cols_ = std::max(1, static_cast<int>(std::lround((region.y_left_m - region.y_right_m) / region.y_step_m)));
  const std::size_t n = static_cast<std::size_t>(rows_) * static_cast<std::size_t>(cols_);
  calibrated_row_.assign(n, kNoSource);
  source_row_.assign(n, -1);
  source_col_.assign(n, 0);
  weight_x_.assign(n, 0);
  weight_y_.assign(n, 0);
  valid_ = cv::Mat::zeros(rows_, cols_, CV_8UC1);
  hidden_from_.assign(n, 0.0f);
  // Per image column: the first row of the bonnet under u or u + 1.
  std::vector<float> hidden_from_column(static_cast<std::size_t>(std::max(0, source_cols_ - 1)));
  for (std::size_t u = 0; u < hidden_from_column.size(); ++u)
    hidden_from_column[u] =
        std::min(hidden_below.row_at(static_cast<float>(u)), hidden_below.row_at(static_cast<float>(u + 1)));
  for (int r = 0; r < rows_; ++r) {
    for (int c = 0; c < cols_; ++c) {
      Eigen::Vector2d pixel;
      if (!camera.ground_to_image({ground_x(static_cast<float>(r)), ground_y(static_cast<float>(c))}, pixel))
        continue;
      // Bilinear reads (u, v) .. (u+1, v+1): all four must be road pixels.
      // Rows beyond the image are kept (a row shift may bring them in).
      if (!(pixel.x() >= 0.0 && pixel.x() < source_cols_ - 1 &&
            std::abs(pixel.y()) < static_cast<double>(INT16_MAX)))
        continue;
      const int u = static_cast<int>(pixel.x());
      const int v = static_cast<int>(std::floor(pixel.y()));
      const std::size_t i = static_cast<std::size_t>(r) * cols_ + c;
      calibrated_row_[i] = static_cast<std::int16_t>(v);
      source_col_[i] = static_cast<std::int16_t>(u);
      weight_x_[i] = static_cast<std::uint8_t>(std::min(255.0, std::floor((pixel.x() - u) * 256.0)));
      weight_y_[i] = static_cast<std::uint8_t>(std::min(255.0, std::floor((pixel.y() - v) * 256.0)));
      hidden_from_[i] = hidden_from_column[static_cast<std::size_t>(u)];
    }
  }
  set_row_shift(0, 0);
}

void BirdsEyeView::set_row_shift(int rows, int outline_rows) {
  row_shift_ = rows;
  const float outline_shift = static_cast<float>(outline_rows);
  // Run on every move of the view: one branchless pass, which vectorises.
  std::uint8_t* valid = valid_.ptr<std::uint8_t>(0);  // continuous: created here
  const std::size_t n = source_row_.size();
  const std::int16_t* calibrated_row = calibrated_row_.data();
  const float* hidden_from = hidden_from_.data();
  std::int16_t* source_row = source_row_.data();
  const int last_row = source_rows_ - 1;
  for (std::size_t i = 0; i < n; ++i) {
    const int calibrated = calibrated_row[i];
    const int v = calibrated + rows;
    const int seen = static_cast<int>(calibrated != kNoSource) & static_cast<int>(v >= 0) &
                     static_cast<int>(v < last_row) &
                     static_cast<int>(static_cast<float>(v + 1) < hidden_from[i] + outline_shift);
    source_row[i] = static_cast<std::int16_t>(seen * (v + 1) - 1);  // v, or -1 unseen
    valid[i] = static_cast<std::uint8_t>(seen * 255);
  }
}

void BirdsEyeView::warp(const cv::Mat& grey, cv::Mat& out) const {
  const std::uint8_t* src = grey.ptr<std::uint8_t>(0);
  const std::size_t stride = grey.step[0];
  for (int r = 0; r < rows_; ++r) {
    std::uint8_t* dst = out.ptr<std::uint8_t>(r);
    const std::size_t base = static_cast<std::size_t>(r) * cols_;
    for (int c = 0; c < cols_; ++c) {
      const int v = source_row_[base + c];
      if (v < 0) {
        dst[c] = 0;
        continue;
      }
      const std::uint8_t* p = src + static_cast<std::size_t>(v) * stride + source_col_[base + c];
      const int fx = weight_x_[base + c], fy = weight_y_[base + c];
      const int top = p[0] * (256 - fx) + p[1] * fx;
      const int bottom = p[stride] * (256 - fx) + p[stride + 1] * fx;
      dst[c] = static_cast<std::uint8_t>((top * (256 - fy) + bottom * fy + (1 << 15)) >> 16);
    }
  }
}

}  // namespace markloop::perception
