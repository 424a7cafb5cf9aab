#include <algorithm>
#include <cmath>

#include <catch2/catch_test_macros.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "app/perception/marking_features.hpp"

using namespace markloop::perception;

namespace {

// A bird's-eye patch of road with a painted arrow (stem and head), the
// mask of its paint and its box.
struct ArrowPatch {
  cv::Mat bev{96, 48, CV_8UC1, cv::Scalar(70)};
  cv::Mat mask;
  PatchBox box{8, 8, 39, 87, 4.0f, 1.6f, 1};

  ArrowPatch() {
    cv::rectangle(bev, cv::Rect(20, 36, 8, 52), cv::Scalar(210), cv::FILLED);
    const cv::Point head[] = {{8, 40}, {24, 8}, {39, 40}};
    cv::fillConvexPoly(bev, head, 3, cv::Scalar(210));
    mask = bev > 140;
  }
};

// Euclidean distance between the HOG values of two feature vectors over
// the cell rows first_row..last_row (of kPatchRows / kHogCell), and the
// length of the first's there.
std::pair<float, float> hog_rows_difference(const Features& a, const Features& b, int first_row,
                                            int last_row) {
  constexpr int kCellCols = kPatchCols / kHogCell;
  float difference = 0.0f, length = 0.0f;
  for (int i = first_row * kCellCols * kHogBins; i < (last_row + 1) * kCellCols * kHogBins; ++i) {
    difference += (a[i] - b[i]) * (a[i] - b[i]);
    length += a[i] * a[i];
  }
  return {std::sqrt(difference), std::sqrt(length)};
}

}  // namespace

TEST_CASE("a shadow over the head of an arrow leaves the HOG of its stem almost as it was") {
  ArrowPatch sunny;
  Features in_sun{};
  PatchScratch scratch;
  compute_features(sunny.bev, sunny.mask, sunny.box, scratch, in_sun);

  // A tree's shadow over the far half, the head: road and paint there at
  // 35 % of their brightness. The paint mask stays (the detector's local
  // threshold still finds paint in a shadow).
  ArrowPatch shaded;
  cv::Mat far_half = shaded.bev(cv::Rect(0, 0, 48, 48));
  far_half.convertTo(far_half, CV_8UC1, 0.35);
  Features in_shadow{};
  compute_features(shaded.bev, sunny.mask, shaded.box, scratch, in_shadow);

  // The last block row of cells (rows 6 and 7 of 8) lies wholly on the
  // stem in the sun, away from the shadow's edge. HOG normalised over the
  // whole patch grows there by the share of the edges the shadow dimmed
  // (by 27 % of its length with that normalisation); per block, only the
  // floor's share moves (6.6 %).
  constexpr int kCellRows = kPatchRows / kHogCell;
  const auto [difference, length] = hog_rows_difference(in_sun, in_shadow, kCellRows - 2, kCellRows - 1);
  REQUIRE(length > 0.1f);
  CHECK(difference < 0.12f * length);

  // The shadowed head's blocks are scaled back to unit length (less the
  // floor), so they keep more of their shape too (29 % against 41 %).
  const auto [head_difference, head_length] = hog_rows_difference(in_sun, in_shadow, 0, 1);
  REQUIRE(head_length > 0.1f);
  CHECK(head_difference < 0.35f * head_length);
}

TEST_CASE("a block of bare road stays near zero beside one of paint") {
  // A lane-wide box with the paint at its right: cells 0 and 1 of each
  // row are road with faint texture (3 grey levels), cells 2 and 3 hold
  // the bar's edges. Scaled to unit length on its own, the texture's
  // block would look as strong as the paint's; the floor keeps it small.
  cv::Mat bev(96, 48, CV_8UC1, cv::Scalar(70));
  cv::rectangle(bev, cv::Rect(32, 8, 8, 80), cv::Scalar(210), cv::FILLED);
  for (int r = 8; r < 88; r += 3) bev.at<std::uint8_t>(r, 8) = 73;
  const cv::Mat mask = bev > 140;
  const PatchBox box{0, 8, 47, 87, 4.0f, 2.4f, 1};
  Features features{};
  PatchScratch scratch;
  compute_features(bev, mask, box, scratch, features);
  constexpr int kCellCols = kPatchCols / kHogCell;
  float road = 0.0f, paint = 0.0f;
  for (int row = 0; row < kPatchRows / kHogCell; ++row)
    for (int col = 0; col < kCellCols; ++col)
      for (int b = 0; b < kHogBins; ++b) {
        float& side = col < 2 ? road : paint;
        side = std::max(side, features[(row * kCellCols + col) * kHogBins + b]);
      }
  CHECK(paint > 0.2f);
  CHECK(road < 0.1f * paint);
}

TEST_CASE("a patch turned half way round gives the features of the marking turned") {
  // The arrow drawn head down (the image turned by 180 degrees, the box
  // with it), its patch turned, reads as the arrow upright.
  ArrowPatch upright;
  cv::Mat bev, mask;
  cv::rotate(upright.bev, bev, cv::ROTATE_180);
  cv::rotate(upright.mask, mask, cv::ROTATE_180);
  const PatchBox box{bev.cols - 1 - upright.box.col1,
                     bev.rows - 1 - upright.box.row1,
                     bev.cols - 1 - upright.box.col0,
                     bev.rows - 1 - upright.box.row0,
                     upright.box.length_m,
                     upright.box.width_m,
                     upright.box.parts};
  PatchScratch scratch;
  Features read_upright{}, head_down{}, turned{};
  compute_features(upright.bev, upright.mask, upright.box, scratch, read_upright);
  compute_features(bev, mask, box, scratch, head_down);
  turn_features(scratch, head_down, turned);
  float largest = 0.0f, from_head_down = 0.0f;
  for (std::size_t i = 0; i < read_upright.size(); ++i) {
    largest = std::max(largest, std::abs(read_upright[i] - turned[i]));
    from_head_down = std::max(from_head_down, std::abs(read_upright[i] - head_down[i]));
  }
  CHECK(largest < 1e-4f);
  CHECK(from_head_down > 0.1f);  // read as it lies, the arrow head down is another pattern
}
