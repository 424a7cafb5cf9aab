// A world of persistent road markings laid along a route, and the route
// itself. Every pass over a road sees the same markings.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "engine/types.hpp"

namespace markloop::sim {

// Marking classes the simulator draws; names match the classifier's labels.
const std::vector<std::string>& marking_class_names();

struct Marking {
  std::uint32_t id = 0;
  Label label = 0;  // index into marking_class_names()
  double x = 0.0;
  double y = 0.0;
  double heading = 0.0;
  int lane = 0;
};

// A drivable path sampled densely by arc length.
class Path {
 public:
  void add_point(double x, double y);
  double length() const { return cumulative_.empty() ? 0.0 : cumulative_.back(); }
  // Pose at arc length s (clamped to the path), heading along the path.
  Pose2 at(double s) const;

 private:
  std::vector<double> xs_, ys_, cumulative_;
};

struct Scenario {
  std::string name;
  std::string description;
  Path road;          // one lap of the road network's centre line (right lane)
  int laps = 1;       // how many times the drive goes round
  std::vector<Marking> markings;
};

struct WorldConfig {
  double row_spacing_min_m = 15.0;  // along-track distance between marking rows
  double row_spacing_max_m = 60.0;
  double lane_width_m = 3.5;
  int lanes = 2;                    // the car drives in lane 0 (rightmost)
  double marking_probability = 0.6; // per lane and row
};

// Built-in scenarios: "loop" (a city block driven twice), "ring" (a 3 km ring
// road driven twice), "figure8", "long" (about 60 km in laps, for capacity
// and allocation tests). Returns nullopt for an unknown name.
std::optional<Scenario> make_scenario(std::string_view name, std::uint64_t seed,
                                      const WorldConfig& config = {});
std::vector<std::string> scenario_names();

}  // namespace markloop::sim
