// Paint mask, the detector's first stage: which pixels of the bird's-eye
// view are bright paint. A pixel is paint when it is brighter than the
// mean of a window around it (an integral image) and than the road of each
// quadrant of that window; then, where a line along the road crosses paint
// across it (a stop line meeting a lane line), the crossing is cut so that
// the two come apart as parts.
#pragma once

#include <cstdint>
#include <cstring>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "app/perception/birdseye.hpp"
#include "app/perception/detector/detector_config.hpp"

namespace markloop::perception {

// The first column from c on with paint in row m, or cols: paint is sparse,
// so unpainted stretches are skipped eight bytes at a time.
inline int next_painted(const std::uint8_t* m, int c, int cols) {
  for (std::uint64_t eight = 0; c + 8 <= cols; c += 8) {
    std::memcpy(&eight, m + c, sizeof eight);
    if (eight != 0) break;
  }
  while (c < cols && m[c] == 0) ++c;
  return c;
}

class PaintMask {
 public:
  // For views of rows x cols pixels of `region`.
  PaintMask(const PaintMaskConfig& config, const BirdsEyeRegion& region, int rows, int cols);

  // The paint of `bev` (CV_8UC1), judged on its `valid` pixels, whose
  // integral `valid_integral` is (ViewEdges).
  void find(const cv::Mat& bev, const cv::Mat& valid, const cv::Mat& valid_integral);
  // No paint anywhere (a view that shows no road).
  void clear();

  // CV_8UC1: 255 = paint.
  const cv::Mat& mask() const { return mask_; }

 private:
  // The junction settings in view pixels.
  struct JunctionPixels {
    int along, across;  // junction_along_m, junction_across_m
    int long_bar;       // junction_long_bar_m, at least `across`
    int margin;         // junction_cut_margin_m
    int bridge;         // junction_bridge_m
    int worn_along;     // junction_worn_along_m
    float min_fill;     // junction_min_fill; 0: unbroken runs only
  };

  void threshold(const cv::Mat& bev, const cv::Mat& valid, const cv::Mat& valid_integral);
  void veto_one_sided_paint(const cv::Mat& bev, const cv::Mat& valid);
  void integrate_road(const cv::Mat& bev, const cv::Mat& valid);
  void cut_line_junctions();
  void count_vertical_runs();
  // Marks row r's junction pixels in run_below_ (-1, or -2 beside a long
  // bar); true when it marked any.
  bool mark_junctions(int r);
  // The length (long_bar, across or 0) of a worn bar beside the run
  // [c, end) of mask row `m`.
  int worn_bar_beside(int c, int end, const std::uint8_t* m) const;
  void clear_junctions();

  PaintMaskConfig config_;
  JunctionPixels junction_{};
  int window_cols_ = 1, window_rows_ = 1;
  cv::Mat mask_;      // CV_8UC1 paint mask
  cv::Mat integral_;  // CV_32SC1 (rows+1) x (cols+1): bird's-eye sums
  // CV_8UC2 {value, 1}: the road's pixels (valid, not painted by the
  // window test), 0 elsewhere; CV_32SC2: their integral, interleaved so that
  // a quadrant's sum and count share cache lines.
  cv::Mat road_pixels_, road_integral_;
  std::vector<std::int16_t> run_above_;  // paint run length down to each pixel
  std::vector<std::int16_t> run_below_;  // ... and from it downwards
};

}  // namespace markloop::perception
