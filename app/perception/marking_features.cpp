#include "app/perception/marking_features.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace markloop::perception {
namespace {

// Margin around the box, as a fraction of its size, so that the outline of
// the paint is inside the patch.
constexpr float kMargin = 0.08f;
constexpr float kHogClip = 0.2f;
constexpr int kHogBlockCells = 2;  // HOG normalised per block of 2 x 2 cells
constexpr float kHogBlockFloor = 0.1f;
static_assert((kPatchCols / kHogCell) % kHogBlockCells == 0 && (kPatchRows / kHogCell) % kHogBlockCells == 0,
              "whole blocks of cells");

float sample(const cv::Mat& image, float x, float y) {
  const int x0 = std::clamp(static_cast<int>(std::floor(x)), 0, image.cols - 1);
  const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, image.rows - 1);
  const int x1 = std::min(x0 + 1, image.cols - 1), y1 = std::min(y0 + 1, image.rows - 1);
  const float fx = std::clamp(x - static_cast<float>(x0), 0.0f, 1.0f);
  const float fy = std::clamp(y - static_cast<float>(y0), 0.0f, 1.0f);
  const std::uint8_t* r0 = image.ptr<std::uint8_t>(y0);
  const std::uint8_t* r1 = image.ptr<std::uint8_t>(y1);
  const float top = r0[x0] + (r0[x1] - r0[x0]) * fx;
  const float bottom = r1[x0] + (r1[x1] - r1[x0]) * fx;
  return top + (bottom - top) * fy;
}

// L2-Hys over `n` values: scaled to unit length, clipped, scaled again.
// `energy_floor` is added to the squared length (in the units of the
// values) so that a block with hardly any edges is not blown up to the size
// of one with many.
void normalise(float* v, int n, float energy_floor) {
  float sum = energy_floor + 1e-6f;
  for (int i = 0; i < n; ++i) sum += v[i] * v[i];
  float scale = 1.0f / std::sqrt(sum);
  sum = energy_floor * scale * scale + 1e-6f;
  for (int i = 0; i < n; ++i) {
    v[i] = std::min(v[i] * scale, kHogClip);
    sum += v[i] * v[i];
  }
  scale = 1.0f / std::sqrt(sum);
  for (int i = 0; i < n; ++i) v[i] *= scale;
}

// The patch resampled from the box (and its margin): grey and paint (0..1).
void resample_patch(const cv::Mat& bev, const cv::Mat& mask, const PatchBox& box, PatchScratch& scratch) {
  const float width = static_cast<float>(box.col1 - box.col0 + 1);
  const float height = static_cast<float>(box.row1 - box.row0 + 1);
  const float left = static_cast<float>(box.col0) - kMargin * width;
  const float top = static_cast<float>(box.row0) - kMargin * height;
  const float step_x = width * (1.0f + 2.0f * kMargin) / kPatchCols;
  const float step_y = height * (1.0f + 2.0f * kMargin) / kPatchRows;
  for (int r = 0; r < kPatchRows; ++r) {
    for (int c = 0; c < kPatchCols; ++c) {
      const float x = left + (static_cast<float>(c) + 0.5f) * step_x - 0.5f;
      const float y = top + (static_cast<float>(r) + 0.5f) * step_y - 0.5f;
      scratch.grey[r * kPatchCols + c] = sample(bev, x, y);
      scratch.paint[r * kPatchCols + c] = sample(mask, x, y) * (1.0f / 255.0f);
    }
  }
}

// The grey to zero mean and unit deviation, so that light does not matter.
void standardise_grey(PatchScratch& scratch) {
  float mean = 0.0f;
  for (float g : scratch.grey) mean += g;
  mean /= static_cast<float>(kPatchCols * kPatchRows);
  float var = 0.0f;
  for (float g : scratch.grey) var += (g - mean) * (g - mean);
  const float inv_std = 1.0f / std::sqrt(var / static_cast<float>(kPatchCols * kPatchRows) + 1.0f);
  for (float& g : scratch.grey) g = (g - mean) * inv_std;
}

constexpr int kCellCols = kPatchCols / kHogCell;
constexpr int kCellRows = kPatchRows / kHogCell;

