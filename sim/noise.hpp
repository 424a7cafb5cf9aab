// Deterministic hashing and value noise: textures and conditions that are a
// pure function of world coordinates and a seed, so a place looks the same on
// every pass and every run.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

namespace markloop::sim {

// splitmix64's finaliser: a good 64-bit mix of any integer.
constexpr std::uint64_t hash_mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

inline std::uint64_t hash2(std::int64_t x, std::int64_t y, std::uint64_t seed) {
  return hash_mix(static_cast<std::uint64_t>(x) * 0x9E3779B185EBCA87ULL ^
                  static_cast<std::uint64_t>(y) * 0xC2B2AE3D27D4EB4FULL ^ seed);
}

// Uniform in [0, 1) from a hash.
inline float unit_from_hash(std::uint64_t h) {
  return static_cast<float>(h >> 40) * (1.0F / 16777216.0F);
}

// Smooth value noise in [0, 1) with unit lattice spacing.
inline float value_noise(double x, double y, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  auto tx = static_cast<float>(x - fx), ty = static_cast<float>(y - fy);
  tx = tx * tx * (3.0F - 2.0F * tx);
  ty = ty * ty * (3.0F - 2.0F * ty);
  const float v00 = unit_from_hash(hash2(ix, iy, seed));
  const float v10 = unit_from_hash(hash2(ix + 1, iy, seed));
  const float v01 = unit_from_hash(hash2(ix, iy + 1, seed));
  const float v11 = unit_from_hash(hash2(ix + 1, iy + 1, seed));
  const float a = v00 + (v10 - v00) * tx;
  const float b = v01 + (v11 - v01) * tx;
  return a + (b - a) * ty;
}

inline float smoothstep(float edge0, float edge1, float x) {
  float t = (x - edge0) * (1.0F / (edge1 - edge0));
  t = t < 0.0F ? 0.0F : (t > 1.0F ? 1.0F : t);
  return t * t * (3.0F - 2.0F * t);
}

}  // namespace markloop::sim

namespace markloop::sim {

// Value noise from a precomputed periodic tile of random values: the same
// function family as value_noise() (smooth interpolation between lattice
// values) at a few nanoseconds per sample. Periodic every kSize lattice
// cells; callers use it at scales where that period is far larger than the
// view, or mix two scales so the repetition does not show.
class NoiseTile {
 public:
  static constexpr std::int64_t kSize = 1024;  // power of two
  explicit NoiseTile(std::uint64_t seed) : values_(static_cast<std::size_t>(kSize * kSize)) {
    for (std::int64_t y = 0; y < kSize; ++y)
      for (std::int64_t x = 0; x < kSize; ++x)
        values_[static_cast<std::size_t>(y * kSize + x)] = unit_from_hash(hash2(x, y, seed));
  }
  float operator()(double x, double y) const {
    const double fx = std::floor(x), fy = std::floor(y);
    const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
    auto tx = static_cast<float>(x - fx), ty = static_cast<float>(y - fy);
    tx = tx * tx * (3.0F - 2.0F * tx);
    ty = ty * ty * (3.0F - 2.0F * ty);
    constexpr std::int64_t m = kSize - 1;
    const std::size_t x0 = static_cast<std::size_t>(ix & m), x1 = static_cast<std::size_t>((ix + 1) & m);
    const std::size_t y0 = static_cast<std::size_t>(iy & m) * kSize;
    const std::size_t y1 = static_cast<std::size_t>((iy + 1) & m) * kSize;
    const float* v = values_.data();
    const float a = v[y0 + x0] + (v[y0 + x1] - v[y0 + x0]) * tx;
    const float b = v[y1 + x0] + (v[y1 + x1] - v[y1 + x0]) * tx;
    return a + (b - a) * ty;
  }

 private:
  std::vector<float> values_;
};

}  // namespace markloop::sim
