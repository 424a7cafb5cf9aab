// Bird's-eye (inverse perspective) view of a rectangle of road in front of
// the vehicle. The lookup table (source offset and bilinear weights per
// output pixel) is computed once from the camera model; warping a frame is
// then a table walk, with no allocation.
//
// Output layout: row 0 is the far edge (x_far_m), the last row the near edge;
// column 0 is the left edge (y_left_m), the last column the right edge.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "app/perception/camera_model.hpp"

namespace markloop::perception {

struct BirdsEyeRegion {
  float x_near_m = 3.0f;  // ahead of the vehicle reference point
  float x_far_m = 20.0f;
  float y_left_m = 9.0f;  // left of the vehicle reference point
  float y_right_m = -9.0f;
  float x_step_m = 0.05f;  // metres per output row (along the road)
  float y_step_m = 0.04f;  // metres per output column (across the road)
};

// The car's own body (the bonnet) as the camera sees it: image pixels at or
// below this outline are not road. A polyline of (column, row) points, left
// to right, linear between them and flat beyond the ends; no points: the
// whole image may be road.
struct ImageOutline {
  static constexpr std::size_t kMaxPoints = 16;
  std::array<std::array<float, 2>, kMaxPoints> points{};
  std::size_t count = 0;

  // The outline's row at an image column; +infinity when there is none.
  float row_at(float col) const;
};

class BirdsEyeView {
 public:
  // Output pixels that would read the image at or below `hidden_below`, or
  // outside the image, or above the horizon, are invalid (value 0).
  BirdsEyeView(const CameraModel& camera, const BirdsEyeRegion& region,
               const ImageOutline& hidden_below = {});

  int rows() const { return rows_; }
  int cols() const { return cols_; }
  const BirdsEyeRegion& region() const { return region_; }
  // 255 where the output pixel sees road in the image, 0 elsewhere.
  const cv::Mat& valid() const { return valid_; }

  // `grey`: CV_8UC1 of the camera's size (checked by the caller);
  // `out`: CV_8UC1 rows() x cols(), preallocated.
  void warp(const cv::Mat& grey, cv::Mat& out) const;

  // Reads the image `rows` lower (negative: higher) than the calibration
  // says: the road's horizon is that many rows lower in the image, as when
  // the camera is pitched up by about rows / focal length. The bonnet
  // outline moves by `outline_rows` (the same when the camera's mount
  // moved, none when the car pitched). Recomputes valid(); no allocation.
  void set_row_shift(int rows, int outline_rows);
  int row_shift() const { return row_shift_; }

  // True when the output pixel is unseen because its source lies on the
  // bonnet or below the image's last row (not beyond the image's sides or
  // top): the road the car is about to drive over.
  bool unseen_below(int row, int col) const {
    const std::size_t i = static_cast<std::size_t>(row) * cols_ + col;
    return source_row_[i] < 0 && calibrated_row_[i] != kNoSource && calibrated_row_[i] + row_shift_ >= 0;
  }

  // Ground point (vehicle frame, metres) of an output pixel position
  // (fractional: pixel centres are at integers).
  float ground_x(float row) const { return region_.x_far_m - (row + 0.5f) * region_.x_step_m; }
  float ground_y(float col) const { return region_.y_left_m - (col + 0.5f) * region_.y_step_m; }

 private:
  BirdsEyeRegion region_;
  int rows_ = 0, cols_ = 0;
  int source_cols_ = 0, source_rows_ = 0;
  // Per output pixel: the top-left source pixel the calibration gives
  // (kNoSource: none, or not in the image's columns), and the one read at
  // the current row shift (row -1: invalid); bilinear weights in 1/256 (fx, fy).
  static constexpr std::int16_t kNoSource = INT16_MIN;
  std::vector<std::int16_t> calibrated_row_;
  std::vector<std::int16_t> source_row_, source_col_;
  // Per output pixel: the first row of the bonnet under its source columns
  // u and u + 1 (read per pixel, so that set_row_shift() has no lookup).
  std::vector<float> hidden_from_;
  int row_shift_ = 0;
  std::vector<std::uint8_t> weight_x_, weight_y_;
  cv::Mat valid_;
};

}  // namespace markloop::perception
