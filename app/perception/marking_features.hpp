// Features of one marking candidate, computed on its box in the bird's-eye
// image: a HOG of the patch resampled to a fixed size (normalised per block
// of 2 x 2 cells), the paint occupancy on a coarse grid, and the size of
// the box on the ground. Fixed-size arrays, no allocation.
#pragma once

#include <array>
#include <cstddef>

#include <opencv2/core/mat.hpp>

namespace markloop::perception {

inline constexpr int kPatchCols = 16;  // across the road
inline constexpr int kPatchRows = 32;  // along the road
inline constexpr int kHogCell = 4;
inline constexpr int kHogBins = 8;  // signed orientation: paint edges have a polarity
inline constexpr int kHogFeatures = (kPatchCols / kHogCell) * (kPatchRows / kHogCell) * kHogBins;
inline constexpr int kOccupancyCell = 2;
inline constexpr int kOccupancyFeatures = (kPatchCols / kOccupancyCell) * (kPatchRows / kOccupancyCell);
inline constexpr int kShapeFeatures = 6;
inline constexpr int kFeatureCount = kHogFeatures + kOccupancyFeatures + kShapeFeatures;

using Features = std::array<float, kFeatureCount>;

struct PatchScratch {
  std::array<float, kPatchCols * kPatchRows> grey{};
  std::array<float, kPatchCols * kPatchRows> paint{};
};

struct PatchBox {
  int col0, row0, col1, row1;  // inclusive, bird's-eye pixels
  float length_m, width_m;     // along, across the road
  int parts;                   // bright regions grouped in the box
};

// `bev`, `mask`: CV_8UC1 of the same size; the box must lie inside them.
// Leaves in `scratch` the patch the features came from.
void compute_features(const cv::Mat& bev, const cv::Mat& mask, const PatchBox& box, PatchScratch& scratch,
                      Features& out);

// Turns the patch in `scratch` (as compute_features left it, whose features
// are `upright`) half way round, and gives its features so. A marking seen
// from behind (an arrow in the oncoming lane) then reads as one seen ahead:
// on the ground the view from behind is the marking turned by 180 degrees,
// and a turn keeps a left arrow a left arrow.
void turn_features(PatchScratch& scratch, const Features& upright, Features& turned);

}  // namespace markloop::perception