// HOG: signed gradient orientation, magnitude split linearly between the
// two nearest bins, one histogram per cell.
void cell_histograms(const PatchScratch& scratch, float* hog) {
  std::fill(hog, hog + kHogFeatures, 0.0f);
  constexpr float kBinWidth = 2.0f * std::numbers::pi_v<float> / kHogBins;
  const auto at = [&](int rr, int cc) {
    return scratch.grey[std::clamp(rr, 0, kPatchRows - 1) * kPatchCols + std::clamp(cc, 0, kPatchCols - 1)];
  };
  for (int r = 0; r < kPatchRows; ++r) {
    for (int c = 0; c < kPatchCols; ++c) {
      const float gx = at(r, c + 1) - at(r, c - 1);
      const float gy = at(r + 1, c) - at(r - 1, c);
      const float magnitude = std::sqrt(gx * gx + gy * gy);
      if (magnitude < 1e-6f) continue;
      float angle = std::atan2(gy, gx);
      if (angle < 0.0f) angle += 2.0f * std::numbers::pi_v<float>;
      const float bin = angle / kBinWidth - 0.5f;
      const int b0 = static_cast<int>(std::floor(bin));
      const float frac = bin - static_cast<float>(b0);
      const int cell = (r / kHogCell) * kCellCols + c / kHogCell;
      float* h = hog + cell * kHogBins;
      h[(b0 + kHogBins) % kHogBins] += magnitude * (1.0f - frac);
      h[(b0 + 1) % kHogBins] += magnitude * frac;
    }
  }
}

// Each block of 2 x 2 cells on its own, as in Dalal and Triggs' HOG: a
// shadow across part of a marking weakens the edges there and only there.
// The floor, a fraction of a block's mean energy, keeps blocks of bare road
// near zero.
void normalise_blocks(float* hog) {
  float energy = 0.0f;
  for (int i = 0; i < kHogFeatures; ++i) energy += hog[i] * hog[i];
  constexpr int kBlockFeatures = kHogBlockCells * kHogBlockCells * kHogBins;
  constexpr int kBlocks = kHogFeatures / kBlockFeatures;
  const float energy_floor = kHogBlockFloor * energy / kBlocks;
  std::array<float, kBlockFeatures> block;
  for (int block_row = 0; block_row < kCellRows / kHogBlockCells; ++block_row)
    for (int block_col = 0; block_col < kCellCols / kHogBlockCells; ++block_col) {
      // The block's cells, copied out and back: they are not contiguous.
      const auto cell = [&](int k) {
        const int row = block_row * kHogBlockCells + k / kHogBlockCells;
        const int col = block_col * kHogBlockCells + k % kHogBlockCells;
        return hog + (row * kCellCols + col) * kHogBins;
      };
      for (int k = 0; k < kHogBlockCells * kHogBlockCells; ++k)
        std::copy_n(cell(k), kHogBins, block.begin() + k * kHogBins);
      normalise(block.data(), kBlockFeatures, energy_floor);
      for (int k = 0; k < kHogBlockCells * kHogBlockCells; ++k)
        std::copy_n(block.begin() + k * kHogBins, kHogBins, cell(k));
    }
}

// Paint on a coarse grid of the patch.
void occupancy_grid(const PatchScratch& scratch, float* occupancy) {
  constexpr int kOccCols = kPatchCols / kOccupancyCell;
  std::fill(occupancy, occupancy + kOccupancyFeatures, 0.0f);
  for (int r = 0; r < kPatchRows; ++r)
    for (int c = 0; c < kPatchCols; ++c)
      occupancy[(r / kOccupancyCell) * kOccCols + c / kOccupancyCell] +=
          scratch.paint[r * kPatchCols + c] * (1.0f / (kOccupancyCell * kOccupancyCell));
}

// The box's size on the ground, its paint's share and its parts.
void shape_of(const PatchBox& box, const PatchScratch& scratch, float* shape) {
  float fill = 0.0f;
  for (float p : scratch.paint) fill += p;
  fill /= static_cast<float>(kPatchCols * kPatchRows);
  shape[0] = box.length_m;
  shape[1] = box.width_m;
  shape[2] = std::log(std::max(box.length_m, 0.05f) / std::max(box.width_m, 0.05f));
  shape[3] = fill;
  shape[4] = static_cast<float>(std::min(box.parts, 8));
  shape[5] = std::log(std::max(box.length_m * box.width_m, 0.01f));
}

}  // namespace

void compute_features(const cv::Mat& bev, const cv::Mat& mask, const PatchBox& box, PatchScratch& scratch,
                      Features& out) {
  resample_patch(bev, mask, box, scratch);
  standardise_grey(scratch);
  float* hog = out.data();
  cell_histograms(scratch, hog);
  normalise_blocks(hog);
  float* occupancy = hog + kHogFeatures;
  occupancy_grid(scratch, occupancy);
  shape_of(box, scratch, occupancy + kOccupancyFeatures);
}

void turn_features(PatchScratch& scratch, const Features& upright, Features& turned) {
  std::reverse(scratch.grey.begin(), scratch.grey.end());
  std::reverse(scratch.paint.begin(), scratch.paint.end());
  float* hog = turned.data();
  cell_histograms(scratch, hog);
  normalise_blocks(hog);
  occupancy_grid(scratch, hog + kHogFeatures);
  std::copy(upright.end() - kShapeFeatures, upright.end(), turned.end() - kShapeFeatures);
}

}  // namespace markloop::perception
