// Angle units shared by the programs and the bus (the DBC carries degrees,
// the code works in radians). Converting by multiplying with one of these
// constants keeps each conversion a single rounding, the same everywhere.
#pragma once

#include <numbers>

namespace markloop {

inline constexpr double kRadiansPerDegree = std::numbers::pi / 180.0;
inline constexpr double kDegreesPerRadian = 180.0 / std::numbers::pi;

}  // namespace markloop
