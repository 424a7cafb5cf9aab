// A world of persistent road markings laid along a route, and the route
// itself. Every pass over a road sees the same markings: the world is laid
// once along the route's first pass, and a later stretch that runs along an
// earlier one (within WorldConfig::revisit_radius_m, similar heading) gets no
// new road, lines or markings of its own. Where the route crosses itself (an
// intersection) no marking is painted, as on real roads; nor over, or
// within a metre of, another marking in its lane; nor where the road bends
// under it or a line of another stretch of road runs across it.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "app/common/result.hpp"
#include "app/engine/types.hpp"
#include "app/perception/marking_classes.hpp"

namespace markloop::sim {

// Marking classes the simulator draws: exactly the classifier's labels
// (perception::kMarkingClassNames), index = Label.
const std::vector<std::string>& marking_class_names();
inline constexpr std::size_t kClassCount = perception::kMarkingClassCount;

struct Marking {
  std::uint32_t id = 0;
  Label label = 0;  // index into marking_class_names()
  double x = 0.0;   // centre of the painted footprint, world frame, metres
  double y = 0.0;
  double heading = 0.0;   // driving direction the marking is painted for
  int lane = 0;           // 0 = the route's lane; crosswalks span the road (lane 0)
  double length_m = 0.0;  // footprint along the heading
  double width_m = 0.0;   // footprint across
};

// Footprint (length along the lane, width across) of a marking class, in
// metres, for a lane `lane_width_m` wide on a road of `lanes` lanes.
std::array<double, 2> marking_size(Label label, double lane_width_m, int lanes);

// An oriented rectangle of road surface or line paint, world frame.
enum class StripKind : std::uint8_t { kRoad, kWhiteLine, kYellowLine };
struct Strip {
  double x = 0.0, y = 0.0, heading = 0.0;
  float half_length = 0.0F, half_width = 0.0F;
  StripKind kind = StripKind::kRoad;
};

// A drivable path sampled densely by arc length.
class Path {
 public:
  void add_point(double x, double y);
  double length() const { return cumulative_.empty() ? 0.0 : cumulative_.back(); }
  std::size_t size() const { return xs_.size(); }
  // Pose at arc length s (clamped to the path), heading along the path.
  Pose2 at(double s) const;

 private:
  std::vector<double> xs_, ys_, cumulative_;
};

struct Scenario {
  std::string name;
  std::string description;
  Path road;     // one lap of the drive along the right lane's centre
  int laps = 1;  // how many times the drive goes round
  int days = 1;  // > 1: each lap is another day (other light, other sensor noise)
  std::vector<Marking> markings;
  std::vector<Strip> strips;  // road surface and lane lines
};

struct WorldConfig {
  double row_spacing_min_m = 15.0;  // along-track distance between marking rows
  double row_spacing_max_m = 60.0;
  double lane_width_m = 3.5;
  int lanes = 2;                     // the car drives in lane 0 (rightmost)
  double marking_probability = 0.6;  // per lane and row
  // Relative frequency of each class (index = Label); unset = the scenario's
  // default (the legacy scenarios draw no stop lines or crosswalks).
  std::optional<std::array<double, kClassCount>> class_weights;
  // A stretch of route within this distance of an earlier one, heading within
  // 45 degrees, is a revisit of that road.
  double revisit_radius_m = 2.5;
  // The length of the town scenario "far", which never comes back (0: its
  // default).
  double route_km = 0.0;
};

// Default class mix of the newer scenarios: arrows dominate, as on urban roads.
std::array<double, kClassCount> default_class_weights();
// Parses "name=weight,name=weight,..." (unnamed classes get 0); an error
// says what is wrong.
Result<std::array<double, kClassCount>> parse_class_weights(std::string_view text);

// Built-in scenarios (see scenario_names()). Returns nullopt for an unknown
// name.
std::optional<Scenario> make_scenario(std::string_view name, std::uint64_t seed,
                                      const WorldConfig& config = {});
std::vector<std::string> scenario_names();

// A world laid along an arbitrary route (driven once), revisits included.
Scenario make_route_scenario(std::string name, Path route, std::uint64_t seed,
                             const WorldConfig& config = {});

}  // namespace markloop::sim
