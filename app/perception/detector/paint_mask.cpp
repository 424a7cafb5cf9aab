#include "app/perception/detector/paint_mask.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace markloop::perception {
namespace {

// Whether `value` is brighter than the mean of `count` pixels summing to
// `sum` by contrast_q8 / 256 grey levels or ratio_q8 / 256 of the mean,
// whichever is larger; in integers scaled by count and 256 (no division;
// 255 * 256 * count stays below 2^31 for count < 2^15). Branch-free, so
// the threshold's loop vectorises.
inline bool brighter_than_mean(std::int32_t value, std::int32_t sum, std::int32_t count,
                               std::int32_t contrast_q8, std::int32_t ratio_q8) {
  const std::int32_t margin = std::max(contrast_q8 * count, ratio_q8 * sum);
  return value * count * 256 > sum * 256 + margin;
}

int odd_at_least_3(float value) {
  const int n = std::max(3, static_cast<int>(std::lround(value)));
  return n | 1;
}

int pixels(float metres, float step_m) {
  return static_cast<int>(std::lround(metres / step_m));
}

}  // namespace

PaintMask::PaintMask(const PaintMaskConfig& config, const BirdsEyeRegion& region, int rows, int cols)
    : config_(config) {
  window_cols_ = odd_at_least_3(config.local_window_m / region.y_step_m);
  window_rows_ = odd_at_least_3(config.local_window_m / region.x_step_m);
  junction_.along = std::max(2, pixels(config.junction_along_m, region.x_step_m));
  junction_.across = std::max(2, pixels(config.junction_across_m, region.y_step_m));
  junction_.long_bar = std::max(junction_.across, pixels(config.junction_long_bar_m, region.y_step_m));
  junction_.margin = std::max(1, pixels(config.junction_cut_margin_m, region.x_step_m));
  junction_.bridge = pixels(config.junction_bridge_m, region.y_step_m);
  junction_.worn_along = pixels(config.junction_worn_along_m, region.x_step_m);
  junction_.min_fill = config.junction_min_fill;
  mask_.create(rows, cols, CV_8UC1);
  mask_.setTo(0);
  integral_.create(rows + 1, cols + 1, CV_32SC1);
  integral_.setTo(0);
  road_pixels_.create(rows, cols, CV_8UC2);
  road_integral_.create(rows + 1, cols + 1, CV_32SC2);
  road_integral_.setTo(cv::Scalar::all(0));
  const std::size_t count = static_cast<std::size_t>(rows) * cols;
  run_above_.assign(count, 0);
  run_below_.assign(count, 0);
}

void PaintMask::find(const cv::Mat& bev, const cv::Mat& valid, const cv::Mat& valid_integral) {
  threshold(bev, valid, valid_integral);
  if (config_.quadrant_min_contrast > 0) veto_one_sided_paint(bev, valid);
  cut_line_junctions();
}

void PaintMask::clear() {
  for (int r = 0; r < mask_.rows; ++r) std::fill_n(mask_.ptr<std::uint8_t>(r), mask_.cols, std::uint8_t{0});
}

void PaintMask::threshold(const cv::Mat& bev, const cv::Mat& valid, const cv::Mat& valid_integral) {
  const int rows = bev.rows, cols = bev.cols;
  cv::integral(bev, integral_, CV_32S);  // into the buffer sized at start-up
  const int half_r = window_rows_ / 2, half_c = window_cols_ / 2;
  // Paint: value > mean + max(contrast, ratio * mean).
  const std::int32_t ratio_q8 = static_cast<std::int32_t>(std::lround(config_.min_contrast_ratio * 256.0f));
  const std::int32_t contrast_q8 = config_.min_contrast * 256;
  for (int r = 0; r < rows; ++r) {
    const int r0 = std::max(0, r - half_r), r1 = std::min(rows, r + half_r + 1);
    const std::int32_t* sum_top = integral_.ptr<std::int32_t>(r0);
    const std::int32_t* sum_bottom = integral_.ptr<std::int32_t>(r1);
    const std::int32_t* count_top = valid_integral.ptr<std::int32_t>(r0);
    const std::int32_t* count_bottom = valid_integral.ptr<std::int32_t>(r1);
    const std::uint8_t* in = bev.ptr<std::uint8_t>(r);
    const std::uint8_t* v = valid.ptr<std::uint8_t>(r);
    std::uint8_t* out = mask_.ptr<std::uint8_t>(r);
    const auto decide = [&](int c, int c0, int c1) {
      const std::int32_t count = count_bottom[c1] - count_bottom[c0] - count_top[c1] + count_top[c0];
      const std::int32_t sum = sum_bottom[c1] - sum_bottom[c0] - sum_top[c1] + sum_top[c0];
      // Bitwise, not short-circuit: no branch, so the loop vectorises.
      const int paint = static_cast<int>(v[c] != 0) &
                        static_cast<int>(brighter_than_mean(in[c], sum, count, contrast_q8, ratio_q8));
      out[c] = static_cast<std::uint8_t>(paint * 255);
    };
    // Where the window lies wholly inside the row its bounds are fixed
    // offsets, and the loop vectorises; the borders clamp them.
    const int inner_begin = std::min(cols, half_c), inner_end = std::max(inner_begin, cols - half_c);
    for (int c = 0; c < inner_begin; ++c) decide(c, 0, std::min(cols, c + half_c + 1));
    for (int c = inner_begin; c < inner_end; ++c) decide(c, c - half_c, c + half_c + 1);
    for (int c = inner_end; c < cols; ++c) decide(c, std::max(0, c - half_c), cols);
  }
}

