// The road's horizon measured from lane lines: lines along a flat road meet
// at a vanishing point on the horizon, so the row where the image's lane
// lines cross says how far the camera's pitch differs from its calibration
// (another mounting, a loaded or braking car). Fixed memory, no allocation.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>

namespace markloop::perception {

// A stretch of line in the image, pixels (x right, y down).
struct ImageSegment {
  float x0, y0, x1, y1;
};

struct VanishingSearch {
  float min_row, max_row;  // crossings outside these rows are not the horizon
  float min_col, max_col;  // ... nor outside these columns
  // Pairs of segments closer in direction than this (radians) cross at an
  // ill-defined point: skipped.
  float min_angle_rad = 0.1f;
  // A segment supports a crossing when it points at it within this angle.
  float support_angle_rad = 0.05f;
};

inline constexpr std::size_t kMaxHorizonSegments = 24;

// The horizon row where the segments (at most the first
// kMaxHorizonSegments) meet: of the crossings of pairs inside `search`, the
// one the most segments point at; the median row of the crossings among
// those segments. Nothing when no pair crosses inside `search`.
std::optional<float> vanishing_row(std::span<const ImageSegment> segments, const VanishingSearch& search);

}  // namespace markloop::perception
