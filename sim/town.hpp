// A town of two-way streets on a grid, and the drives through it. Unlike the
// other scenarios, the world is laid from the street network, not along the
// route: every street is painted in both directions, so any pass, in any
// direction, sees the same paint. Right-hand traffic: each direction's lanes
// lie to the right of the street's axis (lane 0 outermost), its markings
// painted in its own lanes for its own direction. Every leg of every
// intersection has a crosswalk across the whole road and a stop line across
// each approach lane before it; turn arrows stand in the approach lanes;
// between intersections a few speed numbers, diamonds, bikes and words.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sim/world.hpp"

namespace markloop::sim {

// Columns run north-south at x = xs[i], rows east-west at y = ys[j]; every
// column crosses every row. Streets run overhang_m past the outermost
// crossings and end there.
struct Town {
  std::vector<double> xs, ys;
  std::vector<int> column_lanes, row_lanes;  // lanes per direction
  double lane_width_m = 3.5;
  double overhang_m = 60.0;

  // Half the width of a street's surface: its lanes and a shoulder.
  double half_width(bool column, std::size_t index) const;
  // The intersection of column i and row j: {x0, y0, x1, y1}.
  std::array<double, 4> box(std::size_t i, std::size_t j) const;
};

// Where the paint of an intersection's leg lies, in metres from the
// intersection box's edge outwards. Each approach draws its own distances
// from these ranges, as real intersections differ by a metre or more.
struct LegLayout {
  static constexpr std::array<double, 2> kCrosswalkFrom{0.5, 2.0};  // a crosswalk 3 m long
  static constexpr std::array<double, 2> kStopLineGap{1.0, 2.5};    // then a stop line 0.45 m wide
  static constexpr std::array<double, 2> kArrowGap{2.0, 6.0};       // then the arrows
  static constexpr double kLinesFrom = 8.0;                         // lane lines end behind every stop line
};

// A place on the grid: column i, row j. Fractional between crossings;
// below 0 or above the last index, along the street's end stub (-1 is the
// street's end).
struct GridPoint {
  double i = 0.0, j = 0.0;
};

struct TownScenario {
  Town town;
  std::vector<GridPoint> route;  // consecutive points share a column or a row
  Scenario scenario;
};

std::vector<std::string> town_scenario_names();
// A town scenario, or nullopt for a name that is none. config.route_km sets
// the length of "far".
std::optional<TownScenario> make_town(std::string_view name, std::uint64_t seed, const WorldConfig& config);

// The path a car drives along `route`: the centre of lane 0 of each street
// in its direction, corners rounded as a car turns.
Path town_path(const Town& town, const std::vector<GridPoint>& route);

}  // namespace markloop::sim
