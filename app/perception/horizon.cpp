#include "app/perception/horizon.hpp"

#include <algorithm>
#include <bitset>
#include <cmath>

namespace markloop::perception {
namespace {

struct Crossing {
  float x, y;
  std::uint8_t a, b;  // the two segments
};
static_assert(kMaxHorizonSegments <= 256, "segment indexes are bytes");

// Whether segment s points at (x, y): the angle between it and the line from
// its middle to the point is under max_angle (sine compared, no trigonometry).
bool points_at(const ImageSegment& s, float x, float y, float max_sine) {
  const float dx = s.x1 - s.x0, dy = s.y1 - s.y0;
  const float tx = x - 0.5f * (s.x0 + s.x1), ty = y - 0.5f * (s.y0 + s.y1);
  const float cross = dx * ty - dy * tx;
  return std::abs(cross) <= max_sine * std::hypot(dx, dy) * std::hypot(tx, ty);
}

}  // namespace

std::optional<float> vanishing_row(std::span<const ImageSegment> segments, const VanishingSearch& search) {
  constexpr std::size_t kMaxPairs = kMaxHorizonSegments * (kMaxHorizonSegments - 1) / 2;
  std::array<Crossing, kMaxPairs> crossings;
  std::size_t count = 0;
  const std::size_t n = std::min(segments.size(), kMaxHorizonSegments);
  const float min_sine = std::sin(search.min_angle_rad);
  for (std::size_t i = 0; i < n; ++i) {
    const ImageSegment& a = segments[i];
    const float adx = a.x1 - a.x0, ady = a.y1 - a.y0;
    const float alen = std::hypot(adx, ady);
    if (!(alen > 0.0f)) continue;
    for (std::size_t j = i + 1; j < n; ++j) {
      const ImageSegment& b = segments[j];
      const float bdx = b.x1 - b.x0, bdy = b.y1 - b.y0;
      const float blen = std::hypot(bdx, bdy);
      if (!(blen > 0.0f)) continue;
      // a0 + t * da = b0 + s * db; cross = da x db = |da| |db| sin(angle).
      const float cross = adx * bdy - ady * bdx;
      if (!(std::abs(cross) >= min_sine * alen * blen)) continue;
      const float t = ((b.x0 - a.x0) * bdy - (b.y0 - a.y0) * bdx) / cross;
      const float x = a.x0 + t * adx, y = a.y0 + t * ady;
      if (y < search.min_row || y > search.max_row || x < search.min_col || x > search.max_col) continue;
      crossings[count++] = {x, y, static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(j)};
    }
  }
  if (count == 0) return std::nullopt;
  // Lines that merged with something else (a car, a shadow) point astray:
  // the crossing most segments point at wins, and the rows of the crossings
  // among those segments are its estimate (their median).
  const float max_sine = std::sin(search.support_angle_rad);
  std::bitset<kMaxHorizonSegments> best;
  for (std::size_t k = 0; k < count; ++k) {
    std::bitset<kMaxHorizonSegments> support;
    for (std::size_t i = 0; i < n; ++i)
      if (points_at(segments[i], crossings[k].x, crossings[k].y, max_sine)) support.set(i);
    if (support.count() > best.count()) best = support;
  }
  std::array<float, kMaxPairs> rows;
  std::size_t used = 0;
  for (std::size_t k = 0; k < count; ++k)
    if (best.test(crossings[k].a) && best.test(crossings[k].b)) rows[used++] = crossings[k].y;
  if (used == 0) return std::nullopt;
  const auto middle = rows.begin() + static_cast<std::ptrdiff_t>(used / 2);
  std::nth_element(rows.begin(), middle, rows.begin() + static_cast<std::ptrdiff_t>(used));
  return *middle;
}

}  // namespace markloop::perception
