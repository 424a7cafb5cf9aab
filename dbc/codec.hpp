// Conversions between physical and raw signal values used by the generated
// encoders and decoders.
#pragma once

#include <cmath>
#include <cstdint>

namespace markloop::dbc {

constexpr std::int64_t saturate(std::int64_t value, std::int64_t low, std::int64_t high) noexcept {
  return value < low ? low : (value > high ? high : value);
}

// raw = round((physical - offset) / factor), half away from zero, saturated
// to [raw_min, raw_max] (the DBC's [min|max]). NaN encodes as raw_min: the
// bus has no "invalid" value, and the minimum is the conservative end.
inline std::int64_t raw_from_physical(double physical, double factor, double offset, std::int64_t raw_min,
                                      std::int64_t raw_max) noexcept {
  const double scaled = (physical - offset) / factor;
  if (!(scaled > static_cast<double>(raw_min))) return raw_min;  // also catches NaN
  if (scaled >= static_cast<double>(raw_max)) return raw_max;
  return static_cast<std::int64_t>(std::llround(scaled));
}

constexpr double physical_from_raw(std::int64_t raw, double factor, double offset) noexcept {
  return static_cast<double>(raw) * factor + offset;
}

}  // namespace markloop::dbc