void PaintMask::integrate_road(const cv::Mat& bev, const cv::Mat& valid) {
  // Integral of the road, i.e. of the pixels less the paint found so far (its
  // values and its count), so that a quadrant that an arrow's head fills is
  // judged by the road around the head, not by the head. threshold() paints
  // valid pixels only: the road is what is valid and not painted.
  const int rows = bev.rows, cols = bev.cols;
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* in = bev.ptr<std::uint8_t>(r);
    const std::uint8_t* m = mask_.ptr<std::uint8_t>(r);
    const std::uint8_t* v = valid.ptr<std::uint8_t>(r);
    std::uint8_t* road = road_pixels_.ptr<std::uint8_t>(r);
    for (int c = 0; c < cols; ++c) {
      const std::uint8_t is_road = static_cast<std::uint8_t>((v[c] != 0) & (m[c] == 0));
      road[2 * c] = static_cast<std::uint8_t>(in[c] * is_road);
      road[2 * c + 1] = is_road;
    }
  }
  cv::integral(road_pixels_, road_integral_, CV_32S);
}

void PaintMask::veto_one_sided_paint(const cv::Mat& bev, const cv::Mat& valid) {
  const int rows = bev.rows, cols = bev.cols;
  integrate_road(bev, valid);
  const int half_r = window_rows_ / 2, half_c = window_cols_ / 2;
  const std::int32_t ratio_q8 =
      static_cast<std::int32_t>(std::lround(config_.quadrant_min_contrast_ratio * 256.0f));
  const std::int32_t contrast_q8 = config_.quadrant_min_contrast * 256;
  // A quadrant with little road (the view's edge, paint) says too little
  // about the road there to veto anything.
  const std::int32_t min_count = std::max(1, (half_r + 1) * (half_c + 1) / 4);
  for (int r = 0; r < rows; ++r) {
    std::uint8_t* out = mask_.ptr<std::uint8_t>(r);
    const std::uint8_t* in = bev.ptr<std::uint8_t>(r);
    // The quadrants' rows: [r - half_r, r] and [r, r + half_r], clamped.
    const cv::Vec2i* row_bounds[2][2] = {
        {road_integral_.ptr<cv::Vec2i>(std::max(0, r - half_r)), road_integral_.ptr<cv::Vec2i>(r + 1)},
        {road_integral_.ptr<cv::Vec2i>(r), road_integral_.ptr<cv::Vec2i>(std::min(rows, r + half_r + 1))}};
    for (int c = next_painted(out, 0, cols); c < cols; c = next_painted(out, c + 1, cols)) {
      const int col_bounds[2][2] = {{std::max(0, c - half_c), c + 1}, {c, std::min(cols, c + half_c + 1)}};
      for (const auto& rb : row_bounds) {
        for (const auto& cb : col_bounds) {
          const cv::Vec2i road = rb[1][cb[1]] - rb[1][cb[0]] - rb[0][cb[1]] + rb[0][cb[0]];
          if (road[1] < min_count) continue;
          if (!brighter_than_mean(in[c], road[0], road[1], contrast_q8, ratio_q8)) out[c] = 0;
        }
      }
    }
  }
}

void PaintMask::cut_line_junctions() {
  count_vertical_runs();
  // Junction pixels: on a long vertical run and on a long horizontal run.
  // They are marked in run_below_ (as -1) first and cleared with their
  // 8-neighbours afterwards, so that no diagonal contact survives. Where the
  // paint across is a long bar (a stop line, not an arrow's head), they are
  // marked -2 and the cut reaches `margin` rows further along the line: a
  // slanted or blurred edge of the bar would otherwise join them again.
  bool any = false;
  for (int r = 0; r < mask_.rows; ++r) any = mark_junctions(r) || any;
  if (any) clear_junctions();
}

void PaintMask::count_vertical_runs() {
  const int rows = mask_.rows, cols = mask_.cols;
  // Vertical run lengths, saturating (int16): from above, then from below.
  // `previous` is the run one row back (none for the first row); written
  // without branches so that the loop vectorises.
  const auto extend_runs = [cols](const std::uint8_t* m, const std::int16_t* previous, std::int16_t* here) {
    if (previous == nullptr) {
      for (int c = 0; c < cols; ++c) here[c] = static_cast<std::int16_t>(m[c] != 0);
      return;
    }
    for (int c = 0; c < cols; ++c)
      here[c] = static_cast<std::int16_t>((m[c] != 0) * std::min(previous[c] + 1, 30000));
  };
  for (int r = 0; r < rows; ++r) {
    std::int16_t* here = run_above_.data() + static_cast<std::size_t>(r) * cols;
    extend_runs(mask_.ptr<std::uint8_t>(r), r > 0 ? here - cols : nullptr, here);
  }
  for (int r = rows - 1; r >= 0; --r) {
    std::int16_t* here = run_below_.data() + static_cast<std::size_t>(r) * cols;
    extend_runs(mask_.ptr<std::uint8_t>(r), r + 1 < rows ? here + cols : nullptr, here);
  }
}

bool PaintMask::mark_junctions(int r) {
  const int cols = mask_.cols;
  const std::uint8_t* m = mask_.ptr<std::uint8_t>(r);
  const std::int16_t* above = run_above_.data() + static_cast<std::size_t>(r) * cols;
  std::int16_t* below = run_below_.data() + static_cast<std::size_t>(r) * cols;
  const bool worn_bars = junction_.min_fill > 0.0f;
  bool any = false;
  int c = 0;
  while ((c = next_painted(m, c, cols)) < cols) {
    int end = c;
    while (end < cols && m[end] != 0) ++end;
    const bool unbroken = end - c >= junction_.across;
    int beside = 0;
    if (!unbroken && worn_bars) {
      bool on_line = false;
      for (int k = c; k < end && !on_line; ++k) on_line = above[k] + below[k] - 1 >= junction_.worn_along;
      if (on_line) beside = worn_bar_beside(c, end, m);
    }
    if (unbroken || beside > 0) {
      const std::int16_t mark = std::max(end - c, beside) >= junction_.long_bar ? -2 : -1;
      const int line_length = unbroken ? junction_.along : junction_.worn_along;
      for (int k = c; k < end; ++k)
        if (above[k] + below[k] - 1 >= line_length) {
          below[k] = mark;
          any = true;
        }
    }
    c = end;
  }
  return any;
}

int PaintMask::worn_bar_beside(int c, int end, const std::uint8_t* m) const {
  // A stretch at least min_fill paint starting within `bridge` of the run.
  // Asked only of runs on a line (few per row), and most of those have road
  // beside them.
  const int cols = mask_.cols, bridge = junction_.bridge;
  const float min_fill = junction_.min_fill;
  const auto filled = [&](int from, int to) {  // [from, to) inside the row
    int paint = 0;
    for (int k = from; k < to; ++k) paint += m[k] != 0;
    return static_cast<float>(paint) >= min_fill * static_cast<float>(to - from);
  };
  int right = end;  // the first paint after the run, within the bridge
  while (right < cols && right - end < bridge && m[right] == 0) ++right;
  int left = c - 1;  // the last paint before it
  while (left >= 0 && c - 1 - left < bridge && m[left] == 0) --left;
  const bool paint_right = right < cols && m[right] != 0;
  const bool paint_left = left >= 0 && m[left] != 0;
  for (const int length : {junction_.long_bar, junction_.across}) {
    if (paint_right && right + length <= cols && filled(right, right + length)) return length;
    if (paint_left && left + 1 - length >= 0 && filled(left + 1 - length, left + 1)) return length;
  }
  return 0;
}

void PaintMask::clear_junctions() {
  const int rows = mask_.rows, cols = mask_.cols;
  for (int r = 0; r < rows; ++r) {
    const std::int16_t* below = run_below_.data() + static_cast<std::size_t>(r) * cols;
    for (int c = 0; c < cols; ++c) {
      if (below[c] >= 0) continue;
      const int reach = below[c] == -2 ? junction_.margin : 1;
      for (int rr = std::max(0, r - reach); rr <= std::min(rows - 1, r + reach); ++rr) {
        std::uint8_t* m = mask_.ptr<std::uint8_t>(rr);
        for (int cc = std::max(0, c - 1); cc <= std::min(cols - 1, c + 1); ++cc) m[cc] = 0;
      }
    }
  }
}

}  // namespace markloop::perception
